"""Global planner on the inflated costmap: coarse-to-fine Dijkstra on sparse grid graphs (SciPy).

A 200 m x 200 m yard at 5 cm is 16 million cells, too many for one graph search per goal. The
planner therefore works in three steps, all vectorised (no per-cell Python loop):

1. **Exact reachability**: the costmap's connected-component labels answer "no path" at once.
2. **Coarse search**: blocks of ``coarse_factor`` x ``coarse_factor`` cells form an 8-connected
   graph (built once per costmap change). A block is passable when any of its cells is (an
   optimistic relaxation: every fine path maps onto a coarse one); partly blocked blocks cost more,
   so the coarse route prefers open space.
3. **Fine search** in a corridor of blocks around the coarse route, on a 16-connected graph
   (knight moves: at most 2.7 % longer than the Euclidean optimum), widened if the corridor
   does not hold a path; then line-of-sight shortcutting that never raises the path's peak cost.
"""
import math
from collections import namedtuple

import numpy as np
from scipy import ndimage
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

Plan = namedtuple("Plan", "points length")   # points: (N, 2) array of map metres

_OFFSETS_8 = [(dr, dc) for dr in (-1, 0, 1) for dc in (-1, 0, 1) if (dr, dc) != (0, 0)]
_KNIGHT = [(dr, dc) for dr in (-2, -1, 1, 2) for dc in (-2, -1, 1, 2) if abs(dr) != abs(dc)]


class PlanningError(Exception):
    """No path; the message is the reason reported to the caller."""


def _knight_crossed(dr, dc):
    """The two cells a straight knight move from (0, 0) to (dr, dc) passes through."""
    sr, sc = int(math.copysign(1, dr)), int(math.copysign(1, dc))
    if abs(dr) == 2:
        return (sr, 0), (sr, sc)
    return (0, sc), (sr, sc)


def grid_graph(flat, shape, node_cost, offsets):
    """Directed sparse graph over the cells ``flat`` (sorted flat indices) of a grid of ``shape``.

    Edge weight = step length (cells) x mean cost of its two ends. Knight moves also require the
    two cells they cross to be nodes, so no edge clips an obstacle corner.
    """
    height, width = shape
    rows, cols = np.divmod(flat, width)
    n = len(flat)

    def lookup(dr, dc):
        r, c = rows + dr, cols + dc
        inside = (r >= 0) & (r < height) & (c >= 0) & (c < width)
        target = np.where(inside, r * width + c, -1)
        pos = np.minimum(np.searchsorted(flat, target), n - 1)
        found = inside & (flat[pos] == target)
        return found, pos

    sources, targets, weights = [], [], []
    for dr, dc in offsets:
        found, pos = lookup(dr, dc)
        if abs(dr) + abs(dc) == 3:
            for cr, cc in _knight_crossed(dr, dc):
                found &= lookup(cr, cc)[0]
        src = np.flatnonzero(found)
        dst = pos[src]
        sources.append(src)
        targets.append(dst)
        weights.append(math.hypot(dr, dc) * 0.5 * (node_cost[src] + node_cost[dst]))
    graph = csr_matrix((np.concatenate(weights), (np.concatenate(sources), np.concatenate(targets))),
                       shape=(n, n))
    return graph


def _walk(predecessors, target):
    path = [target]
    while predecessors[path[-1]] >= 0:
        path.append(predecessors[path[-1]])
    return path[::-1]


class Planner(object):
    def __init__(self, costmap, coarse_factor=8, corridor_blocks=(2, 6, 16), start_escape_m=1.0):
        if coarse_factor < 2:
            raise ValueError("coarse_factor must be >= 2")
        self.costmap = costmap
        self.coarse_factor = int(coarse_factor)
        self.corridor_blocks = tuple(int(c) for c in corridor_blocks)
        self.start_escape_m = float(start_escape_m)
        self._coarse_for = None
        self.refresh()

    def refresh(self):
        """Rebuild the coarse graph; call after the costmap changed."""
        cost = self.costmap.cost
        k = self.coarse_factor
        height, width = cost.shape
        hc, wc = -(-height // k), -(-width // k)
        padded = np.full((hc * k, wc * k), np.inf, dtype=np.float32)
        padded[:height, :width] = cost
        blocks = padded.reshape(hc, k, wc, k).transpose(0, 2, 1, 3).reshape(hc, wc, k * k)
        finite = np.isfinite(blocks)
        free_count = finite.sum(axis=2)
        passable = free_count > 0
        mean_cost = np.where(finite, blocks, 0).sum(axis=2) / np.maximum(free_count, 1)
        blocked_share = 1.0 - free_count / float(k * k)
        coarse_cost = (mean_cost * (1.0 + 4.0 * blocked_share)).astype(np.float64)
        self._coarse_shape = (hc, wc)
        self._coarse_flat = np.flatnonzero(passable.ravel())
        self._coarse_graph = grid_graph(self._coarse_flat, (hc, wc),
                                        coarse_cost.ravel()[self._coarse_flat], _OFFSETS_8)
        self._coarse_for = cost

    def plan(self, start_xy, goal_xy):
        """Return a Plan from ``start_xy`` to ``goal_xy`` (map metres) or raise PlanningError."""
        if self._coarse_for is not self.costmap.cost:
            self.refresh()
        grid, cost = self.costmap.grid, self.costmap.cost
        start = grid.world_to_cell(*start_xy)
        goal = grid.world_to_cell(*goal_xy)
        if not grid.contains(*goal):
            raise PlanningError("goal (%.2f, %.2f) is outside the map" % tuple(goal_xy))
        if not grid.contains(*start):
            raise PlanningError("robot (%.2f, %.2f) is outside the map" % tuple(start_xy))
        if not np.isfinite(cost[goal]):
            raise PlanningError("goal (%.2f, %.2f) is inside an obstacle or too close to one" % tuple(goal_xy))
        prefix = []
        if not np.isfinite(cost[start]):
            escaped = self._escape(start)
            if escaped is None:
                raise PlanningError("robot (%.2f, %.2f) is inside an obstacle" % tuple(start_xy))
            prefix, start = [start], escaped
        if self.costmap.labels[start] != self.costmap.labels[goal]:
            raise PlanningError("goal (%.2f, %.2f) is not reachable (enclosed by obstacles)" % tuple(goal_xy))
        coarse_route = self._coarse_route(start, goal)
        for blocks in self.corridor_blocks:
            cells = self._fine_route(start, goal, coarse_route, blocks)
            if cells is not None:
                break
        else:
            raise PlanningError("no path found in the search corridor")
        points = self._smooth(np.array(cells))
        if prefix:
            points = np.vstack([np.array(prefix), points])
        xs, ys = grid.cell_to_world(points[:, 0], points[:, 1])
        xy = np.stack([xs, ys], axis=1)
        xy[0] = start_xy
        xy[-1] = goal_xy
        length = float(np.hypot(*np.diff(xy, axis=0).T).sum()) if len(xy) > 1 else 0.0
        return Plan(xy, length)

    def _escape(self, cell):
        """Nearest free cell within start_escape_m of a start that lies in the inflated zone."""
        radius = int(math.ceil(self.start_escape_m / self.costmap.resolution))
        r0, c0 = max(cell[0] - radius, 0), max(cell[1] - radius, 0)
        window = self.costmap.cost[r0:cell[0] + radius + 1, c0:cell[1] + radius + 1]
        free = np.argwhere(np.isfinite(window))
        if len(free) == 0:
            return None
        d = np.hypot(free[:, 0] + r0 - cell[0], free[:, 1] + c0 - cell[1])
        best = np.argmin(d)
        if d[best] > radius:
            return None
        return int(free[best, 0] + r0), int(free[best, 1] + c0)

    def _coarse_route(self, start, goal):
        k = self.coarse_factor
        wc = self._coarse_shape[1]
        flat = self._coarse_flat

        def node(cell):
            target = (cell[0] // k) * wc + cell[1] // k
            return int(np.searchsorted(flat, target))

        s, g = node(start), node(goal)
        _dist, pred = dijkstra(self._coarse_graph, directed=True, indices=s, return_predecessors=True)
        if s != g and pred[g] < 0:
            return np.array([flat[s], flat[g]])  # cannot happen given the labels; corridor search decides
        return flat[_walk(pred, g)]

    def _fine_route(self, start, goal, coarse_route, blocks):
        k = self.coarse_factor
        hc, wc = self._coarse_shape
        corridor = np.zeros((hc, wc), dtype=bool)
        corridor.ravel()[coarse_route] = True
        corridor = ndimage.binary_dilation(corridor, structure=np.ones((3, 3), dtype=bool), iterations=blocks)
        br, bc = np.nonzero(corridor)
        rows = (br[:, None, None] * k + np.arange(k)[None, :, None] + np.zeros((1, 1, k), dtype=np.int64)).ravel()
        cols = (bc[:, None, None] * k + np.arange(k)[None, None, :] + np.zeros((1, k, 1), dtype=np.int64)).ravel()
        cost = self.costmap.cost
        height, width = cost.shape
        inside = (rows < height) & (cols < width)
        rows, cols = rows[inside], cols[inside]
        keep = np.isfinite(cost[rows, cols])
        flat = np.sort(rows[keep] * width + cols[keep])
        s = int(np.searchsorted(flat, start[0] * width + start[1]))
        g = int(np.searchsorted(flat, goal[0] * width + goal[1]))
        node_cost = cost.ravel()[flat].astype(np.float64)
        graph = grid_graph(flat, (height, width), node_cost, _OFFSETS_8 + _KNIGHT)
        _dist, pred = dijkstra(graph, directed=True, indices=s, return_predecessors=True)
        if s != g and pred[g] < 0:
            return None
        route = flat[_walk(pred, g)]
        return [tuple(rc) for rc in np.stack(np.divmod(route, width), axis=1)]

    def _segment_peak(self, a, b):
        """Highest cost on the straight segment between cells a and b (inf if it clips a lethal cell)."""
        steps = int(math.ceil(max(abs(b[0] - a[0]), abs(b[1] - a[1])) * 4)) + 1
        t = np.linspace(0.0, 1.0, steps)
        rows = np.rint(a[0] + (b[0] - a[0]) * t).astype(np.int64)
        cols = np.rint(a[1] + (b[1] - a[1]) * t).astype(np.int64)
        return float(self.costmap.cost[rows, cols].max())

    def _smooth(self, cells):
        """Greedy line-of-sight shortcutting; a shortcut may not pass costlier cells than it replaces."""
        if len(cells) <= 2:
            return cells
        cost = self.costmap.cost[cells[:, 0], cells[:, 1]]
        keep = [0]
        i, last = 0, len(cells) - 1

        def visible(j):
            return self._segment_peak(cells[i], cells[j]) <= cost[i:j + 1].max() + 1e-6

        while i < last:
            good, step = i + 1, 1
            while good + step <= last and visible(good + step):
                good += step
                step *= 2
            bad = min(good + step, last + 1)
            while bad - good > 1:  # binary search between the last visible and the first hidden
                mid = (good + bad) // 2
                if visible(mid):
                    good = mid
                else:
                    bad = mid
            keep.append(good)
            i = good
        return cells[keep]
