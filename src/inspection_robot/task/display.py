"""A reading as an operator reads it: rounded to its meter's resolution, with its unit or meaning.

One function for every place that shows a value: the reports (HTML, the ``display`` column of
report.csv and report.json), query_results / review_queue rows and task_status's last_result, which
the console shows as they come. The raw ``value`` always stays beside it: ``display`` is text.

A reading's ``decimals`` are its target's resolution at the time it was read (from the calibration,
inspection.calibration_schema.display_decimals: ``digits``, or the smallest division of its scale),
kept in the reading row; rows stored before it have none and are shown with 4 significant digits.
Lamps and switches are state codes and are shown as words (``off``, ``lit red``; ``closed``,
``open``), foreign objects as a count.
"""
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
