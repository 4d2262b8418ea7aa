"""How far a running drive has got, from move_action feedback: task_manager's ETA falls during drives.

move_base reports feedback "1" (planned, data ``{"path_length": m}``) when it has a path and "2"
(moving, data ``{"remaining": m, ...}``) every ``~feedback_period`` while it follows it (docs/interface.md,
Navigation). The fraction driven is 1 - remaining / path_length of the latest plan (a replan starts it
again from that plan's length). Pure: fed event codes and JSON text, no ROS.
"""
import json
import math

from inspection_robot.interface import MOVE_FEEDBACK_MOVING, MOVE_FEEDBACK_PLANNED


class DriveProgress(object):
    """Feed each move_action feedback; ``feed`` returns the fraction driven (0..1) or None (unknown)."""

    def __init__(self):
        self.path_length = None

    def feed(self, event_code, data):
        try:
            values = json.loads(data) if data else {}
        except ValueError:
            return None
        if not isinstance(values, dict):
            return None
        if event_code == MOVE_FEEDBACK_PLANNED:
            length = _number(values.get("path_length"))
            self.path_length = length if length is not None and length > 0 else None
            return 0.0 if self.path_length else None
        if event_code == MOVE_FEEDBACK_MOVING and self.path_length:
            remaining = _number(values.get("remaining"))
            if remaining is None:
                return None
            return min(1.0, max(0.0, 1.0 - remaining / self.path_length))
        return None


def _number(value):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        return None
    return float(value)
