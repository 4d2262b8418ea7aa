"""Departure curves: a planned path reshaped so that the robot drives off without spinning in place.

The planner's path starts at the robot whatever its heading, so the follower used to spin in place
whenever the path left more than ``spin_exit`` off the robot's heading (at a patrol stop the robot
faces the equipment, and the next path usually leaves sideways). On this chassis a spin is dear: it
needs steer mode, and every straight <-> steer switch brings the robot to rest and turns the wheels
for ``switch_time`` (1 s), so one departure spin cost two switches besides the turn itself
(bench/patrol_drive.py: about half of the time the simulated yard's patrol drives lost against
their planned length at full speed).

``shape_path`` replaces the path's first metres by the curve the robot drives in straight mode from
its heading onto the path: pure pursuit (lookahead ``lookahead_min_m``) with curvature at most
1 / ``min_turn_radius_m``, driven on paper from the robot's pose. The curve is kept only when it
joins the path within ``curve_max_m``, the path leaves at most ``curve_max_rad`` off the robot's
heading, and all of the curve is clear of obstacles (``clearance(x, y) > 0``: outside the inflated
footprint, as the planner's own path) and so is the line ``curve_sight_m`` ahead of every point of
it. That line, inflated by the robot's radius as the costmap is, covers obstacle_detector's corridor
(front_offset + distance = 1.65 m ahead, as wide as the footprint; the default 2.0 m adds the 0.35 m
the robot drove wide of the paper curve in patrol_sim). The detector stops the robot at anything in
that corridor, and a U-turn that swings the robot's front at equipment stopped it there: a charge
cycle begun mid-turn beside cabinet_1 ended "blocked" on every retry. Otherwise the robot spins in
place first as before (a spin checks the footprint's 0.8 m disc instead). Pure
module. (The goal's yaw is still reached by a spin at the end: a curve into the goal along its yaw
does not settle within the 2° yaw tolerance over a short straight run; patrol stops avoid that
spin differently, task.patrol.turns_to_yaw.)
"""
import math

import numpy as np

from inspection_robot.angles import wrap_angle

STEP_M = 0.05       # m between the points of a curve
JOIN_M = 0.02       # m, a curve has joined the path this close to it ...
JOIN_RAD = 0.05     # ... and this parallel to it


class _Polyline(object):
    def __init__(self, points):
        self.points = np.asarray(points, dtype=float)
        seg = np.diff(self.points, axis=0)
        self.seg_len = np.hypot(seg[:, 0], seg[:, 1])
        self.cum = np.concatenate([[0.0], np.cumsum(self.seg_len)])
        self.heading = np.arctan2(seg[:, 1], seg[:, 0])
        self.length = float(self.cum[-1])

    def project(self, x, y, s_min):
        """(arc length, distance, segment heading) of the closest point at or after ``s_min``."""
        lo = max(int(np.searchsorted(self.cum, s_min, side="right")) - 1, 0)
        a, d = self.points[lo:-1], np.diff(self.points[lo:], axis=0)
        t = np.clip(((x - a[:, 0]) * d[:, 0] + (y - a[:, 1]) * d[:, 1]) / np.maximum((d * d).sum(axis=1), 1e-12),
                    0.0, 1.0)
        dist = np.hypot(a[:, 0] + t * d[:, 0] - x, a[:, 1] + t * d[:, 1] - y)
        i = int(np.argmin(dist))
        return float(self.cum[lo + i] + t[i] * self.seg_len[lo + i]), float(dist[i]), float(self.heading[lo + i])

    def point_at(self, s):
        s = min(max(s, 0.0), self.length)
        i = max(min(int(np.searchsorted(self.cum, s, side="right")) - 1, len(self.seg_len) - 1), 0)
        t = (s - self.cum[i]) / self.seg_len[i] if self.seg_len[i] > 0 else 0.0
        return self.points[i] + t * (self.points[i + 1] - self.points[i])

    def after(self, s):
        """The polyline from arc length ``s`` on."""
        i = int(np.searchsorted(self.cum, s, side="right"))
        return np.vstack([self.point_at(s), self.points[i:]])


def join_curve(points, x, y, heading, radius, lookahead, max_length):
    """The curve from (x, y, heading) onto polyline ``points`` (pure pursuit, curvature <= 1 / radius):
    (curve (K, 2) from (x, y) to where it joins, arc length of the join on the path), or None when it
    has not joined after ``max_length`` metres or the path ends first."""
    path = _Polyline(points)
    if path.length < 1e-6:
        return None
    curve, s = [(x, y)], 0.0
    kappa_max = 1.0 / radius if radius > 0 else float("inf")
    for _ in range(int(max_length / STEP_M)):
        s, dist, direction = path.project(x, y, s)
        if dist <= JOIN_M and abs(wrap_angle(direction - heading)) <= JOIN_RAD:
            return np.array(curve), s
        if s + lookahead >= path.length:
            return None
        tx, ty = path.point_at(s + lookahead)
        alpha = wrap_angle(math.atan2(ty - y, tx - x) - heading)
        kappa = 2.0 * math.sin(alpha) / lookahead if abs(alpha) < math.pi / 2 else math.copysign(kappa_max, alpha)
        kappa = max(-kappa_max, min(kappa_max, kappa))
        heading += kappa * STEP_M / 2.0     # midpoint rule
        x, y = x + STEP_M * math.cos(heading), y + STEP_M * math.sin(heading)
        heading += kappa * STEP_M / 2.0
        curve.append((x, y))
    return None


SIGHT_STEP_M = 0.1  # m between the points checked ahead of the robot along a curve


def _clear(curve, yaw, clearance, sight):
    """Every point of ``curve`` (robot heading ``yaw`` at its start) and the line ``sight`` m ahead of
    it are clear."""
    if clearance is None:
        return True
    ahead = np.arange(0.0, sight + 1e-9, SIGHT_STEP_M) if sight > 0 else np.zeros(1)
    steps = np.diff(curve, axis=0)
    headings = np.concatenate([[yaw], np.arctan2(steps[:, 1], steps[:, 0])])
    for (px, py), heading in zip(curve, headings):
        c, s = math.cos(heading), math.sin(heading)
        if not all(clearance(float(px + d * c), float(py + d * s)) > 0.0 for d in ahead):
            return False
    return True


def _initial_turn(points, heading):
    seg = np.diff(points, axis=0)
    seg = seg[np.hypot(seg[:, 0], seg[:, 1]) > 1e-9]
    if not len(seg):
        return 0.0
    return abs(wrap_angle(math.atan2(seg[0][1], seg[0][0]) - heading))


def departure(points, pose, params, clearance=None):
    """``points`` starting with the curve the robot drives from ``pose`` (x, y, yaw) onto the path, or
    None when it would turn more than ``curve_max_rad`` or there is no clear such curve."""
    x, y, yaw = pose
    if _initial_turn(points, yaw) > params.curve_max_rad:
        return None
    joined = join_curve(points, x, y, yaw, params.min_turn_radius, params.lookahead_min, params.curve_max_m)
    if joined is None:
        return None
    curve, s = joined
    if not _clear(curve, yaw, clearance, params.curve_sight):
        return None
    return np.vstack([curve, _Polyline(points).after(s)[1:]])


def curved_path(points, pose, goal, params, clearance=None):
    """The planned ``points`` starting with a departure curve from ``pose`` (module docstring), or
    None when there is none: no clear one, curves off (``curve_max_m`` 0), or a backward goal (the
    robot reverses out without turning)."""
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    if goal.backward or params.curve_max_m <= 0 or len(points) < 2:
        return None
    return departure(points, pose, params, clearance)


def shape_path(points, pose, goal, params, clearance=None):
    """The planned ``points`` with a departure curve from ``pose`` where there is one (curved_path)."""
    shaped = curved_path(points, pose, goal, params, clearance)
    return np.asarray(points, dtype=float).reshape(-1, 2) if shaped is None else shaped
