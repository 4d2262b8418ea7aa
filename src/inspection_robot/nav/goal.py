"""move_action goals: strict parsing of the goal JSON (INTERFACE.md section 4, "Navigation").

``{"with_direction":0|1, "precision":0|1, "move_style":0|1, "velocity_x":m/s, "velocity_yaw":rad/s,
"goal_pose":{"position":{"x":..,"y":..,"z":0},"orientation":{"x":0,"y":0,"z":..,"w":..}}}``

Flags and speeds may be omitted (flags default to 0, speeds to the node's defaults); a speed
above the node's maximum is clamped to it. Anything malformed raises CommandError with a reason,
a key not listed above too (``speed``: the goal would otherwise run at the default speed).
"""
import json
import math
from collections import namedtuple

from inspection_robot.angles import quaternion_from_yaw, yaw_from_quaternion
from inspection_robot.command import CommandError, parse_json, refuse_unknown_keys
from inspection_robot.interface import MOVE_GOAL_TYPE

MoveGoal = namedtuple("MoveGoal", "x y yaw with_direction precision backward velocity_x velocity_yaw")
GOAL_KEYS = ("goal_pose", "with_direction", "precision", "move_style", "velocity_x", "velocity_yaw")
POSE_KEYS = ("position", "orientation")
XYZ = ("x", "y", "z")
XYZW = ("x", "y", "z", "w")


def _number(obj, key, where, default=None):
    value = obj.get(key, default)
    if value is None:
        raise CommandError("%s.%s is missing" % (where, key))
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise CommandError("%s.%s must be a finite number, got %s" % (where, key, json.dumps(value)))
    return float(value)


def _flag(obj, key):
    value = obj.get(key, 0)
    if isinstance(value, bool):
        return value
    if value not in (0, 1):
        raise CommandError("%s must be 0 or 1, got %s" % (key, json.dumps(value)))
    return bool(value)


def parse_move_goal(goal_type, data, default_velocity_x, default_velocity_yaw, max_velocity_x, max_velocity_yaw):
    if goal_type != MOVE_GOAL_TYPE:
        raise CommandError("goal type must be '%s', got '%s'" % (MOVE_GOAL_TYPE, goal_type))
    obj = parse_json(data, "goal data")
    if not isinstance(obj, dict):
        raise CommandError("goal data must be a JSON object")
    refuse_unknown_keys(obj, "goal data", GOAL_KEYS)
    pose = obj.get("goal_pose")
    if not isinstance(pose, dict) or not isinstance(pose.get("position"), dict):
        raise CommandError("goal_pose.position is missing")
    refuse_unknown_keys(pose, "goal_pose", POSE_KEYS)
    refuse_unknown_keys(pose["position"], "goal_pose.position", XYZ)
    x = _number(pose["position"], "x", "goal_pose.position")
    y = _number(pose["position"], "y", "goal_pose.position")
    orientation = pose.get("orientation", {"x": 0, "y": 0, "z": 0, "w": 1})
    if not isinstance(orientation, dict):
        raise CommandError("goal_pose.orientation must be an object")
    refuse_unknown_keys(orientation, "goal_pose.orientation", XYZW)
    quat = [_number(orientation, k, "goal_pose.orientation", 0.0 if k != "w" else None) for k in "xyzw"]
    norm = math.sqrt(sum(q * q for q in quat))
    if norm < 1e-6:
        raise CommandError("goal_pose.orientation is not a valid quaternion (zero length)")
    yaw = yaw_from_quaternion(*[q / norm for q in quat])
    move_style = obj.get("move_style", 0)
    if move_style not in (0, 1) or isinstance(move_style, bool):
        raise CommandError("move_style must be 0 (forward) or 1 (backward), got %s" % json.dumps(move_style))
    speeds = []
    for key, default, limit in (("velocity_x", default_velocity_x, max_velocity_x),
                                ("velocity_yaw", default_velocity_yaw, max_velocity_yaw)):
        value = _number(obj, key, "goal", default)
        if value <= 0:
            raise CommandError("%s must be positive, got %s" % (key, json.dumps(obj.get(key))))
        speeds.append(min(value, limit))
    return MoveGoal(x, y, yaw, _flag(obj, "with_direction"), _flag(obj, "precision"), move_style == 1,
                    speeds[0], speeds[1])


def move_goal_data(x, y, yaw, precision=False, backward=False, with_direction=True, velocity_x=None,
                   velocity_yaw=None):
    """The goal JSON ``parse_move_goal`` reads, for clients of move_action (charge_control, task_manager).

    Speeds left None are omitted (move_base's defaults apply).
    """
    qx, qy, qz, qw = quaternion_from_yaw(yaw)
    obj = {"with_direction": int(bool(with_direction)), "precision": int(bool(precision)),
           "move_style": 1 if backward else 0,
           "goal_pose": {"position": {"x": float(x), "y": float(y), "z": 0.0},
                         "orientation": {"x": qx, "y": qy, "z": qz, "w": qw}}}
    if velocity_x is not None:
        obj["velocity_x"] = float(velocity_x)
    if velocity_yaw is not None:
        obj["velocity_yaw"] = float(velocity_yaw)
    return json.dumps(obj, sort_keys=True)
