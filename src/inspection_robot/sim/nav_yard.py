"""The simulated yard (config/sim_world.yaml) as seen by navigation: occupancy map and 3-D points.

Equipment are boxes (footprint [length along its x, width along its y], height, yaw); the yard
is fenced by a wall ``fence_margin`` thick around [0, size_x] x [0, size_y]. ``occupancy_map``
rasterises them into a map_server-style GridMap (scripts/make_sample_map.py writes the shipped
map); ``ObstacleCloud`` produces the point cloud a 3-D sensor on the robot would return, with
ground points, plus boxes a test can drop into the yard.
"""
import math

import numpy as np

from inspection_robot.nav.gridmap import OCC_FREE, OCC_OCCUPIED, GridMap


class Box(object):
    def __init__(self, ident, x, y, yaw, length, width, height):
        self.id = ident
        self.x, self.y, self.yaw = float(x), float(y), float(yaw)
        self.length, self.width, self.height = float(length), float(width), float(height)

    def contains(self, px, py):
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        dx, dy = px - self.x, py - self.y
        u, v = c * dx + s * dy, -s * dx + c * dy
        return (np.abs(u) <= self.length / 2.0) & (np.abs(v) <= self.width / 2.0)

    def surface_points(self, spacing):
        """Points on the four sides of the box (map frame, z up), ``spacing`` apart."""
        half_l, half_w = self.length / 2.0, self.width / 2.0
        perimeter = []
        for (x0, y0), (x1, y1) in (((-half_l, -half_w), (half_l, -half_w)), ((half_l, -half_w), (half_l, half_w)),
                                   ((half_l, half_w), (-half_l, half_w)), ((-half_l, half_w), (-half_l, -half_w))):
            n = max(int(math.ceil(math.hypot(x1 - x0, y1 - y0) / spacing)), 1)
            t = np.arange(n) / float(n)
            perimeter.append(np.stack([x0 + (x1 - x0) * t, y0 + (y1 - y0) * t], axis=1))
        ring = np.concatenate(perimeter)
        zs = np.arange(spacing / 2.0, self.height, spacing)
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        wx = self.x + c * ring[:, 0] - s * ring[:, 1]
        wy = self.y + s * ring[:, 0] + c * ring[:, 1]
        return np.stack([np.repeat(wx[None, :], len(zs), 0).ravel(), np.repeat(wy[None, :], len(zs), 0).ravel(),
                         np.repeat(zs[:, None], len(wx), 1).ravel()], axis=1)


def equipment_boxes(world):
    boxes = []
    for item in world.get("equipment", []):
        pos = item["position"]
        boxes.append(Box(item["id"], pos[0], pos[1], item.get("yaw", 0.0), item["footprint"][0],
                         item["footprint"][1], item.get("height", 2.0)))
    return boxes


def occupancy_map(world, resolution):
    """GridMap of the fenced yard: the fence ring and every equipment footprint occupied."""
    size_x, size_y = [float(v) for v in world["size"]]
    margin = float(world.get("fence_margin", 1.0))
    origin = (-margin, -margin, 0.0)
    width = int(round((size_x + 2 * margin) / resolution))
    height = int(round((size_y + 2 * margin) / resolution))
    cols, rows = np.meshgrid(np.arange(width), np.arange(height))
    xs = origin[0] + (cols + 0.5) * resolution
    ys = origin[1] + (rows + 0.5) * resolution
    occupied = (xs < 0) | (ys < 0) | (xs > size_x) | (ys > size_y)
    for box in equipment_boxes(world):
        occupied |= box.contains(xs, ys)
    occupancy = np.where(occupied, OCC_OCCUPIED, OCC_FREE).astype(np.int8)
    return GridMap(occupancy, resolution, origin)


class ObstacleCloud(object):
    """Points a robot-mounted 3-D sensor sees: equipment, dropped boxes, a patch of ground."""

    def __init__(self, world, sensor_range_m=8.0, spacing_m=0.1, ground_spacing_m=0.25):
        self.range = float(sensor_range_m)
        self.spacing = float(spacing_m)
        self._static = [(b, b.surface_points(self.spacing)) for b in equipment_boxes(world)]
        self._dropped = {}
        g = np.arange(-self.range, self.range, float(ground_spacing_m))
        gx, gy = np.meshgrid(g, g)
        keep = gx * gx + gy * gy < self.range * self.range
        self._ground = np.stack([gx[keep], gy[keep], np.zeros(np.count_nonzero(keep))], axis=1)

    def drop(self, ident, x, y, size, height):
        box = Box(ident, x, y, 0.0, size, size, height)
        self._dropped[ident] = (box, box.surface_points(self.spacing))

    def remove(self, ident):
        return self._dropped.pop(ident, None) is not None

    def clear(self):
        self._dropped.clear()

    @property
    def dropped(self):
        return sorted(self._dropped)

    def points_in_robot_frame(self, x, y, yaw):
        """(N, 3) float32 points within range, in the robot frame (x forward, y left, z up)."""
        clouds = [self._ground]
        c, s = math.cos(yaw), math.sin(yaw)
        for box, pts in list(self._static) + list(self._dropped.values()):
            reach = self.range + math.hypot(box.length, box.width)
            if math.hypot(box.x - x, box.y - y) > reach:
                continue
            dx, dy = pts[:, 0] - x, pts[:, 1] - y
            local = np.stack([c * dx + s * dy, -s * dx + c * dy, pts[:, 2]], axis=1)
            clouds.append(local[local[:, 0] ** 2 + local[:, 1] ** 2 < self.range * self.range])
        return np.concatenate(clouds).astype(np.float32)
