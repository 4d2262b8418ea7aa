"""Alarms an operator sees and acknowledges, without ROS.

An open alarm is a reading whose stated alarm (the reviewed value's once reviewed, as the report
states it) is ``alarm``, ``check`` or ``warning`` (outside the normal band, inside the alarm band)
and that nobody acknowledged yet. Acknowledging records who, when and an optional note on the
reading itself (the store's ``ack_*`` columns), once: the report and every later query show it.
``alarms`` lists open alarms newest first (or the acknowledged ones); ``acknowledge`` settles one.
A trend warning, a failed reading or a normal one is not an alarm to acknowledge: refused with its
state named.
"""
from inspection_robot.command import CommandError, parse_json
from inspection_robot.task.review import parse_query, person
from inspection_robot.task.states import ALARM_ALARM, ALARM_CHECK, ALARM_WARNING
from inspection_robot.task.store import StoreError

ALARM_STATES = (ALARM_ALARM, ALARM_CHECK, ALARM_WARNING)   # what an operator acknowledges
ALARMS_KEYS = ("task_id", "limit", "acknowledged")
ACK_KEYS = ("id", "by", "note")
MAX_NOTE_CHARS = 500


def parse_alarms_query(data):
    """(task_id or None, acknowledged, limit) of an ``alarms`` command; "" lists every open alarm."""
    query = parse_query(data, ALARMS_KEYS, 100)
    acknowledged = query.get("acknowledged", False)
    if not isinstance(acknowledged, bool):
        raise CommandError("acknowledged must be true or false")
    return query.get("task_id"), acknowledged, query["limit"]


def parse_acknowledge(data):
    """(row id, who, note) of an ``acknowledge`` command."""
    request = parse_json(data, "acknowledge")
    if not isinstance(request, dict) or not {"id", "by"} <= set(request) or set(request) - set(ACK_KEYS):
        raise CommandError("acknowledge must be a JSON object with keys id, by and optionally note")
    row_id, by, note = request["id"], request["by"], request.get("note", "")
    if isinstance(row_id, bool) or not isinstance(row_id, int) or row_id < 1:
        raise CommandError("id must be a reading's id (a positive integer)")
    by = person(by, "operator")
    if not isinstance(note, str) or len(note) > MAX_NOTE_CHARS or not note.replace("\n", " ").isprintable():
        raise CommandError("note must be text of at most %d printable characters" % MAX_NOTE_CHARS)
    return row_id, by, note.strip()


def stated_alarm(row):
    """A row's alarm as the report states it: the reviewed value's once reviewed."""
    if row.get("review_time") is not None and row.get("review_alarm"):
        return row["review_alarm"]
    return row["alarm"]


def acknowledge(store, data, now):
    """Acknowledge one open alarm (the ``acknowledge`` command); returns the row after it.
    CommandError (nothing written) for a bad request, an unknown row, a row that is not an alarm or
    one already acknowledged."""
    row_id, by, note = parse_acknowledge(data)
    row = store.reading(row_id)
    if row is None:
        raise CommandError("no reading with id %d" % row_id)
    state = stated_alarm(row)
    if state not in ALARM_STATES:
        raise CommandError("reading %d is not an alarm to acknowledge (alarm %s)" % (row_id, state))
    if row["ack_time"] is not None or not store.acknowledge(row_id, by, note, now):
        row = store.reading(row_id)
        raise CommandError("reading %d was already acknowledged by %s" % (row_id, row["ack_by"]))
    return store.reading(row_id)


class OpenAlarms(object):
    """The count of open alarms for task_status, asked of the store again after this process
    committed, or ``max_age_s`` after the last count (another process may write the store: a
    backup restored, a tool); a store that cannot answer keeps the last count, so the status is
    published all the same. ``monotonic``: the clock of the max age."""

    def __init__(self, store, monotonic, max_age_s=10.0):
        self._store = store
        self._monotonic = monotonic
        self._max_age_s = max_age_s
        self._seen = None
        self._counted_at = None
        self._count = 0

    def count(self):
        now = self._monotonic()
        if self._seen != self._store.commits or now - self._counted_at > self._max_age_s:
            try:
                self._count = self._store.alarm_count(ALARM_STATES)
                self._seen, self._counted_at = self._store.commits, now
            except StoreError:
                pass
        return self._count
