"""Planning costmap: static map + rasterised virtual obstacles, inflated by the robot's footprint.

Virtual obstacles are drawn into a layer of their own that only the planner sees; the static
map published for localization is never modified. Inflation uses one exact Euclidean distance
transform (OpenCV) per change: cells closer than ``robot_radius`` to an obstacle are lethal, cells
within ``robot_radius + safety_margin`` carry a cost that decays linearly, so paths keep clear of
walls when they can. Free space is labelled into 8-connected components once per change, so
"goal unreachable" is answered exactly without searching.
"""
import cv2
import numpy as np

from inspection_robot.nav.gridmap import OCC_UNKNOWN

LETHAL = np.float32(np.inf)


def rasterise_polylines(shape, polylines, resolution, origin):
    """Draw polylines ``[(points, closed), ...]`` (map metres) into a boolean mask of ``shape``.

    Lines are 8-connected and one cell wide, drawn with sub-cell precision, so a wall has no
    diagonal gap a 4-neighbour step could slip through once inflated by at least one cell.
    """
    mask = np.zeros(shape, dtype=np.uint8)
    shift = 4  # sub-pixel bits of cv2.polylines
    scale = float(1 << shift) / resolution
    for points, closed in polylines:
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        if len(pts) == 0:
            continue
        # cell (row, col) has its centre at origin + (col + 0.5, row + 0.5) * resolution
        cols = (pts[:, 0] - origin[0]) * scale - (1 << (shift - 1))
        rows = (pts[:, 1] - origin[1]) * scale - (1 << (shift - 1))
        poly = np.round(np.stack([cols, rows], axis=1)).astype(np.int32).reshape(-1, 1, 2)
        if len(pts) == 1:
            poly = np.concatenate([poly, poly])
        cv2.polylines(mask, [poly], bool(closed), 1, thickness=1, lineType=cv2.LINE_8, shift=shift)
    return mask.astype(bool)


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
        self.cost = None
        self.labels = None
        self.rebuild()

    @property
    def resolution(self):
        return self.grid.resolution

    @property
    def shape(self):
        return self._static.shape

    def set_virtual(self, polylines):
        """Replace the virtual obstacle layer with ``[(points, closed), ...]`` and re-inflate."""
        self.virtual = rasterise_polylines(self.shape, polylines, self.grid.resolution, self.grid.origin)
        self.rebuild()

    def rebuild(self):
        obstacles = self._static | self.virtual
        res = self.grid.resolution
        if obstacles.any():
            # exact Euclidean distance (m) from each cell centre to the nearest obstacle cell centre
            dist = cv2.distanceTransform((~obstacles).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE) * res
        else:
            dist = np.full(self.shape, np.float32(1e9))
        lethal = dist < max(self.robot_radius, res * 0.5)
        cost = np.ones(self.shape, dtype=np.float32)
        if self.safety_margin > 0:
            band = (dist - self.robot_radius) / self.safety_margin
            near = ~lethal & (band < 1.0)
            cost[near] += self.margin_cost * (1.0 - band[near])
        cost[lethal] = LETHAL
        self.cost = cost
        _count, self.labels = cv2.connectedComponents((~lethal).astype(np.uint8), connectivity=8)

    def free(self, row, col):
        return self.grid.contains(row, col) and np.isfinite(self.cost[row, col])

    def connected(self, a, b):
        """True when cells a and b (row, col) are both free and in the same component."""
        if not (self.free(*a) and self.free(*b)):
            return False
        return self.labels[a] == self.labels[b]
