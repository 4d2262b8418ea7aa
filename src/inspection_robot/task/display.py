"""A reading as an operator reads it: rounded to its meter's resolution, with its unit or meaning.

One function for every place that shows a value: the reports (HTML, the ``display`` column of
report.csv and report.json), query_results / review_queue rows and task_status's last_result, which
the console shows as they come. The raw ``value`` always stays beside it: ``display`` is text.

A reading's ``decimals`` are its target's resolution at the time it was read (from the calibration,
display_decimals: ``digits``, or the smallest division of its scale),
kept in the reading row; rows stored before it have none and are shown with 4 significant digits.
Lamps and switches are state codes and are shown as words (``off``, ``lit red``; ``closed``,
``open``), foreign objects as a count.
"""
import math

from inspection_robot.inspection.calibration_schema import MAX_DIGITS, pointer_scale
from inspection_robot.inspection.lamp import LAMP_COLOURS

LEGACY_DIGITS = 4   # significant digits of a value stored without its decimals
SWITCH_STATES = {0: "open", 1: "closed"}


def reading_text(value, unit, decimals, kind):
    """The text of ``value`` (None: "", no value) of a ``kind`` target, e.g. ``0.80 MPa``."""
    if value is None:
        return ""
    value = float(value)
    code = int(round(value)) if value == value and abs(value) < 1e9 else None
    if kind == "lamp" and code is not None and code == value:
        if code == 0:
            return "off"
        return "lit %s" % LAMP_COLOURS[code - 1] if 0 < code <= len(LAMP_COLOURS) else "lamp code %d" % code
    if kind == "switch" and code in SWITCH_STATES and code == value:
        return SWITCH_STATES[code]
    if kind == "foreign" and code is not None:
        return "%d object%s" % (code, "" if code == 1 else "s")
    if decimals is None:
        text = "%.*g" % (LEGACY_DIGITS, value)
    else:
        text = "%.*f" % (int(decimals), value)
    if text.startswith("-") and float(text) == 0.0:
        text = text[1:]   # -0.001 at 2 places is 0.00, not -0.00
    return "%s %s" % (text, unit) if unit else text


def row_display(row):
    """``display`` (the robot's value) and ``review_display`` (the operator's, "" until reviewed) of a row."""
    decimals = row.get("decimals")
    reviewed = row.get("review_time") is not None
    return {"display": reading_text(row.get("value"), row.get("unit", ""), decimals, row.get("kind")),
            "review_display": reading_text(row.get("review_value"), row.get("unit", ""), decimals, row.get("kind"))
            if reviewed else ""}


THERMAL_DECIMALS = 1        # a thermal camera's 0.1 degC
FULL_SCALE_DIVISIONS = 100  # a pointer scale without marks: a hundredth of its span as its division


def display_decimals(kind, params):
    """The decimal places a reading of a target is shown with (its resolution), from checked params.

    ``digits`` wins. A pointer's resolution is the smallest division between its scale's values:
    the marks' values, else a scale_table's values when it has inner points (a non-linear scale,
    whose finest stretch counts): the places are those that write that division (0.05 -> 2,
    0.2 -> 1, 5 -> 0), at most one more than its first significant digit needs (a third: 2) and
    MAX_DIGITS. A scale with neither: the places of the first significant digit of its span /
    FULL_SCALE_DIVISIONS (0..1.6 MPa: 0.016 -> 2; 0..100: 0). Thermal: THERMAL_DECIMALS; lamps and
    switches (state codes) and anything else: 0.
    """
    if params.get("digits") is not None:
        return int(params["digits"])
    if kind == "thermal":
        return THERMAL_DECIMALS
    if kind == "digital":
        return int(params["decimals"])
    if kind != "pointer":
        return 0
    division = _smallest_gap([m[0] for m in params.get("marks") or ()], 2)
    if division is None:   # a table of two entries is only the scale's ends
        division = _smallest_gap([v for v, _a in params.get("scale_table") or ()], 3)
    if division is None:   # no division known: the places of a hundredth's first significant digit
        nominal = float("%.9g" % (pointer_scale(params).full_scale / FULL_SCALE_DIVISIONS))
        return min(MAX_DIGITS, max(0, -int(math.floor(math.log10(nominal)))))
    return division_decimals(division)


def _smallest_gap(values, at_least):
    """The smallest difference between neighbouring distinct ``values``; None for fewer than ``at_least``."""
    values = sorted(set(float(v) for v in values))
    return min(b - a for a, b in zip(values, values[1:])) if len(values) >= at_least else None


def division_decimals(division):
    """The decimal places that write ``division`` (> 0), see display_decimals."""
    division = float("%.9g" % division)   # 0.3 - 0.2 is 0.09999999999999998: a tenth
    first = max(0, -int(math.floor(math.log10(division))))   # places of its first significant digit
    for places in range(first, min(first + 1, MAX_DIGITS) + 1):
        scaled = division * 10 ** places
        if abs(scaled - round(scaled)) <= 1e-6 * max(1.0, scaled):
            return places
    return min(first + 1, MAX_DIGITS)
