"""A simulated robot arm behind :class:`inspection_robot.arm.driver.ArmDriver`.

Cartesian model of the end effector: jog velocities per axis, absolute targets approached in a
straight line at the configured speeds, clamped to the workspace box and the orientation limits
(the joint-like limits). State advances from a monotonic clock whenever it is read. ``fault`` set
to a reason makes every call raise ArmError (tests inject it to exercise unprompted failures).
"""
import math
import threading
import time

from inspection_robot.arm.driver import AXES, ArmDriver, ArmError, Limits


class SimArm(ArmDriver):
    def __init__(self, limits, linear_speed_mm_s=200.0, angular_speed_deg_s=90.0, clock=time.monotonic):
        for lo_hi in tuple(limits.position_mm) + tuple(limits.orientation_deg):
            if not lo_hi[0] <= 0.0 <= lo_hi[1]:
                raise ValueError("arm limits must contain the zero (reset) pose: %r" % (limits,))
        self.limits = Limits(tuple(tuple(float(v) for v in r) for r in limits.position_mm),
                             tuple(tuple(float(v) for v in r) for r in limits.orientation_deg))
        self.linear_speed = float(linear_speed_mm_s)
        self.angular_speed = float(angular_speed_deg_s)
        self._clock = clock
        self._last = clock()
        self._lock = threading.Lock()
        self._pose = [[0.0] * AXES, [0.0] * AXES]           # position, orientation
        self._jog = [[0] * AXES, [0] * AXES]
        self._target = [None, None]
        self.fault = None

    def _check(self):
        if self.fault:
            raise ArmError("arm fault: %s" % self.fault)

    def _advance(self):
        now = self._clock()
        dt = max(0.0, now - self._last)
        self._last = now
        for part, speed, ranges in ((0, self.linear_speed, self.limits.position_mm),
                                    (1, self.angular_speed, self.limits.orientation_deg)):
            pose = self._pose[part]
            target = self._target[part]
            if target is not None:
                error = [t - p for t, p in zip(target, pose)]
                distance = math.sqrt(sum(e * e for e in error))
                step = speed * dt
                if distance <= step:
                    self._pose[part] = list(target)
                    self._target[part] = None
                else:
                    self._pose[part] = [p + e * step / distance for p, e in zip(pose, error)]
            else:
                self._pose[part] = [p + d * speed * dt for p, d in zip(pose, self._jog[part])]
            self._pose[part] = [min(max(p, lo), hi) for p, (lo, hi) in zip(self._pose[part], ranges)]

    def position(self):
        with self._lock:
            self._check()
            self._advance()
            return tuple(self._pose[0])

    def orientation(self):
        with self._lock:
            self._check()
            self._advance()
            return tuple(self._pose[1])

    def jog(self, linear=None, angular=None):
        with self._lock:
            self._check()
            self._advance()
            for part, dirs in ((0, linear), (1, angular)):
                if dirs is not None:
                    self._target[part] = None
                    self._jog[part] = [int(d) for d in dirs]

    def jog_state(self):
        with self._lock:
            self._check()
            return tuple(self._jog[0]), tuple(self._jog[1])

    def command_pose(self, position=None, orientation=None):
        with self._lock:
            self._check()
            self._advance()
            for part, pose in ((0, position), (1, orientation)):
                if pose is not None:
                    self._jog[part] = [0] * AXES
                    self._target[part] = [min(max(float(p), lo), hi) for p, (lo, hi)
                                          in zip(pose, self.limits[part])]

    def stop(self):
        with self._lock:
            self._advance()
            self._jog = [[0] * AXES, [0] * AXES]
            self._target = [None, None]
        self._check()

    def moving(self):
        with self._lock:
            self._check()
            self._advance()
            return any(t is not None for t in self._target) or any(any(j) for j in self._jog)
