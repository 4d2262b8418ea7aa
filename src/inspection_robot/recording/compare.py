"""Does a replay reproduce the live run? Compares two robot_status streams field by field.

Both streams are lists of ``(t, fields)``, ``t`` the header stamp in seconds (live: the robot's
clock; replay: the bag's clock, which is the recording's), ``fields`` a dict of RobotStatus
fields. A replayed status matches when some live status within ``time_tol`` seconds of it has the
same modes and bits (DISCRETE_FIELDS, exactly) and the same pose and speeds within tolerance: live
and replayed statuses are published at slightly different instants, so a transition may sit a
few milliseconds apart. Used by the replay regression rostests; pure, unit tested.
"""
import math

DISCRETE_FIELDS = ("offline_warn", "mode", "nav_status", "sensor_status", "wheel_status", "light_status",
                   "stop_status", "circuit_status", "other_status", "battery_voltage", "battery_current",
                   "battery_quantity", "battery_status", "motor_status", "motor_info", "temperature")


def _close(a, b, tol):
    return abs(a - b) <= tol


def status_difference(live, replayed, pos_tol=0.05, yaw_tol=0.05, speed_tol=0.05):
    """None when two robot_status dicts agree, else the first field that differs (text)."""
    for name in DISCRETE_FIELDS:
        if _as_list(live[name]) != _as_list(replayed[name]):
            return "%s: live %r, replay %r" % (name, _as_list(live[name]), _as_list(replayed[name]))
    lp, rp = list(live["position"]), list(replayed["position"])
    if len(lp) != len(rp) or any(not _close(a, b, pos_tol) for a, b in zip(lp, rp)):
        return "position: live %r, replay %r" % (lp, rp)
    yaw_error = math.atan2(math.sin(live["orientation"] - replayed["orientation"]),
                           math.cos(live["orientation"] - replayed["orientation"]))
    if abs(yaw_error) > yaw_tol:
        return "orientation: live %.3f, replay %.3f" % (live["orientation"], replayed["orientation"])
    for name in ("velocity_x", "velocity_yaw"):
        if not _close(live[name], replayed[name], speed_tol):
            return "%s: live %.3f, replay %.3f" % (name, live[name], replayed[name])
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
        reasons = []
        k = j
        while k < len(live) and live[k][0] <= t + time_tol:
            reason = status_difference(live[k][1], fields, **tolerances)
            if reason is None:
                break
            reasons.append(reason)
            k += 1
        else:
            mismatches.append((t, reasons[0] if reasons else "no live status within %.2f s" % time_tol))
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
