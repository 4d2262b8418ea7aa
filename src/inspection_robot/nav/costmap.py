"""Planning costmap: static map + rasterised virtual obstacles, inflated by the robot's footprint.

Virtual obstacles are drawn into a layer of their own that only the planner sees; the static
map published for localization is never modified. Inflation uses an exact Euclidean distance
transform (OpenCV): cells closer than ``robot_radius`` to an obstacle are lethal, cells within
``robot_radius + safety_margin`` carry a cost that decays linearly, so paths keep clear of walls
when they can. Free space is labelled into 8-connected components, so "goal unreachable" is
answered exactly without searching: each ``LABEL_BLOCK`` x ``LABEL_BLOCK`` block is labelled on
its own (OpenCV) and the block-local components are joined across block seams with a sparse
connected-components pass (SciPy), so a change relabels only the blocks it touches.

A change of the virtual layer is incremental: only the window its polylines and their inflation
touch is redrawn and re-inflated (a cell's cost depends on obstacles within
``robot_radius + safety_margin`` only), and the result equals a full rebuild exactly.
``version`` counts changes and ``changes_since(version)`` tells a planner which windows to update.
"""
import math

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from inspection_robot.lazy import lazy_import
from inspection_robot.nav.gridmap import OCC_UNKNOWN

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load

LETHAL = np.float32(np.inf)
_SHIFT = 4  # sub-pixel bits of cv2.polylines
LABEL_BLOCK = 256  # cells per side of a free-space labelling block


class Window(object):
    """Half-open cell rectangle rows [r0, r1) x cols [c0, c1)."""

    __slots__ = ("r0", "r1", "c0", "c1")

    def __init__(self, r0, r1, c0, c1):
        self.r0, self.r1, self.c0, self.c1 = int(r0), int(r1), int(c0), int(c1)

    def empty(self):
        return self.r0 >= self.r1 or self.c0 >= self.c1

    def grown(self, cells, shape):
        return Window(max(self.r0 - cells, 0), min(self.r1 + cells, shape[0]),
                      max(self.c0 - cells, 0), min(self.c1 + cells, shape[1]))

    def union(self, other):
        if self.empty():
            return other
        if other.empty():
            return self
        return Window(min(self.r0, other.r0), max(self.r1, other.r1), min(self.c0, other.c0), max(self.c1, other.c1))

    def overlaps(self, other):
        return not (self.empty() or other.empty() or self.r1 <= other.r0 or other.r1 <= self.r0
                    or self.c1 <= other.c0 or other.c1 <= self.c0)

    def slices(self):
        return slice(self.r0, self.r1), slice(self.c0, self.c1)

    def __repr__(self):
        return "Window(%d, %d, %d, %d)" % (self.r0, self.r1, self.c0, self.c1)


def _fixed_point(points, resolution, origin):
    """Polyline vertices in cv2.polylines' fixed-point map coordinates (col, row) << _SHIFT."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    scale = float(1 << _SHIFT) / resolution
    # cell (row, col) has its centre at origin + (col + 0.5, row + 0.5) * resolution
    cols = (pts[:, 0] - origin[0]) * scale - (1 << (_SHIFT - 1))
    rows = (pts[:, 1] - origin[1]) * scale - (1 << (_SHIFT - 1))
    poly = np.round(np.stack([cols, rows], axis=1)).astype(np.int64)
    if len(poly) == 1:
        poly = np.concatenate([poly, poly])
    return poly


def _draw(mask, poly, closed, r0=0, c0=0):
    """Draw a fixed-point polyline into ``mask`` whose cell (0, 0) is map cell (r0, c0)."""
    local = poly - np.array([c0 << _SHIFT, r0 << _SHIFT], dtype=np.int64)
    cv2.polylines(mask, [local.astype(np.int32).reshape(-1, 1, 2)], bool(closed), 1, thickness=1,
                  lineType=cv2.LINE_8, shift=_SHIFT)


def _bounds(poly, shape):
    """Window of the cells a fixed-point polyline can touch, clipped to the map (may be empty)."""
    cells = poly >> _SHIFT
    return Window(cells[:, 1].min() - 1, cells[:, 1].max() + 3, cells[:, 0].min() - 1, cells[:, 0].max() + 3) \
        .grown(0, shape)


def rasterise_polylines(shape, polylines, resolution, origin):
    """Draw polylines ``[(points, closed), ...]`` (map metres) into a boolean mask of ``shape``.

    Lines are 8-connected and one cell wide, drawn with sub-cell precision, so a wall has no
    diagonal gap a 4-neighbour step could slip through once inflated by at least one cell.
    """
    mask = np.zeros(shape, dtype=np.uint8)
    for points, closed in polylines:
        if len(points) == 0:
            continue
        _draw(mask, _fixed_point(points, resolution, origin), closed)
    return mask.astype(bool)


class _Polyline(object):
    __slots__ = ("key", "poly", "closed", "bounds")

    def __init__(self, key, poly, closed, bounds):
        self.key, self.poly, self.closed, self.bounds = key, poly, closed, bounds


class Costmap(object):
    """Inflated traversal cost per cell: 1.0 free .. 1 + margin_cost near obstacles, inf lethal."""

    def __init__(self, grid, robot_radius, safety_margin, margin_cost=4.0, unknown_is_obstacle=True):
        if robot_radius < 0 or safety_margin < 0:
            raise ValueError("robot_radius and safety_margin must be >= 0")
        self.grid = grid
        self.robot_radius = float(robot_radius)
        self.safety_margin = float(safety_margin)
        self.margin_cost = float(margin_cost)
        static = grid.occupancy >= 65
        if unknown_is_obstacle:
            static |= grid.occupancy == OCC_UNKNOWN
        self._static = static
        self.virtual = np.zeros_like(static)
        self._polylines = []
        # a cell's cost depends on obstacle cells within this many cells (+1 for rounding)
        self._reach = int(math.ceil((self.robot_radius + self.safety_margin) / grid.resolution)) + 2
        self.cost = None
        blocks = (-(-static.shape[0] // LABEL_BLOCK), -(-static.shape[1] // LABEL_BLOCK))
        self._local = np.zeros(static.shape, dtype=np.int32)  # block-local component, 0: not free
        self._block_count = np.zeros(blocks, dtype=np.int64)  # components per labelling block
        self._component = np.zeros(0, dtype=np.int64)  # global component per block-local one
        self._base = np.zeros(blocks[0] * blocks[1] + 1, dtype=np.int64)
        self._seams = {}  # labelling block -> its links across its right and bottom seams
        self.version = 0
        self._changes = []  # (version, Window or None = everything)
        self.rebuild()

    @property
    def resolution(self):
        return self.grid.resolution

    @property
    def shape(self):
        return self._static.shape

    def set_virtual(self, polylines):
        """Replace the virtual obstacle layer with ``[(points, closed), ...]`` and re-inflate.

        Only the polylines that differ from the current layer are redrawn, and only the window
        they and their inflation touch is re-inflated. Returns that window (None: nothing changed).
        """
        wanted = []
        for points, closed in polylines:
            if len(points) == 0:
                continue
            poly = _fixed_point(points, self.grid.resolution, self.grid.origin)
            key = (poly.tobytes(), bool(closed))
            wanted.append(_Polyline(key, poly, bool(closed), _bounds(poly, self.shape)))
        old_keys = sorted(p.key for p in self._polylines)
        new_keys = sorted(p.key for p in wanted)
        if old_keys == new_keys:
            return None
        remaining = list(new_keys)
        window = Window(0, 0, 0, 0)
        for p in self._polylines:  # removed ones
            if p.key in remaining:
                remaining.remove(p.key)
            else:
                window = window.union(p.bounds)
        kept = list(old_keys)
        for p in wanted:  # added ones
            if p.key in kept:
                kept.remove(p.key)
            else:
                window = window.union(p.bounds)
        self._polylines = wanted
        if window.empty():  # every change lies outside the map
            return None
        # redraw whole polylines only (no clipping at the window edge, which could move pixels)
        while True:
            grown = window
            for p in wanted:
                if p.bounds.overlaps(window):
                    grown = grown.union(p.bounds)
            if (grown.r0, grown.r1, grown.c0, grown.c1) == (window.r0, window.r1, window.c0, window.c1):
                break
            window = grown
        mask = np.zeros((window.r1 - window.r0, window.c1 - window.c0), dtype=np.uint8)
        for p in wanted:
            if p.bounds.overlaps(window):
                _draw(mask, p.poly, p.closed, window.r0, window.c0)
        self.virtual[window.slices()] = mask.astype(bool)
        return self._virtual_changed(window)

    def set_virtual_cells(self, mask):
        """Replace the virtual layer with one already rasterised (a boolean array of the map's
        shape, e.g. move_base's virtual_obstacle_map) and re-inflate only the window that changed.
        Returns that window (None: nothing changed). Feed a costmap either cells or polylines."""
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != self.shape:
            raise ValueError("virtual layer of shape %s for a map of shape %s" % (mask.shape, self.shape))
        changed = mask != self.virtual
        if not changed.any():
            return None
        rows, cols = np.flatnonzero(changed.any(axis=1)), np.flatnonzero(changed.any(axis=0))
        window = Window(rows[0], rows[-1] + 1, cols[0], cols[-1] + 1)
        self._polylines = []
        self.virtual[window.slices()] = mask[window.slices()]
        return self._virtual_changed(window)

    def _virtual_changed(self, window):
        """The virtual cells of ``window`` changed: re-inflate and relabel around it."""
        touched = window.grown(self._reach, self.shape)
        self._inflate(touched)
        self._label(touched)
        self.version += 1
        self._changes.append((self.version, touched))
        del self._changes[:-64]
        return touched

    def rebuild(self):
        """Re-inflate the whole map."""
        self.cost = np.ones(self.shape, dtype=np.float32)
        everything = Window(0, self.shape[0], 0, self.shape[1])
        self._inflate(everything)
        self._label(everything)
        self.version += 1
        self._changes.append((self.version, None))
        del self._changes[:-64]

    def changes_since(self, version):
        """Windows changed after ``version``; None when the whole map must be taken as changed."""
        if version == self.version:
            return []
        if not self._changes or self._changes[0][0] > version + 1:
            return None
        windows = [w for v, w in self._changes if v > version]
        return None if any(w is None for w in windows) else windows

    def _inflate(self, window):
        """Recompute the cost of ``window`` from the obstacles within reach of it."""
        source = window.grown(self._reach, self.shape)
        rows, cols = source.slices()
        obstacles = self._static[rows, cols] | self.virtual[rows, cols]
        res = self.grid.resolution
        if obstacles.any():
            # exact Euclidean distance (m) from each cell centre to the nearest obstacle cell centre
            dist = cv2.distanceTransform((~obstacles).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE) * res
        else:
            dist = np.full(obstacles.shape, np.float32(1e9))
        dist = dist[window.r0 - source.r0:window.r1 - source.r0, window.c0 - source.c0:window.c1 - source.c0]
        lethal = dist < max(self.robot_radius, res * 0.5)
        cost = np.ones(dist.shape, dtype=np.float32)
        if self.safety_margin > 0:
            band = (dist - self.robot_radius) / self.safety_margin
            near = ~lethal & (band < 1.0)
            cost[near] += self.margin_cost * (1.0 - band[near])
        cost[lethal] = LETHAL
        self.cost[window.slices()] = cost

    def _label(self, window):
        """Relabel the labelling blocks ``window`` touches, then rejoin components across seams."""
        b = LABEL_BLOCK
        height, width = self.shape
        nbr, nbc = self._block_count.shape
        br0, br1, bc0, bc1 = window.r0 // b, -(-window.r1 // b), window.c0 // b, -(-window.c1 // b)
        for br in range(br0, br1):
            for bc in range(bc0, bc1):
                rows, cols = slice(br * b, min((br + 1) * b, height)), slice(bc * b, min((bc + 1) * b, width))
                count, local = cv2.connectedComponents(np.isfinite(self.cost[rows, cols]).view(np.uint8),
                                                       connectivity=8)
                self._local[rows, cols] = local
                self._block_count[br, bc] = count - 1
        # a block's seams reach the blocks right of and below it (corners included)
        for br in range(max(br0 - 1, 0), br1):
            for bc in range(max(bc0 - 1, 0), min(bc1 + 1, nbc)):
                self._seams[br * nbc + bc] = self._seam_links(br, bc)
        self._base[1:] = np.cumsum(self._block_count.ravel())
        n = int(self._base[-1])
        links = np.concatenate(list(self._seams.values()) + [np.zeros((0, 4), dtype=np.int64)])
        sources = self._base[links[:, 0]] + links[:, 1] - 1
        targets = self._base[links[:, 2]] + links[:, 3] - 1
        graph = csr_matrix((np.ones(len(links), dtype=np.int8), (sources, targets)), shape=(n, n))
        _count, self._component = connected_components(graph, directed=False)

    def _seam_links(self, br, bc):
        """Distinct (block, local, block, local) pairs of free cells 8-adjacent across the right and
        bottom seams of labelling block (br, bc)."""
        b = LABEL_BLOCK
        height, width = self.shape
        nbc = self._block_count.shape[1]
        r0, r1, c0, c1 = br * b, min((br + 1) * b, height), bc * b, min((bc + 1) * b, width)
        pairs = []
        for d in (-1, 0, 1):
            if c1 < width:
                r = np.arange(max(r0, -d), min(r1, height - d))
                pairs.append((r, np.full(len(r), c1 - 1), r + d, np.full(len(r), c1)))
            if r1 < height:
                c = np.arange(max(c0, -d), min(c1, width - d))
                pairs.append((np.full(len(c), r1 - 1), c, np.full(len(c), r1), c + d))
        if not pairs:
            return np.zeros((0, 4), dtype=np.int64)
        ra, ca, rb, cb = (np.concatenate(p) for p in zip(*pairs))
        la, lb = self._local[ra, ca], self._local[rb, cb]
        ok = (la > 0) & (lb > 0)
        links = np.stack([np.full(int(ok.sum()), br * nbc + bc), la[ok], (rb[ok] // b) * nbc + cb[ok] // b, lb[ok]],
                         axis=1).astype(np.int64)
        return np.unique(links, axis=0) if len(links) else links

    def _node(self, rows, cols):
        """Block-local component number across the whole map of cells (rows, cols); -1: not free."""
        local = self._local[rows, cols]
        block = (rows // LABEL_BLOCK) * self._block_count.shape[1] + cols // LABEL_BLOCK
        return np.where(local > 0, self._base[block] + local - 1, -1)

    def component(self, row, col):
        """Free-space component id of cell (row, col), -1 when it is not free (ids are arbitrary)."""
        node = int(self._node(row, col))
        return int(self._component[node]) if node >= 0 else -1

    def component_image(self):
        """Component id of every cell (-1: not free); a whole-map array, for tests and tools."""
        rows, cols = np.indices(self.shape)
        node = self._node(rows, cols)
        return np.where(node >= 0, self._component[np.maximum(node, 0)], -1)

    def clearance(self, x, y):
        """Distance (m) from the robot's edge at map point (x, y) to the nearest obstacle, read back
        from the cost band: exact within ``safety_margin``, inf beyond it, 0 in lethal or off-map cells."""
        row, col = self.grid.world_to_cell(x, y)
        if not self.grid.contains(row, col):
            return 0.0
        cost = float(self.cost[row, col])
        if not math.isfinite(cost):
            return 0.0
        if cost <= 1.0 or self.margin_cost <= 0:
            return float("inf")
        return max(1.0 - (cost - 1.0) / self.margin_cost, 0.0) * self.safety_margin

    def free(self, row, col):
        return self.grid.contains(row, col) and np.isfinite(self.cost[row, col])

    def connected(self, a, b):
        """True when cells a and b (row, col) are both free and in the same component."""
        if not (self.free(*a) and self.free(*b)):
            return False
        return self.component(*a) == self.component(*b)
