"""A charging dock: where the robot stands to charge, where it lines up first, how close is close enough.

The same description serves the simulated chassis (it charges only when its true pose is within
the tolerances) and charge_control (it drives to ``approach``, docks at ``pose`` with precision 1,
backs off to ``approach``). YAML form (``world.dock`` in config/sim_world.yaml, ``charge_control/dock`` in
the site file, config/robot.example.yaml and config/sim_site.yaml)::

    dock: {pose: [x, y, yaw], approach_pose: [x, y, yaw], tolerance_m: 0.03, tolerance_yaw: 0.05}

Metres and radians in the map frame; ``pose`` yaw is the heading the robot has when docked.
"""
import math
from collections import namedtuple

from inspection_robot.angles import wrap_angle

Dock = namedtuple("Dock", "pose approach tolerance_m tolerance_yaw")

MAX_APPROACH_DISTANCE_M = 10.0  # an approach pose further away than this is a typo, not a dock
FIELDS = ("pose", "approach_pose", "tolerance_m", "tolerance_yaw")


class DockError(ValueError):
    """A dock description that cannot be used; the message names the field."""


def _pose(spec, key):
    value = spec.get(key)
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise DockError("dock.%s must be [x, y, yaw], got %r" % (key, value))
    try:
        pose = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise DockError("dock.%s must be three numbers, got %r" % (key, value))
    if not all(math.isfinite(v) for v in pose):
        raise DockError("dock.%s must be finite, got %r" % (key, value))
    return pose


def _positive(spec, key, default):
    value = spec.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < float("inf"):
        raise DockError("dock.%s must be a positive number, got %r" % (key, value))
    return float(value)


def parse_dock(spec):
    """A Dock from its YAML mapping; anything malformed raises DockError."""
    if not isinstance(spec, dict):
        raise DockError("dock must be a mapping with pose and approach_pose, got %r" % (spec,))
    unknown = sorted(str(key) for key in spec if key not in FIELDS)
    if unknown:  # a misspelt tolerance would silently fall back on its default
        raise DockError("dock.%s: unknown field (dock has %s)" % (unknown[0], ", ".join(FIELDS)))
    pose = _pose(spec, "pose")
    approach = _pose(spec, "approach_pose")
    distance = math.hypot(approach[0] - pose[0], approach[1] - pose[1])
    if not 0.0 < distance <= MAX_APPROACH_DISTANCE_M:
        raise DockError("dock.approach_pose must be 0-%.0f m from dock.pose, is %.2f m"
                        % (MAX_APPROACH_DISTANCE_M, distance))
    return Dock(pose, approach, _positive(spec, "tolerance_m", 0.03), _positive(spec, "tolerance_yaw", 0.05))


def pose_error(dock, pose):
    """(distance m, |yaw difference| rad) between ``pose`` (x, y, yaw) and the dock pose."""
    return (math.hypot(pose[0] - dock.pose[0], pose[1] - dock.pose[1]),
            abs(wrap_angle(pose[2] - dock.pose[2])))


def is_docked(dock, pose):
    """True when ``pose`` is on the dock within its tolerances (the charge contacts touch)."""
    distance, yaw = pose_error(dock, pose)
    return distance <= dock.tolerance_m and yaw <= dock.tolerance_yaw


def near_dock(dock, pose):
    """True when ``pose`` lies between the approach pose and the dock (a back-off is needed to leave)."""
    span = math.hypot(dock.approach[0] - dock.pose[0], dock.approach[1] - dock.pose[1])
    return math.hypot(pose[0] - dock.pose[0], pose[1] - dock.pose[1]) < 0.5 * span
