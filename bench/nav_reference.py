"""Optimal reference for the planner benchmark: Dijkstra over every free cell of a window (SciPy).

The graph is the plain 8-connected grid over the costmap's finite cells, edge weight = step
length x mean cost of its two ends, the same cost model the planner uses. The window is the
pair's bounding box plus a margin; ``touches_border`` says the optimum ran along the window's edge
(then a path outside the window might be cheaper and the sample is not used).
"""
import math

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra


def reference_path(costmap, start_xy, goal_xy, margin_m=15.0, max_cells=6000000):
    """Return (cells (N, 2) of the min-cost 8-connected path, its cost, touches_border) or None.

    None also when the window would exceed ``max_cells`` (the graph would not fit the memory).
    """
    grid = costmap.grid
    a, b = grid.world_to_cell(*start_xy), grid.world_to_cell(*goal_xy)
    m = int(margin_m / grid.resolution)
    r0, r1 = max(min(a[0], b[0]) - m, 0), min(max(a[0], b[0]) + m + 1, grid.height)
    c0, c1 = max(min(a[1], b[1]) - m, 0), min(max(a[1], b[1]) + m + 1, grid.width)
    if (r1 - r0) * (c1 - c0) > max_cells:
        return None
    cost = costmap.cost[r0:r1, c0:c1].astype(np.float64)
    h, w = cost.shape
    free = np.isfinite(cost)
    index = np.full((h, w), -1, dtype=np.int64)
    index[free] = np.arange(int(free.sum()))
    src, dst, weight = [], [], []
    for dr, dc in ((0, 1), (1, -1), (1, 0), (1, 1)):  # each undirected edge once
        ra, ca = slice(max(-dr, 0), h - max(dr, 0)), slice(max(-dc, 0), w - max(dc, 0))
        rb, cb = slice(max(dr, 0), h + min(dr, 0)), slice(max(dc, 0), w + min(dc, 0))
        ia, ib = index[ra, ca], index[rb, cb]
        ok = (ia >= 0) & (ib >= 0)
        src.append(ia[ok])
        dst.append(ib[ok])
        weight.append(math.hypot(dr, dc) * 0.5 * (cost[ra, ca][ok] + cost[rb, cb][ok]))
    n = int(free.sum())
    graph = csr_matrix((np.concatenate(weight), (np.concatenate(src), np.concatenate(dst))), shape=(n, n))
    s, g = index[a[0] - r0, a[1] - c0], index[b[0] - r0, b[1] - c0]
    dist, pred = dijkstra(graph, directed=False, indices=int(s), return_predecessors=True)
    if not np.isfinite(dist[g]):
        return None
    route = [int(g)]
    while pred[route[-1]] >= 0:
        route.append(int(pred[route[-1]]))
    rows, cols = np.nonzero(free)
    cells = np.stack([rows[route[::-1]] + r0, cols[route[::-1]] + c0], axis=1)
    touches = bool(((cells[:, 0] == r0) | (cells[:, 0] == r1 - 1) | (cells[:, 1] == c0) | (cells[:, 1] == c1 - 1)).any()
                   and (r0 > 0 or c0 > 0 or r1 < grid.height or c1 < grid.width))
    return cells, float(dist[g]), touches


def path_cost(costmap, points_xy):
    """Cost of a polyline in map metres on the costmap, in cells x cost (the reference's unit)."""
    grid = costmap.grid
    total = 0.0
    for p, q in zip(points_xy[:-1], points_xy[1:]):
        length = math.hypot(q[0] - p[0], q[1] - p[1]) / grid.resolution
        steps = max(int(math.ceil(length * 2)), 1)
        t = (np.arange(steps) + 0.5) / steps
        cols = np.floor((p[0] + (q[0] - p[0]) * t - grid.origin[0]) / grid.resolution).astype(np.int64)
        rows = np.floor((p[1] + (q[1] - p[1]) * t - grid.origin[1]) / grid.resolution).astype(np.int64)
        total += float(costmap.cost[rows, cols].mean()) * length
    return total
