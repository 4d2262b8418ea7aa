"""Localization health: a pose is trusted while it is fresh and its covariance is small.

Fed with every pose message (time, x, y, yaw, 6x6 row-major covariance, header frame);
``problem(now)`` names why localization counts as lost (nav_warn bit1, goal aborted with ret_code
"2"), or is None. The contract a localizer must meet (docs/interface.md "Localization contract"):
a pose in frame ``map`` at least every ``stale_timeout`` s, with a covariance that is either all
zero (unknown: trusted) or small enough; ``source`` names the topic and its setting in the reasons
so that a localizer that never publishes is found from nav_status alone.
``location_target`` turns a location_cmd into the pose handed to the localizer.
"""
import math

from inspection_robot.angles import wrap_angle
from inspection_robot.command import CommandError, parse_float, split_fields
from inspection_robot.interface import LOCATION_CMD_SET, LOCATION_INIT_POSE, LOCATION_LAST_POSE

MAP_FRAME = "map"   # the one frame move_base plans, follows and reports in


class LocalizationMonitor(object):
    def __init__(self, max_xy_std_m, max_yaw_std_rad, stale_timeout_s, source="the pose topic"):
        self.source = source
        self.max_xy_std = float(max_xy_std_m)
        self.max_yaw_std = float(max_yaw_std_rad)
        self.stale_timeout = float(stale_timeout_s)
        self.pose = None       # (x, y, yaw) of the last message
        self.stamp = None      # when it arrived (the ``now`` given to update)
        self._covariance_problem = None

    def update(self, now, x, y, yaw, covariance, frame=MAP_FRAME):
        if frame.lstrip("/") != MAP_FRAME:
            # a pose in odom or a sensor frame would steer the robot to the wrong place: never used
            self._covariance_problem = "pose from %s is in frame '%s', not '%s'" % (self.source, frame, MAP_FRAME)
            self.stamp = now
            return
        if not all(math.isfinite(v) for v in (x, y, yaw)):
            self._covariance_problem = "pose is not finite"
            self.stamp = now
            return
        self.pose = (float(x), float(y), wrap_angle(float(yaw)))
        self.stamp = now
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
        if self.stamp is None:
            return "no pose received yet from %s" % self.source
        age = now - self.stamp
        if age > self.stale_timeout:
            return "pose from %s is stale (%.1f s old)" % (self.source, age)
        return self._covariance_problem

    def lost(self, now):
        return self.problem(now) is not None


def location_target(cmd, data, init_pose, read_last_pose):
    """The pose a location_cmd asks for, as (x, y, yaw) in map metres and radians.

    ``cmd`` must be set_location; ``data`` is init_pose (``init_pose`` from config), last_pose
    (``read_last_pose()`` returns the saved dict or None) or "x,y,yaw". Anything else, including a
    damaged last-pose file, raises CommandError with the reason.
    """
    if cmd != LOCATION_CMD_SET:
        raise CommandError("unknown command '%s'" % cmd)
    if data == LOCATION_INIT_POSE:
        return tuple(float(v) for v in init_pose)
    if data == LOCATION_LAST_POSE:
        try:
            stored = read_last_pose()
        except (OSError, ValueError) as err:
            raise CommandError("last pose file unreadable: %s" % err)
        if not stored:
            raise CommandError("no last pose saved yet")
        try:
            values = [stored[k] for k in ("x", "y", "yaw")]
        except (KeyError, TypeError):
            raise CommandError("last pose file lacks x, y, yaw: %r" % (stored,))
        x, y, yaw = [parse_float(v, k) for v, k in zip(values, ("x", "y", "yaw"))]
        return x, y, wrap_angle(yaw)
    x, y, yaw = split_fields(data, 3)
    return parse_float(x, "x"), parse_float(y, "y"), wrap_angle(parse_float(yaw, "yaw"))
