"""Planar angle helpers shared by motion, nav, status, sim and the nodes (radians throughout).

One place for wrapping and for the yaw <-> quaternion conversion of a planar pose, so the
odometry, the simulators, the localizer inputs and robot_status cannot drift apart.
"""
import math


def wrap_angle(angle):
    """``angle`` (rad) wrapped to [-pi, pi]."""
    return math.atan2(math.sin(angle), math.cos(angle))


def yaw_from_quaternion(x, y, z, w):
    """Yaw (rad, about +z) of the quaternion (x, y, z, w)."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def quaternion_from_yaw(yaw):
    """(x, y, z, w) of a rotation by ``yaw`` rad about +z."""
    return 0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0)
