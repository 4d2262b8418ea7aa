"""find_scale_action payloads (INTERFACE.md section 4, "Meter finding"): the goal and result JSON.

One module for both ends: find_scale parses goals and writes results here, task_manager writes
goals and parses results here, so a key renamed on one side cannot silently miss the other.
"""
import json

from inspection_robot.command import CommandError, parse_json, refuse_unknown_keys
from inspection_robot.files import confine_path
from inspection_robot.interface import FIND_GOAL_TYPES

# the result's keys: the spec's five, then second_filename (the second look for read_scale, "" when none)
RESULT_KEYS = ("filename", "infrared_filename", "foreign_filename", "roi_vertex", "infrared_roi_vertex",
               "second_filename")


def find_goal_data(preset_dir):
    """The goal JSON ``parse_find_goal`` reads."""
    return json.dumps({"preset_path": preset_dir})


def parse_find_goal(goal_type, data, preset_roots):
    """(type, preset directory) of a goal; CommandError with the reason on bad input."""
    if goal_type not in FIND_GOAL_TYPES:
        raise CommandError("unknown goal type '%s' (one of %s)" % (goal_type, "|".join(FIND_GOAL_TYPES)))
    fields = parse_json(data, "goal data")
    if not isinstance(fields, dict) or not isinstance(fields.get("preset_path"), str):
        raise CommandError('goal data must be {"preset_path": "<dir>"}')
    refuse_unknown_keys(fields, "goal data", ("preset_path",))
    return goal_type, confine_path(fields["preset_path"], preset_roots)


def find_result_data(filename="", infrared_filename="", foreign_filename="", roi_vertex=(), infrared_roi_vertex=(),
                     second_filename=""):
    """The data JSON of a succeeded goal (all keys always present; pre_find answers them empty)."""
    return json.dumps({"filename": filename, "infrared_filename": infrared_filename,
                       "foreign_filename": foreign_filename, "roi_vertex": list(roi_vertex),
                       "infrared_roi_vertex": list(infrared_roi_vertex), "second_filename": second_filename})


def parse_find_result(data):
    """The dict of a succeeded goal's data; ``second_filename`` defaults to "" (an older find_scale).

    ValueError / KeyError / TypeError when the data is not such an object.
    """
    found = json.loads(data)
    if not isinstance(found, dict):
        raise TypeError("not a JSON object")
    out = {key: found[key] for key in RESULT_KEYS[:5]}
    out["second_filename"] = found.get("second_filename", "")
    return out


def reason_data(reason):
    """The data JSON of a failed or cancelled goal (move_action and find_scale_action alike)."""
    return json.dumps({"reason": reason})


def reason_of(data):
    """The ``reason`` of a failed goal's data, else the data itself as text."""
    try:
        return str(json.loads(data).get("reason", data))
    except (ValueError, AttributeError):
        return str(data)
