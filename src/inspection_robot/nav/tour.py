"""The shortest order of a patrol's stops: a path from the robot through every stop to the home pose.

``lengths`` is the matrix of the planner's path lengths between the points (index 0 the start,
the last index the end; the stops in between), so the tour follows the yard's roads, not straight
lines. The start and the end stay where they are; when they are the same place the path is a
closed tour.

Up to ``EXACT_MAX_STOPS`` stops the order is exact (Held-Karp dynamic programming over subsets).
Above, it is iterated local search: cheapest insertion, then 2-opt and Or-opt moves until none
shortens the path, then a random double-bridge kick and local search again, keeping the best,
for a fixed number of kicks with a fixed seed (the same stops give the same order). The planner's
lengths are symmetric up to smoothing; the search uses the mean of both directions and the length
it reports is the sum of the matrix along the chosen order.

A plan costs milliseconds to tens of milliseconds on a large yard, so ``order_points`` does not
plan every pair: it plans each point's nearest neighbours, stands in the straight-line distance (a
lower bound of any path) for the others, orders, plans the legs of that order it had only bounded,
and orders again until every leg of the order is a planned one. Every leg of the result is then a
real path length, and no unplanned leg could have been shorter than the bound it was judged by.
"""
import math
import random

import numpy as np

EXACT_MAX_STOPS = 11
DEFAULT_KICKS = 100   # as good as 300 on bench_tour's yards, a third of the time


class TourError(ValueError):
    """The stops cannot be ordered (a stop unreachable from another, a malformed matrix)."""


def path_length(lengths, order):
    """Sum of ``lengths`` along ``order`` (consecutive pairs)."""
    return float(sum(lengths[a][b] for a, b in zip(order, order[1:])))


def shortest_order(lengths, kicks=DEFAULT_KICKS, seed=0, start=None):
    """The visiting order (indices into ``lengths``, starting with 0, ending with n-1) and its length.

    ``lengths``: n x n (n >= 2) path lengths, row = from, column = to; inf where there is no path.
    ``start``: an order to improve instead of building one (the local search only).
    """
    d = np.asarray(lengths, dtype=float)
    if d.ndim != 2 or d.shape[0] != d.shape[1] or d.shape[0] < 2:
        raise TourError("lengths must be a square matrix of at least 2 x 2, got shape %s" % (d.shape,))
    if np.isnan(d).any() or (d < 0).any():
        raise TourError("lengths must be non-negative numbers")
    n = d.shape[0]
    if not np.isfinite(d).all():
        i, j = np.argwhere(~np.isfinite(d))[0]
        raise TourError("no path from point %d to point %d" % (i, j))
    sym = (d + d.T) / 2.0
    if n - 2 <= EXACT_MAX_STOPS:
        order = _held_karp(sym)
    else:
        order = _local_search(sym, kicks, random.Random(seed), start)
    return order, path_length(d, order)


def _held_karp(d):
    """Exact shortest path 0 -> every stop -> n-1 over the stops 1..n-2."""
    n = d.shape[0]
    stops = list(range(1, n - 1))
    m = len(stops)
    if m == 0:
        return [0, n - 1]
    full = (1 << m) - 1
    # cost[mask][k]: shortest path from 0 through the stops in mask, ending at stop k (k in mask)
    cost = np.full((1 << m, m), math.inf)
    parent = np.full((1 << m, m), -1, dtype=int)
    for k in range(m):
        cost[1 << k, k] = d[0, stops[k]]
    sub = d[np.ix_(stops, stops)]
    for mask in range(1, 1 << m):
        row = cost[mask]
        if not np.isfinite(row).any():
            continue
        for k in range(m):
            bit = 1 << k
            if mask & bit:
                continue
            # best last stop j in mask before going to k
            through = row + sub[:, k]
            j = int(np.argmin(through))
            if through[j] < cost[mask | bit, k]:
                cost[mask | bit, k] = through[j]
                parent[mask | bit, k] = j
    last = cost[full] + d[stops, n - 1]
    k = int(np.argmin(last))
    order, mask = [], full
    while k >= 0:
        order.append(stops[k])
        mask, k = mask & ~(1 << k), int(parent[mask, k])
    return [0] + order[::-1] + [n - 1]


def _insertion(d):
    """Cheapest insertion of every stop into the path [0, n-1], farthest stop first."""
    n = d.shape[0]
    path = [0, n - 1]
    left = sorted(range(1, n - 1), key=lambda s: -(d[0, s] + d[s, n - 1]))
    for s in left:
        a, b = np.array(path[:-1]), np.array(path[1:])
        extra = d[a, s] + d[s, b] - d[a, b]
        i = int(np.argmin(extra))
        path.insert(i + 1, s)
    return path


def _two_opt(d, path):
    """Reverse segments path[i..j] while one shortens the path (first improvement per i)."""
    improved = True
    n = len(path)
    while improved:
        improved = False
        for i in range(1, n - 2):
            p = np.array(path)
            a, b = p[i - 1], p[i]
            c, e = p[i:n - 1], p[i + 1:n]     # candidate segment ends j = i..n-2: c = path[j], e = path[j+1]
            delta = d[a, c] + d[b, e] - d[a, b] - d[c, e]
            j = int(np.argmin(delta))
            if delta[j] < -1e-9:
                path[i:i + j + 1] = path[i:i + j + 1][::-1]
                improved = True
    return path


def _or_opt(d, path):
    """Move a run of 1-3 consecutive stops elsewhere (either way round) while that shortens the path."""
    improved = True
    while improved:
        improved = False
        n = len(path)
        for size in (1, 2, 3):
            for i in range(1, n - size):
                seg = path[i:i + size]
                before, after = path[i - 1], path[i + size]
                gain = d[before, seg[0]] + d[seg[-1], after] - d[before, after]
                rest = path[:i] + path[i + size:]
                p = np.array(rest)
                a, b = p[:-1], p[1:]
                fwd = d[a, seg[0]] + d[seg[-1], b] - d[a, b]
                rev = d[a, seg[-1]] + d[seg[0], b] - d[a, b]
                k_f, k_r = int(np.argmin(fwd)), int(np.argmin(rev))
                if min(fwd[k_f], rev[k_r]) < gain - 1e-9:
                    if fwd[k_f] <= rev[k_r]:
                        rest[k_f + 1:k_f + 1] = seg
                    else:
                        rest[k_r + 1:k_r + 1] = seg[::-1]
                    path[:] = rest
                    improved = True
                    break
            if improved:
                break
    return path


def _descend(d, path):
    while True:
        before = path_length(d, path)
        _or_opt(d, _two_opt(d, path))
        if path_length(d, path) >= before - 1e-9:
            return path


def _double_bridge(path, rng):
    """Cut the stops into four runs A B C D and join them as A C B D (a move 2-opt cannot undo)."""
    inner = path[1:-1]
    if len(inner) < 8:
        rng.shuffle(inner)
        return [path[0]] + inner + [path[-1]]
    i, j, k = sorted(rng.sample(range(1, len(inner)), 3))
    inner = inner[:i] + inner[j:k] + inner[i:j] + inner[k:]
    return [path[0]] + inner + [path[-1]]


def _local_search(d, kicks, rng, start=None):
    best = _descend(d, list(start) if start is not None else _insertion(d))
    best_len = path_length(d, best)
    current, current_len = list(best), best_len
    for _ in range(kicks):
        candidate = _descend(d, _double_bridge(current, rng))
        length = path_length(d, candidate)
        if length < current_len - 1e-9:
            current, current_len = candidate, length
            if length < best_len - 1e-9:
                best, best_len = list(candidate), length
    return best


def order_points(points, measure, neighbours=8, kicks=DEFAULT_KICKS, seed=0):
    """Order ``points`` [(x, y), ...] (first = start, last = end) by path length.

    ``measure(i, j)`` returns the path length between points i and j (raising TourError when there
    is none); it is called once per pair at most, and only for the pairs the order needs.
    Returns (order, length, pairs measured).
    """
    xy = np.asarray(points, dtype=float)
    n = len(xy)
    if xy.ndim != 2 or n < 2:
        raise TourError("at least a start and an end are needed")
    d = np.hypot(*(xy[:, None, :] - xy[None, :, :]).transpose(2, 0, 1))
    known = set()

    def plan(i, j):
        if i == j or (min(i, j), max(i, j)) in known:
            return
        length = float(measure(i, j))
        if not math.isfinite(length):
            raise TourError("no path from point %d to point %d" % (i, j))
        d[i, j] = d[j, i] = max(length, d[i, j])   # never below the straight line
        known.add((min(i, j), max(i, j)))

    for i in range(n):
        for j in np.argsort(d[i])[1:neighbours + 1]:
            plan(i, int(j))
    order, _length = shortest_order(d, kicks, seed)
    while True:
        legs = [(a, b) for a, b in zip(order, order[1:]) if a != b and (min(a, b), max(a, b)) not in known]
        if not legs:
            return order, path_length(d, order), len(known)
        for a, b in legs:
            plan(a, b)
        # the planned legs only grew: improve the last order rather than search from scratch
        order, _length = shortest_order(d, max(1, kicks // 4), seed, start=order)
