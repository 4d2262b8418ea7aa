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
        k = self.coarse_factor
        if changes is None:
            self._block_cost = np.zeros((hc, wc), dtype=np.float64)
            # free cells along each block's edges: [top, bottom, left, right], corners [tl, tr, bl, br]
            self._edge_free = np.zeros((4, hc, wc, k), dtype=bool)
            self._corner_free = np.zeros((4, hc, wc), dtype=bool)
            # per block and direction _OFFSETS_8[i]: the neighbour, whether linked, the edge weight
            rows, cols = np.mgrid[0:hc, 0:wc]
            self._targets = np.stack([((rows + dr) % hc) * wc + (cols + dc) % wc for dr, dc in _OFFSETS_8], axis=2)
            self._linked = np.zeros((hc, wc, len(_OFFSETS_8)), dtype=bool)
            self._weights = np.zeros((hc, wc, len(_OFFSETS_8)), dtype=np.float64)
            changes = [None]
            ht, wt = -(-hc // TOP), -(-wc // TOP)
            self._top_shape = (ht, wt)
            self._top_block = ((rows // TOP) * wt + cols // TOP).ravel()
            self._part = np.zeros(hc * wc, dtype=np.int64)
            self._part_cost = np.zeros(hc * wc)
            self._part_row = np.zeros(hc * wc)
            self._part_col = np.zeros(hc * wc)
            self._top_edges = [np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0)]
        for w in changes:
            b0, b1, d0, d1 = (0, hc, 0, wc) if w is None else (w.r0 // k, -(-w.r1 // k), w.c0 // k, -(-w.c1 // k))
            self._update_blocks(b0, b1, d0, d1)
            # links of the changed blocks and of their neighbours (into the changed blocks)
            b0, b1, d0, d1 = max(b0 - 1, 0), min(b1 + 1, hc), max(d0 - 1, 0), min(d1 + 1, wc)
            self._update_links(b0, b1, d0, d1)
            ht, wt = self._top_shape
            self._update_top(max(b0 // TOP - 1, 0), min(-(-b1 // TOP) + 1, ht),
                             max(d0 // TOP - 1, 0), min(-(-d1 // TOP) + 1, wt))
        self._coarse = _CsrParts(self._targets.reshape(hc * wc, -1),
                                 np.where(self._linked, self._weights, np.inf).reshape(hc * wc, -1))
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

    def _update_links(self, b0, b1, d0, d1):
        """Recompute the links (and weights) leaving blocks rows [b0, b1) x cols [d0, d1)."""
        hc, wc = self._coarse_shape
        top, bottom, left, right = self._edge_free
        tl, tr, bl, br = self._corner_free
        cost = self._block_cost
        rows, cols = np.mgrid[b0:b1, d0:d1]
        for i, (dr, dc) in enumerate(_OFFSETS_8):
            nr, nc = rows + dr, cols + dc
            inside = (nr >= 0) & (nr < hc) & (nc >= 0) & (nc < wc)
            nr, nc = np.clip(nr, 0, hc - 1), np.clip(nc, 0, wc - 1)
            mine, theirs = (rows, cols), (nr, nc)
            if dr == 0:  # a free cell on my shared edge 8-adjacent to a free cell on its edge
                ok = _touch(right[mine], left[theirs]) if dc > 0 else _touch(left[mine], right[theirs])
            elif dc == 0:
                ok = _touch(bottom[mine], top[theirs]) if dr > 0 else _touch(top[mine], bottom[theirs])
            else:
                corner = {(1, 1): (br, tl), (1, -1): (bl, tr), (-1, 1): (tr, bl), (-1, -1): (tl, br)}[(dr, dc)]
                ok = corner[0][mine] & corner[1][theirs]
            self._linked[b0:b1, d0:d1, i] = ok & inside & np.isfinite(cost[mine]) & np.isfinite(cost[theirs])
            self._weights[b0:b1, d0:d1, i] = math.hypot(dr, dc) * 0.5 * (cost[mine] + cost[theirs])

    def _update_top(self, t0, t1, u0, u1):
        """Re-derive the top-level parts and their edges for top blocks rows [t0, t1) x cols [u0, u1).

        The window must include one top block of margin around every changed coarse block: edges
        from outside it then keep their ends and weights. A part's id is its smallest coarse block
        id, so a window update gives the same ids as a full build.
        """
        hc, wc = self._coarse_shape
        n = hc * wc
        rows, cols = np.mgrid[t0 * TOP:min(t1 * TOP, hc), u0 * TOP:min(u1 * TOP, wc)]
        nodes = (rows * wc + cols).ravel()  # ascending
        m = len(nodes)
        local = np.full(n, -1, dtype=np.int64)
        local[nodes] = np.arange(m)
        linked = self._linked.reshape(n, -1)[nodes]
        targets = self._targets.reshape(n, -1)[nodes]
        block = self._top_block[nodes]
        inner = linked & (self._top_block[targets] == block[:, None])
        src = np.repeat(np.arange(m), inner.sum(axis=1))
        graph = csr_matrix((np.ones(len(src)), (src, local[targets[inner]])), shape=(m, m))
        count, comp = connected_components(graph, directed=True, connection="weak")
        _labels, first = np.unique(comp, return_index=True)  # nodes ascend: first member = smallest id
        part = nodes[first][comp]
        self._part[nodes] = part
        cost = self._block_cost.ravel()[nodes]
        passable = np.isfinite(cost)
        members = np.maximum(np.bincount(comp, weights=passable, minlength=count), 1)
        ids = nodes[first]
        self._part_cost[ids] = np.bincount(comp, weights=np.where(passable, cost, 0.0), minlength=count) / members
        self._part_row[ids] = np.bincount(comp, weights=(nodes // wc) * passable, minlength=count) / members
        self._part_col[ids] = np.bincount(comp, weights=(nodes % wc) * passable, minlength=count) / members
        # edges leaving the window's parts, one per pair of parts
        cross = linked & ~inner
        a = np.repeat(part, cross.sum(axis=1))
        b = self._part[targets[cross]]
        pairs = np.unique(a * n + b)
        a, b = np.divmod(pairs, n)
        ht, wt = self._top_shape
        in_window = np.zeros(ht * wt, dtype=bool)
        in_window.reshape(ht, wt)[t0:t1, u0:u1] = True
        keep = ~in_window[self._top_block[self._top_edges[0]]]
        weight = np.hypot(self._part_row[a] - self._part_row[b], self._part_col[a] - self._part_col[b]) \
            * 0.5 * (self._part_cost[a] + self._part_cost[b])
        self._top_edges = [np.concatenate([e[keep], new]) for e, new in zip(self._top_edges, (a, b, weight))]
        ea, eb, ew = self._top_edges
        self._top_graph = csr_matrix((np.maximum(ew, 1e-6), (ea, eb)), shape=(n, n))

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
        if not self.costmap.connected(start, goal):
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
        parts = _CsrParts(targets, np.where(linked, weights, np.inf), free, len(rows))

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
    """A directed graph with a fixed number of edge slots per node (infinite weight: no edge).

    Slot j of row i goes to ``targets[i, j]``; the rows are ``nodes`` (sorted ids, None: 0..)
    of a graph of ``n`` nodes. Fixed slots keep a window update to an in-place write.
    """

    def __init__(self, targets, weights, nodes=None, n=None):
        slots = targets.shape[1]
        n = len(targets) if n is None else n
        per_node = np.zeros(n, dtype=np.int64)
        per_node[slice(None) if nodes is None else nodes] = slots
        self.n = n
        self.indptr = np.concatenate([[0], np.cumsum(per_node)])
        self.indices = targets.ravel()
        self.weights = weights.ravel()

    def subgraph(self, nodes):
        """CSR matrix of the graph restricted to ``nodes`` (sorted ids, renumbered 0..); None: all."""
        if nodes is None:
            nodes = np.arange(self.n)
        local = np.full(self.n, -1, dtype=np.int64)
        local[nodes] = np.arange(len(nodes))
        starts = self.indptr[nodes]
        counts = self.indptr[nodes + 1] - starts
        total = int(counts.sum())
        first = np.cumsum(counts) - counts
        edges = np.repeat(starts - first, counts) + np.arange(total)
        targets = local[self.indices[edges]]
        ok = (targets >= 0) & np.isfinite(self.weights[edges])
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
