"""Named routines and their schedules: when a routine patrol is due, and which runs were missed.

A routine is a task without an id, saved under a name; a schedule runs one routine at a local time
of day ("HH:MM", the robot's local time zone, no DST handling beyond what the zone's rules give) on
some weekdays, or once on a date. Each run is submitted as a routine-priority task with the id
``<routine>_<YYYYMMDD_HHMM>`` (local time of the run).

A run that cannot start is missed, never skipped in silence: task_manager was not running at the
time (found at start-up from the last check time kept in the store), a task was running for longer
than the grace period, or the routine failed its submission checks. The Scheduler is pure logic on
an injected clock: the node calls ``tick(now, busy)`` on a timer and submits what it answers.
The time zone is passed in (None: the machine's local zone), so tests run in UTC.
"""
import datetime
import re
from collections import namedtuple

from inspection_robot.command import CommandError, parse_json
from inspection_robot.task.spec import PRIORITY_ROUTINE, TASK_ID_PATTERN, TASK_KEYS, json_object, short_value

WEEKDAYS = ("mon", "tue", "wed", "thu", "fri", "sat", "sun")   # datetime.weekday() order
SCHEDULE_KEYS = ("name", "routine", "time", "weekdays", "date", "enabled")
ROUTINE_KEYS = ("name", "task")
ROUTINE_TASK_KEYS = tuple(k for k in TASK_KEYS if k != "id")
# a run's task id is <routine>_<YYYYMMDD_HHMM>: 14 characters more, within a task id's 64
RUN_SUFFIX = "_%Y%m%d_%H%M"
ROUTINE_NAME_PATTERN = re.compile(r"[A-Za-z0-9_-]{1,50}")
TIME_PATTERN = re.compile(r"([01][0-9]|2[0-3]):([0-5][0-9])")
DATE_PATTERN = re.compile(r"[0-9]{4}-[0-9]{2}-[0-9]{2}")
MISSED_KEPT = 20            # missed runs kept (and listed) per schedule, newest first
MAX_CATCH_UP = 5000         # due times looked at per schedule and tick (ten years offline, daily: 3650)
REASON_NOT_RUNNING = "task_manager was not running"

# one due run: its schedule and routine names, its time (unix s) and its task id
Run = namedtuple("Run", "schedule routine at task_id")


def local_zone(now, tz=None):
    """The time zone schedules run in at ``now`` (``tz`` None: the robot's own): {"name": "CST",
    "utc_offset_s": 28800}, so a backend can turn a schedule's HH:MM into a moment."""
    moment = datetime.datetime.fromtimestamp(now, tz)
    moment = moment if moment.tzinfo is not None else moment.astimezone()
    return {"name": moment.tzname() or "", "utc_offset_s": int(moment.utcoffset().total_seconds())}


def check_routine_name(name):
    """``name`` if it is 1-50 characters of A-Z a-z 0-9 _ - (the run's id adds 14), else CommandError."""
    if not isinstance(name, str) or not ROUTINE_NAME_PATTERN.fullmatch(name):
        raise CommandError("routine name must be 1-50 characters of A-Z a-z 0-9 _ -, got %s" % short_value(name))
    return name


def check_schedule_name(name):
    if not isinstance(name, str) or not TASK_ID_PATTERN.fullmatch(name):
        raise CommandError("schedule name must be 1-64 characters of A-Z a-z 0-9 _ -, got %s" % short_value(name))
    return name


def parse_routine(data):
    """routine_save's JSON -> (name, task dict without id). The task's own checks (presets,
    reachability) are the caller's: spec.parse_task with ``routine_task(...)``."""
    obj = json_object(parse_json(data, "routine"), "routine", ROUTINE_KEYS)
    name = check_routine_name(obj.get("name"))
    task = obj.get("task")
    if not isinstance(task, dict):
        raise CommandError("routine task must be a JSON object (a task without id), got %s" % short_value(task))
    if "id" in task:
        raise CommandError("routine task must not have an id (each run gets <routine>_<YYYYMMDD_HHMM>)")
    json_object(task, "routine task", ROUTINE_TASK_KEYS)
    if task.get("priority", PRIORITY_ROUTINE) != PRIORITY_ROUTINE:
        raise CommandError("routine task priority must be routine (scheduled runs are routine tasks), got %s"
                           % short_value(task.get("priority")))
    return name, task


def routine_task(task, task_id):
    """The task dict of one run (what submit gets): the routine's task with its id."""
    out = dict(task)
    out["id"] = task_id
    return out


def run_id(routine, at, tz=None):
    """``<routine>_<YYYYMMDD_HHMM>`` of a run at unix time ``at`` (local time of ``tz``)."""
    return routine + datetime.datetime.fromtimestamp(at, tz).strftime(RUN_SUFFIX)


def parse_schedule(data, routines, now, tz=None):
    """schedule_set's JSON -> the stored schedule dict {"name", "routine", "time", "weekdays" or
    "date", "enabled"}; ``routines``: the names saved. A one-off in the past is refused."""
    obj = json_object(parse_json(data, "schedule"), "schedule", SCHEDULE_KEYS)
    out = {"name": check_schedule_name(obj.get("name"))}
    routine = obj.get("routine")
    if not isinstance(routine, str) or routine not in routines:
        raise CommandError("unknown routine %s" % (("'%s'" % routine[:64]) if isinstance(routine, str)
                                                   else short_value(routine)))
    out["routine"] = routine
    out["time"] = _parse_time(obj.get("time"))
    if ("weekdays" in obj) == ("date" in obj):
        raise CommandError("a schedule takes weekdays (a list of mon..sun) or date (YYYY-MM-DD), one of them")
    if "weekdays" in obj:
        days = obj["weekdays"]
        if not isinstance(days, list) or not days or any(d not in WEEKDAYS for d in days):
            raise CommandError("weekdays must be a non-empty list of %s, got %s"
                               % (", ".join(WEEKDAYS), short_value(days)))
        out["weekdays"] = [d for d in WEEKDAYS if d in days]
    else:
        out["date"] = _parse_date(obj["date"]).isoformat()
    enabled = obj.get("enabled", True)
    if not isinstance(enabled, bool):
        raise CommandError("enabled must be true or false, got %s" % short_value(enabled))
    out["enabled"] = enabled
    if "date" in out and next_run(out, now, tz) is None:
        raise CommandError("schedule time %s %s is in the past" % (out["date"], out["time"]))
    return out


def _parse_time(value):
    match = TIME_PATTERN.fullmatch(value) if isinstance(value, str) else None
    if match is None:
        raise CommandError("time must be HH:MM (00:00 to 23:59, robot local time), got %s" % short_value(value))
    return value


def _parse_date(value):
    try:
        if not isinstance(value, str) or not DATE_PATTERN.fullmatch(value):
            raise ValueError
        return datetime.date(int(value[:4]), int(value[5:7]), int(value[8:]))
    except ValueError:
        raise CommandError("date must be a calendar date YYYY-MM-DD, got %s" % short_value(value))


def _at(day, hhmm, tz):
    """Unix time of local ``hhmm`` on ``day`` in ``tz`` (None: the machine's zone)."""
    dt = datetime.datetime(day.year, day.month, day.day, int(hhmm[:2]), int(hhmm[3:]), tzinfo=tz)
    return dt.timestamp()


def next_run(schedule, after, tz=None):
    """The schedule's first run strictly after unix time ``after``, or None (a one-off that passed).
    ``enabled`` is not looked at (the caller's)."""
    if "date" in schedule:
        at = _at(_parse_date(schedule["date"]), schedule["time"], tz)
        return at if at > after else None
    days = set(WEEKDAYS.index(d) for d in schedule["weekdays"])
    day = datetime.datetime.fromtimestamp(after, tz).date()
    for offset in range(8):   # today's time may have passed: a week later at most
        candidate = day + datetime.timedelta(days=offset)
        if candidate.weekday() in days:
            at = _at(candidate, schedule["time"], tz)
            if at > after:
                return at
    raise AssertionError("no weekday in 8 days")   # unreachable: weekdays is non-empty


def due_times(schedule, since, until, tz=None, limit=MAX_CATCH_UP):
    """The schedule's runs in (since, until], oldest first, at most the newest ``limit``."""
    out = []
    at = next_run(schedule, since, tz)
    while at is not None and at <= until:
        out.append(at)
        at = next_run(schedule, at, tz)
    return out[-limit:]


class Scheduler(object):
    """Which runs are due, which wait for a running task, which are missed.

    ``store``: the results store (schedules, routines, the last check time and missed runs).
    ``grace_s``: how long a due run waits while another task runs (or task_manager starts late)
    before it is missed. The last check time is stored at every tick (while there are schedules),
    held back to the oldest run still waiting, so a run waiting when task_manager dies is found
    again (and missed) at start-up.
    """

    def __init__(self, store, grace_s, now, tz=None):
        self.store = store
        self.grace_s = grace_s
        self.tz = tz
        self.started = now
        checked = store.schedule_checked()
        self._scanned = now if checked is None else min(checked, now)   # first start: nothing was missed
        self._waiting = {}   # (schedule, at) -> (Run, why it waits)

    def tick(self, now, busy):
        """``busy``: "" or why no task can start now (e.g. ``task 'x' was running``). Returns the Runs to
        submit now (the caller reports each with ``started_run``, ``busy_run`` or ``failed_run``) and
        the runs past their grace [(Run, reason)], already recorded as missed."""
        schedules = dict((s["name"], s) for s in self.store.schedules())
        for key in list(self._waiting):
            schedule = schedules.get(key[0])
            if schedule is None or not schedule["enabled"]:
                del self._waiting[key]      # deleted or disabled meanwhile: nothing to run
        for schedule in schedules.values():
            if not schedule["enabled"]:
                continue
            since = max(self._scanned, schedule["set_at"])
            for at in due_times(schedule, since, now, self.tz):
                run = Run(schedule["name"], schedule["routine"], at, run_id(schedule["routine"], at, self.tz))
                self._waiting.setdefault((run.schedule, at), (run, REASON_NOT_RUNNING if at < self.started else ""))
        self._scanned = max(self._scanned, now)
        start, missed = [], []
        for key in sorted(self._waiting, key=lambda k: k[1]):
            run, why = self._waiting[key]
            if now - run.at > self.grace_s:
                del self._waiting[key]
                if why and why != REASON_NOT_RUNNING:
                    why = "%s past the grace of %.0f s" % (why, self.grace_s)
                missed.append((run, why or "not started within the grace of %.0f s" % self.grace_s))
            elif busy:
                self._waiting[key] = (run, busy)
            elif not start:   # one per tick: the next one waits for it like for any task
                del self._waiting[key]
                start.append(run)
        self.store.add_missed_runs([(run.schedule, run.at, reason) for run, reason in missed], now, MISSED_KEPT)
        if schedules or self._waiting:   # nothing to miss without schedules: no write every tick
            oldest = min([k[1] for k in self._waiting] or [now])
            self.store.set_schedule_checked(min(now, oldest - 1e-3))
        return start, missed

    def busy_run(self, run):
        """The run's submission found the robot busy after all (a task started meanwhile): it waits
        again, within its grace (the next tick says what it waits for)."""
        self._waiting.setdefault((run.schedule, run.at), (run, ""))

    def started_run(self, run, now):
        self.store.set_schedule_run(run.schedule, run.at, run.task_id)

    def failed_run(self, run, reason, now):
        """The run's task was refused (a check failed): it is missed with that reason."""
        self.store.add_missed_runs([(run.schedule, run.at, reason)], now, MISSED_KEPT)

    def forget(self, name):
        """A schedule was replaced or deleted: its waiting runs are not run."""
        for key in [k for k in self._waiting if k[0] == name]:
            del self._waiting[key]

    def waiting(self):
        return [run for run, _why in self._waiting.values()]
