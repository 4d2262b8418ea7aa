"""Does a replay reproduce the live run? Compares two robot_status streams field by field.

Both streams are lists of ``(t, fields)``, ``t`` the header stamp in seconds (live: the robot's
clock; replay: the bag's clock, which is the recording's), ``fields`` a dict of RobotStatus
fields. A replayed status matches when each of its fields agrees with that field of some live
status within ``time_tol`` seconds of it: modes and bits (DISCRETE_FIELDS) exactly, pose and
speeds within tolerance. Field by field, because live and replayed statuses are published at
slightly different instants and status_control merges several topics: a replayed status may hold
the new odometry and the old control_status for a millisecond, a mix no live status had.
Used by the replay regression rostests; pure, unit tested.
"""
import math

DISCRETE_FIELDS = ("offline_warn", "mode", "nav_status", "sensor_status", "wheel_status", "light_status",
                   "stop_status", "circuit_status", "other_status", "battery_voltage", "battery_current",
                   "battery_quantity", "battery_status", "motor_status", "motor_info", "temperature")
COMPARED_FIELDS = DISCRETE_FIELDS + ("position", "orientation", "velocity_x", "velocity_yaw")


def _close(a, b, tol):
    return abs(a - b) <= tol


def field_difference(name, live, replayed, pos_tol=0.05, yaw_tol=0.05, speed_tol=0.05):
    """None when field ``name`` of two robot_status dicts agrees, else why not (text)."""
    a, b = live[name], replayed[name]
    if name == "position":
        a, b = list(a), list(b)
        if len(a) == len(b) and all(_close(x, y, pos_tol) for x, y in zip(a, b)):
            return None
    elif name == "orientation":
        if abs(math.atan2(math.sin(a - b), math.cos(a - b))) <= yaw_tol:
            return None
    elif name in ("velocity_x", "velocity_yaw"):
        if _close(a, b, speed_tol):
            return None
    elif _as_list(a) == _as_list(b):
        return None
    return "%s: live %r, replay %r" % (name, _as_list(a), _as_list(b))


def status_difference(live, replayed, **tolerances):
    """None when two robot_status dicts agree in every compared field, else the first difference."""
    for name in COMPARED_FIELDS:
        reason = field_difference(name, live, replayed, **tolerances)
        if reason:
            return reason
    return None


def _as_list(value):
    return list(value) if isinstance(value, (list, tuple, bytes)) else value


def compare_runs(live, replayed, time_tol=0.25, margin=1.0, **tolerances):
    """Returns (checked count, mismatches as (t, reason) texts) over the time both streams cover.

    ``margin`` seconds at each end of the common window are skipped (start-up and shut-down).
    """
    if not live or not replayed:
        return 0, [(0.0, "empty stream: %d live, %d replayed statuses" % (len(live), len(replayed)))]
    lo = max(live[0][0], replayed[0][0]) + margin
    hi = min(live[-1][0], replayed[-1][0]) - margin
    mismatches, checked, j = [], 0, 0
    for t, fields in replayed:
        if not lo <= t <= hi:
            continue
        checked += 1
        while j < len(live) and live[j][0] < t - time_tol:
            j += 1
        window = []
        k = j
        while k < len(live) and live[k][0] <= t + time_tol:
            window.append(live[k][1])
            k += 1
        if not window:
            mismatches.append((t, "no live status within %.2f s" % time_tol))
            continue
        for name in COMPARED_FIELDS:
            reasons = [field_difference(name, other, fields, **tolerances) for other in window]
            if all(reasons):
                mismatches.append((t, reasons[0]))
                break
    return checked, mismatches


def rising_edges(stream, field):
    """Times at which ``field`` goes from 0 to non-zero."""
    edges, before = [], None
    for t, fields in stream:
        value = fields[field]
        if value and before is not None and not before:
            edges.append(t)
        before = value
    return edges


def transitions(stream, fields, start=None, end=None):
    """[(t, values)] of a status stream: its state at ``start`` (the last status at or before it, else
    the first after it) and every change of the ``fields`` tuple up to ``end``; ``values`` a tuple."""
    out = []
    for t, status in stream:
        if end is not None and t > end:
            break
        values = tuple(_as_list(status[f]) for f in fields)
        if start is not None and t <= start:
            out = [(start, values)]
        elif not out or out[-1][1] != values:
            out.append((t, values))
    return out


def transition_differences(live, replayed, time_tol=0.5):
    """Texts of the differences between two transitions lists: the same states in the same order,
    each change within ``time_tol`` s (the first entry is the window's start state: value only)."""
    problems = []
    if [v for _t, v in live] != [v for _t, v in replayed]:
        problems.append("states differ: live %s, replay %s" % ([v for _t, v in live], [v for _t, v in replayed]))
        return problems
    for i, ((t_live, values), (t_replay, _v)) in enumerate(zip(live, replayed)):
        if i and abs(t_live - t_replay) > time_tol:
            problems.append("%s: live at %.3f s, replay at %.3f s" % (values, t_live, t_replay))
    return problems
