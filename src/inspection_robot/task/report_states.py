"""A reading's state in the patrol report and the console's words for it: its alarm (the reviewed
value's once reviewed), a failure, an uncertain value nobody reviewed yet, a trend warning; the order
from the most urgent, the colours and the words. The report's page, its map and its summary read it.
"""
from inspection_robot.task.alarms import stated_alarm
from inspection_robot.task.states import (ALARM_ALARM, ALARM_CHECK, ALARM_FAILED, ALARM_NONE, ALARM_NORMAL,
                                          ALARM_TREND, ALARM_WARNING, STATUS_FAILED, STATUS_UNCERTAIN)

# a reading's state in the report, the most urgent first: its alarm, a failure, an uncertain value
# nobody reviewed yet (review), a trend warning; a stop is coloured by its worst reading
STATE_REVIEW = "review"
STATE_NOT_READ = "not read"
STATE_ORDER = (ALARM_ALARM, ALARM_CHECK, ALARM_WARNING, ALARM_FAILED, STATE_REVIEW, ALARM_TREND, ALARM_NORMAL,
               ALARM_NONE)
STATE_RANK = dict((state, i) for i, state in enumerate(STATE_ORDER))
ATTENTION_STATES = (ALARM_ALARM, ALARM_CHECK, ALARM_WARNING, ALARM_FAILED, STATE_REVIEW, ALARM_TREND)
STATE_COLOURS = {ALARM_ALARM: "#c62828", ALARM_CHECK: "#ef6c00", ALARM_WARNING: "#b8860b", ALARM_FAILED: "#616161",
                 STATE_REVIEW: "#6a1b9a", ALARM_TREND: "#f9a825", ALARM_NORMAL: "#2e7d32", ALARM_NONE: "#1565c0",
                 STATE_NOT_READ: "#bdbdbd"}
# a state in the operator's words where its code does not say it (the others read as their code)
STATE_WORDS = {STATE_REVIEW: "needs review", ALARM_NONE: "no limits", STATE_NOT_READ: "not read"}


def needs_review(row):
    """An uncertain value nobody has confirmed or corrected yet."""
    return row["status"] == STATUS_UNCERTAIN and row.get("review_time") is None


def reading_state(row):
    """The report's state of a reading (STATE_ORDER): the reviewed value's alarm once reviewed."""
    if row["status"] == STATUS_FAILED:
        return ALARM_FAILED
    if needs_review(row):
        return ALARM_CHECK if row["alarm"] == ALARM_CHECK else STATE_REVIEW
    return stated_alarm(row)


def worst_state(rows):
    """The most urgent state of ``rows``; STATE_NOT_READ when there are none."""
    states = [reading_state(r) for r in rows]
    return min(states, key=lambda s: STATE_RANK.get(s, len(STATE_ORDER))) if states else STATE_NOT_READ
