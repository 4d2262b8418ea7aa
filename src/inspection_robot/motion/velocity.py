"""MoveCmd validation and clamping.

MoveCmd carries velocity_x in 0.001 m/s and velocity_yaw in 0.001 rad/s. A command is
*refused* (and the robot stopped) when a value is NaN or infinite, when its magnitude exceeds
``refuse_x``/``refuse_yaw`` (far beyond any speed this robot can reach, so most likely a unit
error: clamping it to the maximum would turn a bug into full speed), or when wheel_control is not
0|1. Magnitudes between the configured limit and the refusal threshold are clamped to the limit.
In steer (spin-in-place) mode velocity_x is ignored: the wheels cannot translate.
"""
import math
from collections import namedtuple

from inspection_robot.command import CommandError
from inspection_robot.interface import (MOVE_VELOCITY_X_UNIT_M_S, MOVE_VELOCITY_YAW_UNIT_RAD_S, WHEEL_STEER,
                                        WHEEL_STRAIGHT)

Velocity = namedtuple("Velocity", "x yaw wheel_mode clamped")


class VelocityLimits(object):
    """Limits in SI units: max_x (m/s), max_yaw (rad/s); refuse_x/refuse_yaw above which a command is refused."""

    def __init__(self, max_x=1.0, max_yaw=1.0, refuse_x=5.0, refuse_yaw=5.0):
        for name, value in (("max_x", max_x), ("max_yaw", max_yaw), ("refuse_x", refuse_x),
                            ("refuse_yaw", refuse_yaw)):
            if not (math.isfinite(value) and value > 0):
                raise ValueError("%s must be a positive number, got %r" % (name, value))
        if refuse_x < max_x or refuse_yaw < max_yaw:
            raise ValueError("refusal thresholds must not be below the limits")
        self.max_x, self.max_yaw = float(max_x), float(max_yaw)
        self.refuse_x, self.refuse_yaw = float(refuse_x), float(refuse_yaw)

    def check(self, velocity_x_units, velocity_yaw_units, wheel_control):
        """Return a Velocity in SI units, or raise CommandError with the reason for refusing it."""
        if wheel_control not in (WHEEL_STRAIGHT, WHEEL_STEER):
            raise CommandError("wheel_control must be 0 or 1, got %r" % (wheel_control,))
        vx = _finite(velocity_x_units, "velocity_x") * MOVE_VELOCITY_X_UNIT_M_S
        wz = _finite(velocity_yaw_units, "velocity_yaw") * MOVE_VELOCITY_YAW_UNIT_RAD_S
        if abs(vx) > self.refuse_x:
            raise CommandError("velocity_x %.3f m/s exceeds the plausible %.3f m/s (unit error?)" % (vx, self.refuse_x))
        if abs(wz) > self.refuse_yaw:
            raise CommandError("velocity_yaw %.3f rad/s exceeds the plausible %.3f rad/s (unit error?)"
                               % (wz, self.refuse_yaw))
        if wheel_control == WHEEL_STEER:
            vx = 0.0
        cx = max(-self.max_x, min(self.max_x, vx))
        cz = max(-self.max_yaw, min(self.max_yaw, wz))
        return Velocity(cx, cz, wheel_control, (cx, cz) != (vx, wz))


def _finite(value, name):
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise CommandError("%s is not a number: %r" % (name, value))
    if not math.isfinite(value):
        raise CommandError("%s must be finite, got %r" % (name, value))
    return value
