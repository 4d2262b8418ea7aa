"""The arm driver interface robot_arm talks to (real arms and the simulator implement it).

Poses are in the arm base frame, ROS axes: position (x forward, y left, z up) in mm; orientation
(roll clockwise +, pitch down +, yaw counter-clockwise +) in degrees.
"""
from collections import namedtuple

AXES = 3

Limits = namedtuple("Limits", "position_mm orientation_deg")   # each: ((lo, hi), (lo, hi), (lo, hi))


class ArmError(Exception):
    """The arm could not carry out a request; the message is the reason."""


class ArmDriver(object):
    """Interface. ``limits`` is a :data:`Limits`; jog directions are -1, 0 or +1 per axis."""

    limits = None

    def position(self):
        """(x, y, z) mm now."""
        raise NotImplementedError

    def orientation(self):
        """(roll, pitch, yaw) deg now."""
        raise NotImplementedError

    def jog(self, linear=None, angular=None):
        """Continuous motion: per-axis direction tuples; None leaves that group as it is."""
        raise NotImplementedError

    def jog_state(self):
        """(linear directions, angular directions) of the current jog."""
        raise NotImplementedError

    def command_pose(self, position=None, orientation=None):
        """Go to an absolute pose at full speed (None keeps that part); returns at once."""
        raise NotImplementedError

    def stop(self):
        """Stop every motion."""
        raise NotImplementedError

    def moving(self):
        raise NotImplementedError


def within(values, ranges):
    """Index of the first value outside its (lo, hi) range, or None."""
    for i, (value, (low, high)) in enumerate(zip(values, ranges)):
        if not low <= value <= high:
            return i
    return None
