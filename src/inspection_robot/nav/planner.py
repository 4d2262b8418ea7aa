"""Global planner on the inflated costmap: coarse-to-fine Dijkstra on sparse grid graphs (SciPy).

A 200 m x 200 m yard at 5 cm is 16 million cells, too many for one graph search per goal. The
planner therefore works in three steps, all vectorised (no per-cell Python loop):

1. **Exact reachability**: the costmap's connected-component labels answer "no path" at once.
2. **Coarse search**: blocks of ``coarse_factor`` x ``coarse_factor`` cells form an 8-connected
   graph, kept per costmap change and updated only in the blocks a change touched. Two blocks are
   linked when free cells of theirs touch across the shared edge or corner; the edge costs the
   blocks' mean cell cost, raised for partly blocked blocks so the route prefers open space.
3. **Fine search** in a narrow corridor of blocks around the coarse route, on the 8-connected
   cell graph (widened if the corridor holds no path), then line-of-sight shortcutting that never
   raises the path's peak cost, which takes out the 8-connected zig-zag.

The fine graph is indexed block by block (node = corridor block rank x k^2 + offset in the
block), so building it costs time in proportion to the corridor, never to the map.
"""
import math
from collections import namedtuple

import numpy as np
from scipy import ndimage
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components, dijkstra

Plan = namedtuple("Plan", "points length")   # points: (N, 2) array of map metres

TOP = 4  # coarse blocks per top-level block side
_OFFSETS_8 = [(dr, dc) for dr in (-1, 0, 1) for dc in (-1, 0, 1) if (dr, dc) != (0, 0)]


class PlanningError(Exception):
    """No path; the message is the reason reported to the caller."""


def _walk(predecessors, target):
    pred = predecessors.tolist()  # plain ints: walking a NumPy array element by element is slow
    path = [int(target)]
    while pred[path[-1]] >= 0:
        path.append(pred[path[-1]])
    return path[::-1]


class Planner(object):
    def __init__(self, costmap, coarse_factor=8, corridor_blocks=(0, 2, 8), start_escape_m=1.0):
        if coarse_factor < 2:
            raise ValueError("coarse_factor must be >= 2")
        self.costmap = costmap
        self.coarse_factor = int(coarse_factor)
        self.corridor_blocks = tuple(int(c) for c in corridor_blocks)
        self.start_escape_m = float(start_escape_m)
        height, width = costmap.shape
        k = self.coarse_factor
        self._coarse_shape = (-(-height // k), -(-width // k))
        self._version = None
        self.refresh()

    # --- coarse graph --------------------------------------------------------------------------
    def refresh(self):
        """Bring the coarse graph up to date with the costmap (only the changed blocks)."""
        changes = self.costmap.changes_since(self._version) if self._version is not None else None
        if changes == []:
            return
        hc, wc = self._coarse_shape
        if changes is None:
            self._block_cost = np.zeros((hc, wc), dtype=np.float64)
            # free cells along each block's edges: [top, bottom, left, right], corners [tl, tr, bl, br]
            self._edge_free = np.zeros((4, hc, wc, self.coarse_factor), dtype=bool)
            self._corner_free = np.zeros((4, hc, wc), dtype=bool)
            self._update_blocks(0, hc, 0, wc)
        else:
            k = self.coarse_factor
            for w in changes:
                self._update_blocks(w.r0 // k, -(-w.r1 // k), w.c0 // k, -(-w.c1 // k))
        self._build_coarse_graph()
        self._version = self.costmap.version

    def _update_blocks(self, b0, b1, d0, d1):
        """Recompute the statistics of blocks rows [b0, b1) x cols [d0, d1)."""
        k = self.coarse_factor
        height, width = self.costmap.shape
        nr, nc = b1 - b0, d1 - d0
        padded = np.full((nr * k, nc * k), np.inf, dtype=np.float32)
        r1, c1 = min(b1 * k, height), min(d1 * k, width)
        padded[:r1 - b0 * k, :c1 - d0 * k] = self.costmap.cost[b0 * k:r1, d0 * k:c1]
        blocks = padded.reshape(nr, k, nc, k).transpose(0, 2, 1, 3)
        finite = np.isfinite(blocks)
        free_count = finite.sum(axis=(2, 3))
        mean_cost = np.where(finite, blocks, 0).sum(axis=(2, 3)) / np.maximum(free_count, 1)
        blocked_share = 1.0 - free_count / float(k * k)
        self._block_cost[b0:b1, d0:d1] = np.where(free_count > 0, mean_cost * (1.0 + 4.0 * blocked_share), np.inf)
        self._edge_free[:, b0:b1, d0:d1] = [finite[:, :, 0, :], finite[:, :, -1, :], finite[:, :, :, 0],
                                            finite[:, :, :, -1]]
        self._corner_free[:, b0:b1, d0:d1] = [finite[:, :, 0, 0], finite[:, :, 0, -1], finite[:, :, -1, 0],
                                              finite[:, :, -1, -1]]

    def _build_coarse_graph(self):
        hc, wc = self._coarse_shape
        cost = self._block_cost
        top, bottom, left, right = self._edge_free
        tl, tr, bl, br = self._corner_free
        passable = np.isfinite(cost)
        # linked[i, r, c]: block (r, c) links to its neighbour in direction _OFFSETS_8[i]
        linked = np.zeros((len(_OFFSETS_8), hc, wc), dtype=bool)
        for i, (dr, dc) in enumerate(_OFFSETS_8):
            a = (slice(max(-dr, 0), hc - max(dr, 0)), slice(max(-dc, 0), wc - max(dc, 0)))
            b = (slice(max(dr, 0), hc + min(dr, 0)), slice(max(dc, 0), wc + min(dc, 0)))
            if dr == 0:  # a free cell on my shared edge 8-adjacent to a free cell on its edge
                ok = _touch(right[a], left[b]) if dc > 0 else _touch(left[a], right[b])
            elif dc == 0:
                ok = _touch(bottom[a], top[b]) if dr > 0 else _touch(top[a], bottom[b])
            else:
                mine = {(1, 1): br, (1, -1): bl, (-1, 1): tr, (-1, -1): tl}[(dr, dc)]
                theirs = {(1, 1): tl, (1, -1): tr, (-1, 1): bl, (-1, -1): br}[(dr, dc)]
                ok = mine[a] & theirs[b]
            linked[i][a] = ok & passable[a] & passable[b]
        ids = np.arange(hc * wc).reshape(hc, wc)
        targets = np.stack([np.roll(np.roll(ids, -dr, axis=0), -dc, axis=1) for dr, dc in _OFFSETS_8])
        lengths = np.array([math.hypot(dr, dc) for dr, dc in _OFFSETS_8])
        weights = lengths[:, None, None] * 0.5 * (cost[None] + cost.ravel()[targets])
        order = linked.transpose(1, 2, 0).reshape(-1, len(_OFFSETS_8))  # CSR order: by source node
        self._coarse = _CsrParts(order, targets.transpose(1, 2, 0).reshape(order.shape),
                                 weights.transpose(1, 2, 0).reshape(order.shape))
        self._build_top_graph(linked, targets)

    def _build_top_graph(self, linked, targets):
        """Abstract graph over TOP x TOP blocks of coarse blocks, one node per connected part.

        A node is a set of coarse blocks linked within one top block (so a wall through a top
        block gives two nodes, and the abstraction never routes through it); two nodes are linked
        when a coarse link joins them. Its route confines the coarse search, which keeps it from
        flooding the space in front of a long wall.
        """
        hc, wc = self._coarse_shape
        n = hc * wc
        ht, wt = -(-hc // TOP), -(-wc // TOP)
        rows, cols = np.divmod(np.arange(n), wc)
        top_block = (rows // TOP) * wt + cols // TOP
        src = np.broadcast_to(np.arange(n).reshape(1, hc, wc), linked.shape)[linked]
        dst = targets[linked]
        inner = top_block[src] == top_block[dst]
        graph = csr_matrix((np.ones(int(inner.sum())), (src[inner], dst[inner])), shape=(n, n))
        count, part = connected_components(graph, directed=True, connection="weak")
        cross = ~inner
        pairs = np.unique(part[src[cross]] * count + part[dst[cross]])
        a, b = np.divmod(pairs, count)
        passable = np.isfinite(self._block_cost).ravel()
        members = np.maximum(np.bincount(part, weights=passable, minlength=count), 1)
        mean_cost = np.bincount(part, weights=np.where(passable, self._block_cost.ravel(), 0.0),
                                minlength=count) / members
        centre_r = np.bincount(part, weights=rows * passable, minlength=count) / members
        centre_c = np.bincount(part, weights=cols * passable, minlength=count) / members
        weight = np.hypot(centre_r[a] - centre_r[b], centre_c[a] - centre_c[b]) * 0.5 * (mean_cost[a] + mean_cost[b])
        self._part = part
        self._top_block = top_block
        self._top_shape = (ht, wt)
        self._top_graph = csr_matrix((np.maximum(weight, 1e-6), (a, b)), shape=(count, count))

    # --- planning ------------------------------------------------------------------------------
    def plan(self, start_xy, goal_xy):
        """Return a Plan from ``start_xy`` to ``goal_xy`` (map metres) or raise PlanningError."""
        self.refresh()
        grid, cost = self.costmap.grid, self.costmap.cost
        if not all(math.isfinite(v) for v in tuple(start_xy) + tuple(goal_xy)):
            raise PlanningError("start and goal must be finite numbers")
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
        points = self._smooth(cells)
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
        """Flat block ids of the cheapest block route (None when the coarse graph has none).

        The search first stays within one top-level block of the top-level route, which keeps
        it small and keeps it from flooding the space in front of a long wall.
        """
        k = self.coarse_factor
        wc = self._coarse_shape[1]
        s = (start[0] // k) * wc + start[1] // k
        g = (goal[0] // k) * wc + goal[1] // k
        if s == g:
            return np.array([s])
        top_s, top_g = int(self._part[s]), int(self._part[g])
        _dist, pred = dijkstra(self._top_graph, directed=True, indices=top_s, return_predecessors=True)
        if top_s == top_g or pred[top_g] >= 0:
            on_route = np.zeros(self._top_graph.shape[0], dtype=bool)
            on_route[_walk(pred, top_g)] = True
            ht, wt = self._top_shape
            near = np.zeros(ht * wt, dtype=bool)
            near[self._top_block[on_route[self._part]]] = True
            near = ndimage.binary_dilation(near.reshape(ht, wt), structure=np.ones((3, 3), dtype=bool)).ravel()
            nodes = np.flatnonzero(on_route[self._part] | near[self._top_block])
            route = _search(self._coarse.subgraph(nodes), int(np.searchsorted(nodes, s)),
                            int(np.searchsorted(nodes, g)))
            if route is not None:
                return nodes[route]
        everything = np.arange(self._coarse.n)
        return _search(self._coarse.subgraph(everything), s, g)

    def _fine_route(self, start, goal, coarse_route, blocks):
        """Cells [(row, col), ...] of the cheapest 8-connected path inside the corridor, or None."""
        k = self.coarse_factor
        hc, wc = self._coarse_shape
        cost = self.costmap.cost
        height, width = cost.shape
        corridor = np.zeros((hc, wc), dtype=bool)
        if coarse_route is None:  # fall back to the bounding box of start and goal
            if blocks != self.corridor_blocks[-1]:
                return None
            corridor[min(start[0], goal[0]) // k:max(start[0], goal[0]) // k + 1,
                     min(start[1], goal[1]) // k:max(start[1], goal[1]) // k + 1] = True
        else:
            corridor.ravel()[coarse_route] = True
            corridor[start[0] // k, start[1] // k] = corridor[goal[0] // k, goal[1] // k] = True
        if blocks > 0:  # (iterations=0 would dilate until nothing changes)
            corridor = ndimage.binary_dilation(corridor, structure=np.ones((3, 3), dtype=bool), iterations=blocks)
        rank = np.full((hc + 2, wc + 2), -1, dtype=np.int64)  # one block of padding all round
        br, bc = np.nonzero(corridor)
        rank[br + 1, bc + 1] = np.arange(len(br))
        kk = k * k
        # node i -> block br[i // kk], cell offset divmod(i % kk, k)
        offset_r, offset_c = np.divmod(np.arange(kk), k)
        rows = (br[:, None] * k + offset_r[None, :]).ravel()
        cols = (bc[:, None] * k + offset_c[None, :]).ravel()
        inside = (rows < height) & (cols < width)
        node_cost = np.full(rows.shape, np.inf, dtype=np.float64)
        node_cost[inside] = cost[rows[inside], cols[inside]]
        free = np.flatnonzero(np.isfinite(node_cost))
        fr, fc = rows[free], cols[free]
        targets, linked = [], []
        for dr, dc in _OFFSETS_8:
            nr, nc = fr + dr, fc + dc
            target = rank[(nr + k) // k, (nc + k) // k]  # padding makes row -1 -> block -1 -> rank -1
            ok = target >= 0
            target = np.where(ok, target * kk + (nr % k) * k + nc % k, 0)
            linked.append(ok & np.isfinite(node_cost[target]))
            targets.append(target)
        targets = np.stack(targets, axis=1)
        linked = np.stack(linked, axis=1)
        lengths = np.array([math.hypot(dr, dc) for dr, dc in _OFFSETS_8])
        weights = lengths[None, :] * 0.5 * (node_cost[free][:, None] + node_cost[targets])
        parts = _CsrParts(linked, targets, weights, free, len(rows))

        def node(cell):
            return rank[cell[0] // k + 1, cell[1] // k + 1] * kk + (cell[0] % k) * k + cell[1] % k

        s, g = node(start), node(goal)
        route = _search(parts.subgraph(None), s, g)
        if route is None:
            return None
        return np.stack([rows[route], cols[route]], axis=1)

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


class _CsrParts(object):
    """A directed graph in CSR order: node ``nodes[i]`` has edges to ``targets[i][linked[i]]``.

    ``subgraph`` cuts out the part a search may use.
    """

    def __init__(self, linked, targets, weights, nodes=None, n=None):
        counts = linked.sum(axis=1)
        n = len(linked) if n is None else n
        per_node = np.zeros(n, dtype=np.int64)
        per_node[np.arange(len(linked)) if nodes is None else nodes] = counts
        self.n = n
        self.indptr = np.concatenate([[0], np.cumsum(per_node)])
        self.indices = targets[linked]
        self.weights = weights[linked]

    def subgraph(self, nodes):
        """CSR matrix of the graph restricted to ``nodes`` (sorted ids, renumbered 0..); None: all."""
        if nodes is None:
            return csr_matrix((self.weights, self.indices, self.indptr), shape=(self.n, self.n))
        local = np.full(self.n, -1, dtype=np.int64)
        local[nodes] = np.arange(len(nodes))
        starts = self.indptr[nodes]
        counts = self.indptr[nodes + 1] - starts
        total = int(counts.sum())
        first = np.cumsum(counts) - counts
        edges = np.repeat(starts - first, counts) + np.arange(total)
        targets = local[self.indices[edges]]
        ok = targets >= 0
        sources = np.repeat(np.arange(len(nodes)), counts)
        return csr_matrix((self.weights[edges][ok], (sources[ok], targets[ok])), shape=(len(nodes), len(nodes)))


def _search(graph, s, g):
    """Node path from s to g on a CSR graph (Dijkstra), or None if there is none."""
    if s == g:
        return np.array([s])
    _dist, pred = dijkstra(graph, directed=True, indices=s, return_predecessors=True)
    if pred[g] < 0:
        return None
    return np.array(_walk(pred, g))


def _touch(edge_a, edge_b):
    """Per block pair: a free cell of edge_a (..., k) is 8-adjacent to a free cell of edge_b."""
    widened = edge_b.copy()
    widened[..., 1:] |= edge_b[..., :-1]
    widened[..., :-1] |= edge_b[..., 1:]
    return (edge_a & widened).any(axis=-1)
