"""Patrol order benchmark: task_manager's ``order: "shortest"`` against the exact shortest order.

On the simulated yard (its six stops from inspection_robot_testing/yard_patrol.py, from and back to
the home pose) and on random 200 m x 200 m yards (bench/nav_yards.py, 20 to 80 stops at random free cells, start and
end at a random home), nav/tour.py's ``order_points`` orders the stops by the planner's path
lengths. The exact optimum is an integer program (SciPy's HiGHS: one binary per leg, two legs per
stop, subtour cuts added until none is violated) over the same lengths, found without planning
every pair: legs not yet planned stand at their straight-line length (a lower bound), the legs of
each optimum are planned, and it is solved again until its legs are all planned, which makes it the
optimum of the full matrix. One JSON line per yard: stops, the typed order's length (stops as
generated), the shortest order's length, the exact optimum, the ratio (goal <= 1.05), the pairs
planned against all pairs, and the time to order.
"""
import argparse
import math
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "src"))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from benchlib import report  # noqa: E402
from inspection_robot.nav.costmap import Costmap  # noqa: E402
from inspection_robot.nav.gridmap import load_map  # noqa: E402
from inspection_robot.nav.planner import Planner, PlanningError  # noqa: E402
from inspection_robot.nav.tour import TourError, order_points, path_length  # noqa: E402
from nav_yards import make_yard  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ROBOT_RADIUS = 0.45


class Lengths(object):
    """Planner path lengths between fixed points, each pair planned once."""

    def __init__(self, planner, points):
        self.planner, self.points, self.cache = planner, points, {}

    def __call__(self, i, j):
        key = (min(i, j), max(i, j))
        if key not in self.cache:
            try:
                self.cache[key] = self.planner.plan(self.points[key[0]], self.points[key[1]]).length
            except PlanningError as err:
                raise TourError(str(err))
        return self.cache[key]


def _cycle_edges(n):
    return [(i, j) for i in range(n) for j in range(i + 1, n)]


def exact_order(points, lengths):
    """The shortest path points[0] -> every point -> points[-1] (HiGHS with lazy subtour cuts)."""
    from scipy.optimize import LinearConstraint, milp
    from scipy.sparse import lil_matrix
    from scipy.sparse.csgraph import connected_components
    xy = np.asarray(points, dtype=float)
    n = len(xy)
    edges = _cycle_edges(n)
    index = {e: k for k, e in enumerate(edges)}
    closing = index[(0, n - 1)]   # the path closed into a cycle by a free leg end -> start

    def bound(e):
        key = e
        if key in lengths.cache:
            return lengths.cache[key]
        return float(np.hypot(*(xy[e[0]] - xy[e[1]])))

    cuts = []
    while True:
        cost = np.array([bound(e) for e in edges])
        cost[closing] = 0.0
        rows = lil_matrix((n + len(cuts), len(edges)))
        for k, (i, j) in enumerate(edges):
            rows[i, k] = rows[j, k] = 1
        lo, hi = [2] * n, [2] * n
        for c, members in enumerate(cuts):
            inside = set(members)
            for k, (i, j) in enumerate(edges):
                if i in inside and j in inside:
                    rows[n + c, k] = 1
            lo.append(0)
            hi.append(len(members) - 1)
        lower = np.zeros(len(edges))
        lower[closing] = 1
        result = milp(cost, constraints=LinearConstraint(rows.tocsr(), lo, hi), integrality=np.ones(len(edges)),
                      bounds=(lower, np.ones(len(edges))))
        if not result.success:
            raise RuntimeError("milp: %s" % result.message)
        chosen = [edges[k] for k in np.flatnonzero(result.x > 0.5)]
        graph = lil_matrix((n, n))
        for i, j in chosen:
            graph[i, j] = 1
        count, labels = connected_components(graph, directed=False)
        if count > 1:
            cuts.extend([list(np.flatnonzero(labels == c)) for c in range(count)])
            continue
        unplanned = [e for e in chosen if e != (0, n - 1) and e not in lengths.cache]
        if unplanned:
            for i, j in unplanned:
                lengths(i, j)
            continue
        # walk the cycle from 0 away from n-1: the path 0 -> ... -> n-1
        nxt = {i: [] for i in range(n)}
        for i, j in chosen:
            if (i, j) != (0, n - 1):
                nxt[i].append(j)
                nxt[j].append(i)
        order, prev = [0], None
        while order[-1] != n - 1:
            here = order[-1]
            step = [k for k in nxt[here] if k != prev][0]
            prev = here
            order.append(step)
        return order, sum(lengths(a, b) for a, b in zip(order, order[1:]))


def random_points(costmap, rng, count):
    free = np.argwhere(np.isfinite(costmap.cost))
    grid = costmap.grid
    points = []
    while len(points) < count:
        r, c = free[rng.randint(len(free))]
        x, y = grid.cell_to_world(r, c)
        points.append((float(x), float(y)))
    return points


def one_yard(name, planner, points):
    lengths = Lengths(planner, points)
    started = time.perf_counter()
    order, length, planned = order_points(points, lengths)
    order_s = time.perf_counter() - started
    typed = path_length([[lengths(i, j) if i != j else 0.0 for j in range(len(points))]
                         for i in range(len(points))], list(range(len(points)))) \
        if len(points) <= 12 else sum(lengths(i, i + 1) for i in range(len(points) - 1))
    best_order, best = exact_order(points, lengths)
    n = len(points)
    report(bench="tour_order", yard=name, stops=n - 2, typed_m=round(typed, 1), shortest_m=round(length, 1),
           exact_m=round(best, 1), ratio=round(length / best, 4) if best > 0 else 1.0,
           planned_pairs=planned, all_pairs=n * (n - 1) // 2, order_s=round(order_s, 2), goal=1.05)
    return length / best if best > 0 else 1.0


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", default="20,40,60,80", help="stops per random yard")
    parser.add_argument("--styles", default="bays,posts", help="nav_yards styles")
    parser.add_argument("--seeds", default="1", help="comma-separated yard seeds")
    args = parser.parse_args()
    ratios = []
    from inspection_robot_testing.yard_patrol import YARD_STOPS
    import yaml
    with open(os.path.join(ROOT, "config", "sim_site.yaml")) as f:   # the simulated yard's home
        home = yaml.safe_load(f)["task_manager"]["home_pose"]
    sim = load_map(os.path.join(ROOT, "config", "maps", "substation.yaml"))
    planner = Planner(Costmap(sim, ROBOT_RADIUS, 0.0))
    points = [tuple(home[:2])] + [(pose[0], pose[1]) for _name, pose, _p in YARD_STOPS] + [tuple(home[:2])]
    ratios.append(one_yard("simulated", planner, points))
    for size in (25, 50):   # many stops on the simulated yard's map
        rng = np.random.RandomState(size)
        many = [tuple(home[:2])] + random_points(planner.costmap, rng, size) + [tuple(home[:2])]
        ratios.append(one_yard("simulated-%d" % size, planner, many))
    for style in args.styles.split(","):
        for seed in [int(s) for s in args.seeds.split(",")]:
            costmap = Costmap(make_yard(style, seed), ROBOT_RADIUS, 0.0)
            planner = Planner(costmap)
            for size in [int(s) for s in args.sizes.split(",")]:
                rng = np.random.RandomState(1000 * seed + size)
                points = random_points(costmap, rng, size + 1)
                points.append(points[0])   # back home
                ratios.append(one_yard("%s-%d" % (style, seed), planner, points))
    report(bench="tour_order_worst", ratio=round(max(ratios), 4), yards=len(ratios), goal=1.05,
           ok=bool(max(ratios) <= 1.05 + 1e-9 and not math.isnan(max(ratios))))


if __name__ == "__main__":
    main()
