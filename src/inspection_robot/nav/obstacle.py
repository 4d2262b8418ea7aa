"""3-D obstacle detection in the robot's travel corridor (obstacle_detector).

Points arrive in the sensor frame; a fixed mounting transform (x, y, z, yaw) brings them into
the robot frame (x forward, y left, z up from the ground). Points below ``ground_height`` (ground
and its noise) or above ``max_height`` (overhanging wires, roofs) are ignored. The corridor is a
box ahead of the robot when it drives forward, behind it when it drives backward, and the disc
of the footprint when it spins in place. An obstacle needs ``min_points`` points in the corridor;
``clear_count`` consecutive clear clouds release it, so a flickering return does not chatter.
"""
import math

import numpy as np

FORWARD, BACKWARD, SPIN = 1, -1, 0


def xyz_from_cloud(data, point_step, offsets, count):
    """(N, 3) float32 array from a PointCloud2 byte buffer with float32 x, y, z at ``offsets``."""
    if count == 0:
        return np.zeros((0, 3), dtype=np.float32)
    raw = np.frombuffer(data, dtype=np.uint8, count=count * point_step).reshape(count, point_step)
    cols = [raw[:, o:o + 4].copy().view("<f4").ravel() for o in offsets]
    return np.stack(cols, axis=1)


def cloud_bytes(points):
    """Pack (N, 3) points as PointCloud2 data with fields x, y, z float32 (point_step 12)."""
    return np.ascontiguousarray(points, dtype="<f4").tobytes()


class CorridorDetector(object):
    def __init__(self, half_width_m, front_offset_m, rear_offset_m, distance_m, ground_height_m,
                 max_height_m, spin_radius_m, min_points=5, clear_count=3, sensor_pose=(0.0, 0.0, 0.0, 0.0)):
        self.half_width = float(half_width_m)
        self.front_offset = float(front_offset_m)
        self.rear_offset = float(rear_offset_m)
        self.distance = float(distance_m)
        self.ground_height = float(ground_height_m)
        self.max_height = float(max_height_m)
        self.spin_radius = float(spin_radius_m)
        self.min_points = int(min_points)
        self.clear_count = int(clear_count)
        sx, sy, sz, syaw = [float(v) for v in sensor_pose]
        c, s = math.cos(syaw), math.sin(syaw)
        self._rotation = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]], dtype=np.float32)
        self._translation = np.array([sx, sy, sz], dtype=np.float32)
        self.obstacle = False
        self._clear_run = 0

    def count_in_corridor(self, points, direction):
        """Number of points (sensor frame, (N, 3)) inside the corridor for ``direction``."""
        pts = np.asarray(points, dtype=np.float32)
        if len(pts) == 0:
            return 0
        pts = pts @ self._rotation.T + self._translation
        x, y, z = pts[:, 0], pts[:, 1], pts[:, 2]
        valid = np.isfinite(z) & (z > self.ground_height) & (z < self.max_height)
        if direction == FORWARD:
            inside = (x > self.front_offset) & (x < self.front_offset + self.distance) & (np.abs(y) < self.half_width)
        elif direction == BACKWARD:
            inside = (x < -self.rear_offset) & (x > -self.rear_offset - self.distance) & (np.abs(y) < self.half_width)
        else:
            inside = x * x + y * y < self.spin_radius * self.spin_radius
        return int(np.count_nonzero(valid & inside))

    def update(self, points, direction):
        """Feed one cloud; returns the (debounced) obstacle state."""
        hit = self.count_in_corridor(points, direction) >= self.min_points
        if hit:
            self.obstacle = True
            self._clear_run = 0
        elif self.obstacle:
            self._clear_run += 1
            if self._clear_run >= self.clear_count:
                self.obstacle = False
        return self.obstacle


def direction_from_command(velocity_x, velocity_yaw, wheel_control, previous):
    """Travel direction from a move command; a zero command keeps the previous direction."""
    if wheel_control == 1 and velocity_yaw != 0.0:
        return SPIN
    if velocity_x > 0:
        return FORWARD
    if velocity_x < 0:
        return BACKWARD
    return previous
