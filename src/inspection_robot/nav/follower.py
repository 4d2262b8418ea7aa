"""Path follower: regulated pure pursuit along the planned polyline, spins in place only when needed.

Each ``step(pose)`` returns a Command (m/s, rad/s, wheel mode) for robot_control and the progress
(remaining distance, lateral error). Phases:

- ``align``: heading far from the path direction (more than ``spin_enter`` while driving; at the
  start, more than a ``min_turn_radius`` curve can take) -> spin in place (steer mode,
  wheel_control 1); move_base shapes the path's start into a curve the robot can drive instead
  where there is room (nav/curves.py);
- ``track``: regulated pure pursuit in straight mode (wheel_control 0, velocity_yaw steers): the
  lookahead grows with speed (``lookahead_time`` x speed, between ``lookahead_min`` and
  ``lookahead``), the curvature is capped at 1 / ``min_turn_radius`` (the chassis' straight-mode
  limit), and the speed is regulated so that every corner within braking distance is taken with
  at most ``corner_accel`` lateral acceleration (braking for it at ``corner_decel``); slowing
  down near the goal (at ``decel``, below the chassis' limit so a late 20 Hz tick cannot
  overshoot); near obstacles (proximity regulation): when the robot's edge, at its position or at
  the lookahead point, is closer than ``proximity_m`` to an obstacle (``clearance(x, y)``, read
  from the costmap), the speed is scaled by clearance / ``proximity_m``, down to
  ``proximity_min_scale``; backward goals drive with negative speed and pursue with the robot's rear;
- ``spin``: with_direction goals turn in place to the goal heading at the end;
- ``done``: zero command.

Tolerances come from FollowerParams; precision goals use the tight pair. The follower's ``done`` is
judged on the last pose received, which under CPU starvation lags a robot still rolling at its
approach speed; ``Approach`` wraps the follower so that a goal ends on a pose at rest (phase
``settle`` meanwhile, zero command) and drives the last centimetres again when that pose is out of
tolerance.
"""
import math
from collections import namedtuple

import numpy as np

from inspection_robot.interface import WHEEL_STEER, WHEEL_STRAIGHT
from inspection_robot.angles import wrap_angle

Command = namedtuple("Command", "velocity_x velocity_yaw wheel_control")
Progress = namedtuple("Progress", "phase remaining lateral_error command")

ALIGN, TRACK, SPIN, SETTLE, DONE = "align", "track", "spin", "settle", "done"
# what set the last tracking speed (PathFollower.limit): diagnostics and bench/patrol_drive.py
LIMIT_CRUISE, LIMIT_PROXIMITY, LIMIT_GOAL, LIMIT_CORNER = "cruise", "proximity", "goal_decel", "corner"


class FollowerParams(object):
    def __init__(self, lookahead_m=1.0, xy_tolerance_m=0.05, xy_tolerance_precise_m=0.01,
                 yaw_tolerance_rad=0.035, yaw_tolerance_precise_rad=0.015, spin_enter_rad=1.57,
                 spin_exit_rad=0.15, decel_m_s2=0.5, approach_gain=1.5, min_speed_m_s=0.05,
                 min_speed_precise_m_s=0.02, min_yaw_rate_rad_s=0.05, yaw_gain=3.0, yaw_decel_rad_s2=1.3,
                 lookahead_min_m=0.4, lookahead_time_s=1.2, min_turn_radius_m=0.65, corner_accel_m_s2=1.0,
                 corner_decel_m_s2=0.7, proximity_m=0.2, proximity_min_scale=0.4, rest_m=0.005,
                 rest_rad=0.005, rest_s=0.25, rest_timeout_s=1.0, rest_timeout_precise_s=2.0, max_corrections=2,
                 curve_max_m=6.0, curve_max_rad=math.pi, curve_sight_m=2.0):
        self.lookahead = float(lookahead_m)
        self.lookahead_min = min(float(lookahead_min_m), self.lookahead)
        self.lookahead_time = float(lookahead_time_s)
        self.min_turn_radius = float(min_turn_radius_m)
        self.corner_accel = float(corner_accel_m_s2)
        self.corner_decel = float(corner_decel_m_s2)
        self.proximity = float(proximity_m)
        self.proximity_min_scale = float(proximity_min_scale)
        self.xy_tolerance = float(xy_tolerance_m)
        self.xy_tolerance_precise = float(xy_tolerance_precise_m)
        self.yaw_tolerance = float(yaw_tolerance_rad)
        self.yaw_tolerance_precise = float(yaw_tolerance_precise_rad)
        self.spin_enter = float(spin_enter_rad)
        self.spin_exit = float(spin_exit_rad)
        self.decel = float(decel_m_s2)
        self.approach_gain = float(approach_gain)
        self.yaw_decel = float(yaw_decel_rad_s2)
        self.min_speed = float(min_speed_m_s)
        self.min_speed_precise = float(min_speed_precise_m_s)
        self.min_yaw_rate = float(min_yaw_rate_rad_s)
        self.yaw_gain = float(yaw_gain)
        self.rest_m = float(rest_m)
        self.rest_rad = float(rest_rad)
        self.rest_s = float(rest_s)
        self.rest_timeout = float(rest_timeout_s)
        self.rest_timeout_precise = float(rest_timeout_precise_s)
        self.max_corrections = int(max_corrections)
        self.curve_max_m = float(curve_max_m)   # nav.curves: departure curves
        self.curve_max_rad = float(curve_max_rad)
        self.curve_sight = float(curve_sight_m)


STOP = Command(0.0, 0.0, WHEEL_STRAIGHT)


class PathFollower(object):
    def __init__(self, points, goal, params, clearance=None):
        """``points``: (N, 2) path in map metres (N >= 1); ``goal``: a goal.MoveGoal; ``clearance``:
        (x, y) -> metres from the robot's edge to the nearest obstacle (None: no proximity regulation)."""
        self.clearance = clearance
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        if len(pts) == 1:
            pts = np.vstack([pts, pts])
        self.points = pts
        seg = np.diff(pts, axis=0)
        self._seg_len = np.hypot(seg[:, 0], seg[:, 1])
        self._cum = np.concatenate([[0.0], np.cumsum(self._seg_len)])
        self.goal = goal
        self.p = params
        self.tolerance = params.xy_tolerance_precise if goal.precision else params.xy_tolerance
        self.yaw_tolerance = params.yaw_tolerance_precise if goal.precision else params.yaw_tolerance
        self.min_speed = params.min_speed_precise if goal.precision else params.min_speed
        self.direction = -1.0 if goal.backward else 1.0
        self.phase = ALIGN
        self._progress_s = 0.0
        self._speed = 0.0  # last commanded speed (m/s), sets the lookahead
        self.limit = LIMIT_CRUISE  # what set that speed
        self.length = float(self._cum[-1])
        # corner speeds: turning angle at each inner vertex -> the speed to take it with
        heading = np.arctan2(seg[:, 1], seg[:, 0])
        turn = np.abs(np.angle(np.exp(1j * np.diff(heading)))) if len(seg) > 1 else np.zeros(0)
        turn[self._seg_len[1:] < 1e-9] = 0.0
        turn[self._seg_len[:-1] < 1e-9] = 0.0
        radius = np.maximum(params.min_turn_radius,
                            params.lookahead_min / np.maximum(2.0 * np.sin(turn / 2.0), 1e-9))
        self._corner_s = self._cum[1:-1][turn > 0.05]
        self._corner_speed = np.sqrt(params.corner_accel * radius)[turn > 0.05]

    def project(self, x, y):
        """Arc length of the closest path point (searching ahead of the last one) and its distance."""
        lo = max(int(np.searchsorted(self._cum, self._progress_s - 1.0)) - 1, 0)
        a = self.points[lo:-1]
        d = self.points[lo + 1:] - a
        length2 = np.maximum((d * d).sum(axis=1), 1e-12)
        t = np.clip(((x - a[:, 0]) * d[:, 0] + (y - a[:, 1]) * d[:, 1]) / length2, 0.0, 1.0)
        px, py = a[:, 0] + t * d[:, 0], a[:, 1] + t * d[:, 1]
        dist = np.hypot(px - x, py - y)
        i = int(np.argmin(dist))
        s = float(self._cum[lo + i] + t[i] * self._seg_len[lo + i])
        return s, float(dist[i])

    def point_at(self, s):
        s = min(max(s, 0.0), self.length)
        i = min(int(np.searchsorted(self._cum, s, side="right")) - 1, len(self._seg_len) - 1)
        i = max(i, 0)
        t = (s - self._cum[i]) / self._seg_len[i] if self._seg_len[i] > 0 else 0.0
        return self.points[i] + t * (self.points[i + 1] - self.points[i])

    def step(self, x, y, yaw):
        s, lateral = self.project(x, y)
        self._progress_s = max(self._progress_s, s)
        goal_dist = math.hypot(self.goal.x - x, self.goal.y - y)
        remaining = max(self.length - self._progress_s, 0.0) if goal_dist > self.p.lookahead else goal_dist
        heading = wrap_angle(yaw + (math.pi if self.goal.backward else 0.0))

        if self.phase in (ALIGN, TRACK):
            if goal_dist <= self.tolerance:
                self.phase = SPIN if self.goal.with_direction else DONE
            else:
                lookahead = min(max(self.p.lookahead_time * abs(self._speed), self.p.lookahead_min), self.p.lookahead)
                target = self.goal_point() if goal_dist <= lookahead else \
                    self.point_at(self._progress_s + lookahead)
                alpha = wrap_angle(math.atan2(target[1] - y, target[0] - x) - heading)
                far = goal_dist > 2.0 * lookahead
                if self.phase == TRACK and far and abs(alpha) > self.p.spin_enter:
                    self.phase = ALIGN
                if self.phase == ALIGN:
                    if abs(alpha) > self._align_exit(lookahead) and goal_dist > self.tolerance * 4:
                        self._speed = 0.0
                        return Progress(ALIGN, remaining, lateral, self._spin(alpha))
                    self.phase = TRACK
                command = self._pursue(alpha, goal_dist, remaining, lookahead, self._proximity_scale(x, y, target))
                self._speed = command.velocity_x
                return Progress(TRACK, remaining, lateral, command)
        if self.phase == SPIN:
            error = wrap_angle(self.goal.yaw - yaw)
            if abs(error) <= self.yaw_tolerance:
                self.phase = DONE
            else:
                return Progress(SPIN, remaining, lateral, self._spin(error))
        return Progress(DONE, remaining, lateral, STOP)

    def _align_exit(self, lookahead):
        """Heading error small enough to drive off without spinning: ``spin_exit``, or the angle to a
        lookahead point on a circle of ``min_turn_radius`` (a curve the robot can drive in straight
        mode, such as a departure curve, needs no spin)."""
        if self.p.min_turn_radius <= 0:
            return self.p.spin_exit
        return max(self.p.spin_exit, math.asin(min(1.0, lookahead / (2.0 * self.p.min_turn_radius))) + 0.05)

    def goal_point(self):
        return np.array([self.goal.x, self.goal.y])

    def within_tolerance(self, x, y, yaw):
        """Whether a pose meets the goal: position, and heading for with_direction goals."""
        if math.hypot(self.goal.x - x, self.goal.y - y) > self.tolerance:
            return False
        return not self.goal.with_direction or abs(wrap_angle(self.goal.yaw - yaw)) <= self.yaw_tolerance

    def correction(self, x, y, yaw):
        """A follower for the last centimetres from a pose at rest beside the goal: the straight segment
        to it (the planned path already ended there), same tolerances, backing up (or, on a backward
        goal, going forward) when the goal lies behind rather than turning round for it."""
        heading = wrap_angle(yaw + (math.pi if self.goal.backward else 0.0))
        behind = abs(wrap_angle(math.atan2(self.goal.y - y, self.goal.x - x) - heading)) > math.pi / 2
        goal = self.goal._replace(backward=self.goal.backward != behind)
        return PathFollower([(x, y), (goal.x, goal.y)], goal, self.p, self.clearance)

    def _spin(self, error):
        size = abs(error)
        # braking profile: constant angular deceleration, then proportional
        rate = min(self.goal.velocity_yaw, math.sqrt(2.0 * self.p.yaw_decel * size), self.p.yaw_gain * size)
        rate = max(self.p.min_yaw_rate, rate)
        return Command(0.0, math.copysign(rate, error), WHEEL_STEER)

    def _corner_limit(self):
        """Highest speed from which every corner ahead can still be reached at its corner speed."""
        ahead = self._corner_s - self._progress_s
        near = (ahead > -self.p.lookahead_min) & (ahead < 10.0)
        if not near.any():
            return float("inf")
        distance = np.maximum(ahead[near], 0.0)
        return float(np.sqrt(self._corner_speed[near] ** 2 + 2.0 * self.p.corner_decel * distance).min())

    def _proximity_scale(self, x, y, target):
        """Speed factor near obstacles: clearance / proximity below ``proximity`` (1.0: far from any)."""
        if self.clearance is None or self.p.proximity <= 0:
            return 1.0
        near = min(self.clearance(x, y), self.clearance(float(target[0]), float(target[1])))
        return min(max(near / self.p.proximity, self.p.proximity_min_scale), 1.0)

    def _pursue(self, alpha, goal_dist, remaining, lookahead, scale=1.0):
        to_go = max(remaining, goal_dist)
        # braking profile: constant deceleration, then a proportional approach (no overshoot at 20 Hz)
        limits = ((self.goal.velocity_x, LIMIT_CRUISE), (self.goal.velocity_x * scale, LIMIT_PROXIMITY),
                  (math.sqrt(2.0 * self.p.decel * to_go), LIMIT_GOAL), (self.p.approach_gain * to_go, LIMIT_GOAL),
                  (self._corner_limit(), LIMIT_CORNER))
        speed, self.limit = min(limits, key=lambda pair: pair[0])
        speed = max(speed, self.min_speed)
        lookahead = max(min(lookahead, goal_dist), 1e-3)
        curvature = 2.0 * math.sin(alpha) / lookahead
        if self.p.min_turn_radius > 0 and abs(curvature) > 1.0 / self.p.min_turn_radius:
            curvature = math.copysign(1.0 / self.p.min_turn_radius, curvature)
        # lateral acceleration cap for the curvature actually commanded
        if abs(curvature) > 1e-9 and speed > math.sqrt(self.p.corner_accel / abs(curvature)):
            speed, self.limit = max(math.sqrt(self.p.corner_accel / abs(curvature)), self.min_speed), LIMIT_CORNER
        yaw_rate = speed * curvature
        if abs(yaw_rate) > self.goal.velocity_yaw:
            speed *= self.goal.velocity_yaw / abs(yaw_rate)
            yaw_rate = math.copysign(self.goal.velocity_yaw, yaw_rate)
            self.limit = LIMIT_CORNER
        if abs(alpha) > math.pi / 2:  # target behind (overshoot): back up towards it gently
            speed = -min(speed, self.min_speed)
            yaw_rate = 0.0
        return Command(self.direction * speed, yaw_rate, WHEEL_STRAIGHT)


def mean_pose(poses):
    """(x, y, yaw) mean of planar poses, the heading as a circular mean (poses either side of ±pi)."""
    n = float(len(poses))
    return (sum(p[0] for p in poses) / n, sum(p[1] for p in poses) / n,
            math.atan2(sum(math.sin(p[2]) for p in poses), sum(math.cos(p[2]) for p in poses)))


class Arrival(object):
    """The pose a finished goal is judged on: the robot at rest, seen on poses received after the stop.

    ``update(now, stamp, pose)`` each control cycle (``stamp``: when the pose arrived) returns None
    while the robot may still move, then the pose at rest: once a pose received at least ``rest_s``
    earlier (after the stop) lies within ``rest_m`` and ``rest_rad`` of the newest, the mean of the
    poses from that one to the newest; after ``rest_timeout`` (``rest_timeout_precise`` for a precise
    goal; a noisy localizer never looks still), the mean of the poses received from ``rest_s`` after
    the stop (the braking over). A mean, not the newest pose: a localizer's noise (2 cm σ for a good
    lidar one) is larger than the precise tolerance (1 cm), so one pose would call corrections that
    only move the robot by the noise; twenty poses of a 10 Hz localizer over 2 s shrink it to about a
    fifth. An ordinary goal (5 cm tolerance) needs no such wait: 1 s, every patrol stop pays it.
    """

    def __init__(self, params, stopped_at, precise=False):
        self.p = params
        self.stopped_at = float(stopped_at)
        self.timeout = params.rest_timeout_precise if precise else params.rest_timeout
        self._poses = []  # (stamp, pose) received after the stop, oldest first

    def update(self, now, stamp, pose):
        if pose is not None and stamp is not None and stamp > self.stopped_at and \
                (not self._poses or stamp > self._poses[-1][0]):
            self._poses.append((stamp, pose))
        if not self._poses:
            return None
        newest_stamp, newest = self._poses[-1]
        earlier = [(s, p) for s, p in self._poses if s <= newest_stamp - self.p.rest_s]
        if earlier:
            then_stamp, then = earlier[-1]
            if math.hypot(newest[0] - then[0], newest[1] - then[1]) <= self.p.rest_m and \
                    abs(wrap_angle(newest[2] - then[2])) <= self.p.rest_rad:
                return mean_pose([p for s, p in self._poses if s >= then_stamp])
        if now - self.stopped_at >= self.timeout:
            settled = [p for s, p in self._poses if s >= self.stopped_at + self.p.rest_s]
            return mean_pose(settled or [newest])
        return None


class Approach(object):
    """A goal's follower until the robot rests within tolerance.

    ``step(now, stamp, pose)`` (``stamp``: when that pose arrived, on ``now``'s clock) returns the
    follower's Progress; once the follower is done it returns phase ``settle`` with a zero command
    until ``Arrival`` sees the robot at rest, then ``done`` with the resting pose in ``rest`` when
    that pose is within tolerance, or after ``max_corrections`` straight-line corrections from it.
    """

    def __init__(self, follower, curved=False):
        self.follower = follower
        self.curved = curved   # follows a departure curve (nav/curves.py): it drives forward first
        self.p = follower.p
        self.corrections = 0
        self.rest = None
        self._arrival = None

    def step(self, now, stamp, pose):
        progress = self.follower.step(*pose)
        if progress.phase != DONE:
            return progress
        if self._arrival is None:
            self._arrival = Arrival(self.p, now, self.follower.goal.precision)
        rest = self._arrival.update(now, stamp, pose)
        if rest is None:
            return Progress(SETTLE, progress.remaining, progress.lateral_error, STOP)
        if self.follower.within_tolerance(*rest) or self.corrections >= self.p.max_corrections:
            self.rest = rest
            return progress
        self.corrections += 1
        self.follower, self._arrival = self.follower.correction(*rest), None
        return self.follower.step(*rest)

    def blocked_command(self, pose):
        """What to send while a 3-D obstacle blocks the goal: the follower's spin in place when that is
        what it would do from ``pose`` now, else a stop.

        robot_control refuses either while the obstacle stands (move_base sends this only then,
        supervisor.may_turn_away), but obstacle_detector looks where the last move_cmd points: a stop
        keeps it looking ahead, so a robot stopped facing equipment would wait for it to go away; a
        spin makes it check the footprint's disc, and when that is clear the obstacle is released and
        the robot turns towards its path. The follower spins when its path leaves far off the heading
        (``spin_enter``; at a fresh plan's start, more than the turn a 0.65 m curve takes).
        """
        if pose is not None and self.follower.phase in (ALIGN, TRACK, SPIN):
            command = self.follower.step(*pose).command
            if command.wheel_control == WHEEL_STEER and command.velocity_yaw != 0.0:
                return command
        return STOP


def stop_spin_go_params(**overrides):
    """The follower as it drove before regulation (fixed 0.6 m lookahead, spin beyond 1 rad): a baseline."""
    values = dict(lookahead_m=0.6, lookahead_min_m=0.6, spin_enter_rad=1.0, min_turn_radius_m=0.0,
                  corner_accel_m_s2=1e9, yaw_decel_rad_s2=1.0)
    values.update(overrides)
    return FollowerParams(**values)
