"""Patrol tasks as the backend submits them (JSON), checked completely before the robot moves.

A task is an ordered list of stops; each stop is a goal pose and the presets inspected there.
Parsing is strict: every malformed field raises CommandError naming the stop, the preset and the
value. Two checks need the robot's world and are passed in: ``resolve_preset(name)`` (the preset
directory exists and is calibrated: returns a ResolvedPreset) and ``reachable(x, y)`` (None, or the
reason the pose cannot be reached).
"""
import math
import re
from collections import namedtuple

from inspection_robot.command import CommandError, parse_json, refuse_unknown_keys
from inspection_robot.inspection.calibration_schema import nested_bands_fault

PRIORITY_ROUTINE = "routine"
PRIORITY_SPECIAL = "special"
PRIORITIES = (PRIORITY_ROUTINE, PRIORITY_SPECIAL)
# A task id names its report folder (tasks/reports/<id>/): no '.' (so never '.' or '..'), matched
# with fullmatch (a '$' would let a trailing newline through).
TASK_ID_PATTERN = re.compile(r"[A-Za-z0-9_-]{1,64}")
MAX_STOPS = 200
MAX_PRESETS_PER_STOP = 20
MAX_RETRIES = 10
MAX_COORDINATE_M = 100000.0
TASK_KEYS = ("id", "priority", "retries", "order", "stops")
ORDER_GIVEN = "given"        # stops visited as listed
ORDER_SHORTEST = "shortest"  # task_manager orders them by the planner's path lengths (task/route.py)
ORDERS = (ORDER_GIVEN, ORDER_SHORTEST)
STOP_KEYS = ("name", "pose", "precision", "presets")
PRESET_KEYS = ("preset", "alarms", "foreign")
LIMIT_KEYS = ("normal", "alarm")   # a target's limits as an object (parse_limits)

# What resolve_preset answers: the preset directory (absolute) and its calibrated targets, in
# calibration order, as [{"name", "kind", "unit"}] plus the preset's own limits {name: limits} (parse_limits).
ResolvedPreset = namedtuple("ResolvedPreset", "directory targets alarms")


class Task(object):
    """A checked task. ``stops``: [{"name", "x", "y", "yaw", "precision", "presets": [
    {"preset", "directory", "targets", "alarms", "foreign"}]}] (the stored, resolved form)."""

    def __init__(self, task_id, priority, retries, stops, order=ORDER_GIVEN, planned_length_m=None,
                 home_leg_m=None):
        self.task_id = task_id
        self.priority = priority
        self.retries = retries
        self.stops = stops
        self.order = order
        self.planned_length_m = planned_length_m  # the route's planned length (task/route.py), None until planned
        self.home_leg_m = home_leg_m   # its last leg, the last stop to home, which a patrol does not drive

    def to_dict(self):
        return {"id": self.task_id, "priority": self.priority, "retries": self.retries, "order": self.order,
                "planned_length_m": self.planned_length_m, "home_leg_m": self.home_leg_m, "stops": self.stops}

    @classmethod
    def from_dict(cls, d):
        """The stored form back (already checked at submission; tasks stored before ``order`` existed
        were given in order and not measured)."""
        return cls(d["id"], d["priority"], d["retries"], d["stops"], d.get("order", ORDER_GIVEN),
                   d.get("planned_length_m"), d.get("home_leg_m"))

    def preset_keys(self):
        """Every (stop index, preset index), in patrol order (0-based)."""
        return [(i, j) for i, stop in enumerate(self.stops) for j in range(len(stop["presets"]))]

    @property
    def special(self):
        return self.priority == PRIORITY_SPECIAL


def json_object(value, what, keys):
    if not isinstance(value, dict):
        raise CommandError("%s must be a JSON object, got %s" % (what, json_type(value)))
    return refuse_unknown_keys(value, what, keys)


def json_type(value):
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, (int, float)):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "a list"
    return "null" if value is None else "an object"


def _number(value, what, low=None, high=None):
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise CommandError("%s must be a number, got %s" % (what, json_type(value)))
    if not math.isfinite(value):
        raise CommandError("%s must be finite, got %s" % (what, value))
    if (low is not None and value < low) or (high is not None and value > high):
        raise CommandError("%s out of range [%s, %s]: %s" % (what, low, high, value))
    return float(value)


def _integer(value, what, low, high):
    if isinstance(value, bool) or not isinstance(value, int):
        raise CommandError("%s must be an integer, got %s" % (what, short_value(value)))
    if value < low or value > high:
        raise CommandError("%s out of range [%d, %d]: %d" % (what, low, high, value))
    return value


def short_value(value):
    """A value for an error message, cut short (a careless client may send megabytes)."""
    text = repr(value)
    return text if len(text) <= 40 else text[:40] + "..."


def check_task_id(task_id):
    """``task_id`` if it is 1-64 characters of A-Z a-z 0-9 _ -, else CommandError."""
    if not isinstance(task_id, str) or not TASK_ID_PATTERN.fullmatch(task_id):
        raise CommandError("task id must be 1-64 characters of A-Z a-z 0-9 _ -, got %s" % short_value(task_id))
    return task_id


def parse_band(value, what):
    """An alarm band [low, high] (the normal range of the value)."""
    if not isinstance(value, list) or len(value) != 2:
        raise CommandError("%s must be [low, high], got %s" % (what, short_value(value)))
    low, high = _number(value[0], what + " low"), _number(value[1], what + " high")
    if low > high:
        raise CommandError("%s: low %g is above high %g" % (what, low, high))
    return [low, high]


def parse_limits(value, what):
    """A target's limits: its normal band [low, high] (outside it: alarm), or
    {"normal": [low, high], "alarm": [low, high]} (outside normal: warning; outside alarm: alarm),
    the alarm band containing the normal one. Returned in the form given, checked."""
    if not isinstance(value, dict):
        return parse_band(value, what)
    refuse_unknown_keys(value, what, LIMIT_KEYS)
    if "normal" not in value:
        raise CommandError("%s: missing normal (the band the value should be in)" % what)
    normal = parse_band(value["normal"], what + " normal")
    if "alarm" not in value:
        return {"normal": normal}
    alarm = parse_band(value["alarm"], what + " alarm")
    fault = nested_bands_fault(normal, alarm)
    if fault:
        raise CommandError("%s: %s" % (what, fault))
    return {"normal": normal, "alarm": alarm}


def split_limits(limits):
    """(normal band or None, alarm band or None) of a stored target's limits (parse_limits' forms)."""
    if limits is None:
        return None, None
    if isinstance(limits, dict):
        return limits.get("normal"), limits.get("alarm")
    return limits, None


def parse_task(data, resolve_preset, reachable, default_retries, known_ids=(), default_id=None):
    """Parse and check the JSON text ``data``; returns a Task or raises CommandError. ``default_id``:
    the id of a task given without one (plan, routines), else the id is required."""
    obj = json_object(parse_json(data, "task"), "task", TASK_KEYS)
    task_id = check_task_id(obj.get("id", default_id))
    if task_id in known_ids:
        raise CommandError("duplicate task id '%s' (ids are never reused)" % task_id)
    priority = obj.get("priority", PRIORITY_ROUTINE)
    if priority not in PRIORITIES:
        raise CommandError("priority must be one of %s, got %s" % ("|".join(PRIORITIES), short_value(priority)))
    retries = _integer(obj.get("retries", default_retries), "retries", 0, MAX_RETRIES)
    order = obj.get("order", ORDER_GIVEN)
    if order not in ORDERS:
        raise CommandError("order must be one of %s, got %s" % ("|".join(ORDERS), short_value(order)))
    stops = obj.get("stops")
    if not isinstance(stops, list) or not stops:
        raise CommandError("stops must be a non-empty list")
    if len(stops) > MAX_STOPS:
        raise CommandError("too many stops: %d (at most %d)" % (len(stops), MAX_STOPS))
    parsed = [_parse_stop(stop, i, resolve_preset) for i, stop in enumerate(stops)]
    for i, stop in enumerate(parsed):  # reachability last: the cheap checks answer first
        reason = reachable(stop["x"], stop["y"])
        if reason:
            raise CommandError("stop %d (%s): pose (%.2f, %.2f) is unreachable: %s"
                               % (i + 1, stop["name"], stop["x"], stop["y"], reason))
    return Task(task_id, priority, retries, parsed, order)


def _parse_stop(stop, index, resolve_preset):
    what = "stop %d" % (index + 1)
    stop = json_object(stop, what, STOP_KEYS)
    name = stop.get("name", "stop_%d" % (index + 1))
    if not isinstance(name, str) or len(name) > 64:
        raise CommandError("%s: name must be a string of at most 64 characters" % what)
    pose = json_object(stop.get("pose"), what + " pose", ("x", "y", "yaw"))
    for key in ("x", "y", "yaw"):
        if key not in pose:
            raise CommandError("%s pose: missing %s" % (what, key))
    x = _number(pose["x"], what + " pose x", -MAX_COORDINATE_M, MAX_COORDINATE_M)
    y = _number(pose["y"], what + " pose y", -MAX_COORDINATE_M, MAX_COORDINATE_M)
    yaw = _number(pose["yaw"], what + " pose yaw", -2 * math.pi, 2 * math.pi)
    precision = stop.get("precision", 0)
    if isinstance(precision, bool) or precision not in (0, 1):
        raise CommandError("%s: precision must be 0 or 1, got %s" % (what, short_value(precision)))
    presets = stop.get("presets")
    if not isinstance(presets, list) or not presets:
        raise CommandError("%s: presets must be a non-empty list" % what)
    if len(presets) > MAX_PRESETS_PER_STOP:
        raise CommandError("%s: too many presets: %d (at most %d)" % (what, len(presets), MAX_PRESETS_PER_STOP))
    return {"name": name, "x": x, "y": y, "yaw": math.atan2(math.sin(yaw), math.cos(yaw)),
            "precision": int(precision),
            "presets": [_parse_preset(p, "%s preset %d" % (what, j + 1), resolve_preset)
                        for j, p in enumerate(presets)]}


def _parse_preset(entry, what, resolve_preset):
    if isinstance(entry, str):
        entry = {"preset": entry}
    entry = json_object(entry, what, PRESET_KEYS)
    name = entry.get("preset")
    if not isinstance(name, str) or not name:
        raise CommandError("%s: preset must be a non-empty string (a preset directory or id)" % what)
    foreign = entry.get("foreign", False)
    if not isinstance(foreign, bool):
        raise CommandError("%s: foreign must be true or false, got %s" % (what, short_value(foreign)))
    resolved = resolve_preset(name)  # raises CommandError: unknown preset directory ...
    alarms = dict(resolved.alarms)
    given = entry.get("alarms", {})
    if not isinstance(given, dict):
        raise CommandError("%s: alarms must be an object {target name: [low, high] or "
                           "{\"normal\": [low, high], \"alarm\": [low, high]}}" % what)
    names = [t["name"] for t in resolved.targets]
    for target, band in given.items():
        if target not in names:
            raise CommandError("%s: alarm for unknown target '%s' of preset '%s' (targets: %s)"
                               % (what, target, name, ", ".join(names)))
        alarms[target] = parse_limits(band, "%s alarm of %s" % (what, target))
    return {"preset": name, "directory": resolved.directory, "targets": list(resolved.targets),
            "alarms": alarms, "foreign": foreign}
