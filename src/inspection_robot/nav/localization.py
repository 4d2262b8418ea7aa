"""Localization health: a pose is trusted while it is fresh and its covariance is small.

Fed with every pose message (time, x, y, yaw, 6x6 row-major covariance); ``problem(now)``
names why localization counts as lost (nav_warn bit1, goal aborted with ret_code "2"), or is None.
"""
import math

from inspection_robot.angles import wrap_angle


class LocalizationMonitor(object):
    def __init__(self, max_xy_std_m, max_yaw_std_rad, stale_timeout_s):
        self.max_xy_std = float(max_xy_std_m)
        self.max_yaw_std = float(max_yaw_std_rad)
        self.stale_timeout = float(stale_timeout_s)
        self.pose = None       # (x, y, yaw) of the last message
        self._stamp = None
        self._covariance_problem = None

    def update(self, now, x, y, yaw, covariance):
        if not all(math.isfinite(v) for v in (x, y, yaw)):
            self._covariance_problem = "pose is not finite"
            self._stamp = now
            return
        self.pose = (float(x), float(y), wrap_angle(float(yaw)))
        self._stamp = now
        self._covariance_problem = None
        if covariance is not None and len(covariance) == 36:
            var_x, var_y, var_yaw = covariance[0], covariance[7], covariance[35]
            if not all(math.isfinite(v) for v in (var_x, var_y, var_yaw)):
                self._covariance_problem = "covariance is not finite"
            elif math.sqrt(max(var_x, 0.0) + max(var_y, 0.0)) > self.max_xy_std:
                self._covariance_problem = "position uncertainty %.2f m > %.2f m" % (
                    math.sqrt(max(var_x, 0.0) + max(var_y, 0.0)), self.max_xy_std)
            elif math.sqrt(max(var_yaw, 0.0)) > self.max_yaw_std:
                self._covariance_problem = "heading uncertainty %.3f rad > %.3f rad" % (
                    math.sqrt(max(var_yaw, 0.0)), self.max_yaw_std)

    def problem(self, now):
        if self._stamp is None:
            return "no pose received yet"
        age = now - self._stamp
        if age > self.stale_timeout:
            return "pose is stale (%.1f s old)" % age
        return self._covariance_problem

    def lost(self, now):
        return self.problem(now) is not None
