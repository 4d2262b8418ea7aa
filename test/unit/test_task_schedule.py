"""Routines and schedules (task/schedule.py) on an injected clock in UTC, and their store tables."""
import datetime
import json
import sqlite3

import pytest

from inspection_robot.command import CommandError
from inspection_robot.task.schedule import (REASON_NOT_RUNNING, Scheduler, due_times, next_run, parse_routine,
                                            parse_schedule, run_id)
from inspection_robot.task.store import ResultStore

UTC = datetime.timezone.utc


def at(text):
    """Unix time of 'YYYY-MM-DD HH:MM' UTC."""
    return datetime.datetime.strptime(text, "%Y-%m-%d %H:%M").replace(tzinfo=UTC).timestamp()


def schedule(**fields):
    out = {"name": "s1", "routine": "r1", "time": "08:00", "weekdays": ["mon"]}
    out.update(fields)
    return json.dumps(out)


NOW = at("2026-11-27 12:00")   # a Friday


# --- next run -----------------------------------------------------------------------------------
def test_next_run_today_later_and_tomorrow_across_midnight():
    s = json.loads(schedule(time="23:59", weekdays=["fri", "sat"]))
    assert next_run(s, NOW, UTC) == at("2026-11-27 23:59")
    assert next_run(s, at("2026-11-27 23:59"), UTC) == at("2026-11-28 23:59")   # strictly after


def test_next_run_wraps_the_week():
    s = json.loads(schedule(time="00:00", weekdays=["thu"]))
    assert next_run(s, NOW, UTC) == at("2026-12-03 00:00")   # Sunday -> Monday -> ... Thursday, next month
    fri_morning = json.loads(schedule(time="07:00", weekdays=["fri"]))
    assert next_run(fri_morning, NOW, UTC) == at("2026-12-04 07:00")   # today's time passed: a week later


def test_due_times_in_a_window_and_the_one_off():
    daily = json.loads(schedule(weekdays=["mon", "tue", "wed", "thu", "fri", "sat", "sun"]))
    assert due_times(daily, at("2026-11-27 08:00"), at("2026-11-30 08:00"), UTC) == [
        at("2026-11-28 08:00"), at("2026-11-29 08:00"), at("2026-11-30 08:00")]
    once = {"name": "o", "routine": "r1", "time": "13:30", "date": "2026-11-27"}
    assert next_run(once, NOW, UTC) == at("2026-11-27 13:30")
    assert next_run(once, at("2026-11-27 13:30"), UTC) is None


def test_run_id_is_the_local_minute():
    assert run_id("yard", at("2026-11-27 08:05"), UTC) == "yard_20261127_0805"


# --- parsing ------------------------------------------------------------------------------------
def test_parse_schedule_normalises_weekdays():
    s = parse_schedule(schedule(weekdays=["sun", "mon", "mon"]), {"r1"}, NOW, UTC)
    assert s == {"name": "s1", "routine": "r1", "time": "08:00", "weekdays": ["mon", "sun"], "enabled": True}


@pytest.mark.parametrize("fields, reason", [
    ({"time": "8:00"}, "time must be HH:MM (00:00 to 23:59, robot local time), got '8:00'"),
    ({"time": "24:00"}, "time must be HH:MM (00:00 to 23:59, robot local time), got '24:00'"),
    ({"weekdays": []}, "weekdays must be a non-empty list of mon, tue, wed, thu, fri, sat, sun, got []"),
    ({"weekdays": ["monday"]}, "weekdays must be a non-empty list of mon, tue, wed, thu, fri, sat, sun, got "
                               "['monday']"),
    ({"weekdays": None, "date": "2026-02-30"}, "date must be a calendar date YYYY-MM-DD, got '2026-02-30'"),
    ({"date": "2026-12-01"}, "a schedule takes weekdays (a list of mon..sun) or date (YYYY-MM-DD), one of them"),
    ({"weekdays": None, "date": "2026-11-27", "time": "11:59"}, "schedule time 2026-11-27 11:59 is in the past"),
    ({"routine": "gone"}, "unknown routine 'gone'"),
    ({"name": "a b"}, "schedule name must be 1-64 characters of A-Z a-z 0-9 _ -, got 'a b'"),
    ({"enabled": "yes"}, "enabled must be true or false, got 'yes'"),
    ({"every": 2}, "schedule: unknown key(s) every (allowed: name, routine, time, weekdays, date, enabled)"),
])
def test_parse_schedule_refuses(fields, reason):
    obj = json.loads(schedule(**fields))
    for key in [k for k, v in obj.items() if v is None]:
        del obj[key]
    with pytest.raises(CommandError) as err:
        parse_schedule(json.dumps(obj), {"r1"}, NOW, UTC)
    assert str(err.value) == reason


def test_parse_schedule_not_json():
    with pytest.raises(CommandError, match="^schedule is not valid JSON"):
        parse_schedule("{", {"r1"}, NOW, UTC)


def test_parse_routine():
    task = {"order": "shortest", "stops": []}
    assert parse_routine(json.dumps({"name": "yard", "task": task})) == ("yard", task)
    for data, reason in (({"name": "x" * 51, "task": task}, "routine name must be 1-50 characters"),
                         ({"name": "yard", "task": dict(task, id="t")}, "routine task must not have an id"),
                         ({"name": "yard", "task": dict(task, priority="special")},
                          "routine task priority must be routine"),
                         ({"name": "yard", "task": dict(task, when=1)}, "routine task: unknown key(s) when"),
                         ({"name": "yard"}, "routine task must be a JSON object")):
        with pytest.raises(CommandError) as err:
            parse_routine(json.dumps(data))
        assert str(err.value).startswith(reason)


# --- the scheduler --------------------------------------------------------------------------------
@pytest.fixture
def store(tmp_path):
    store = ResultStore(str(tmp_path / "results.sqlite"))
    store.save_routine("r1", {"stops": []}, NOW - 3600)
    return store


def set_schedule(store, when, **fields):
    s = parse_schedule(schedule(**fields), {"r1"}, when, UTC)
    store.set_schedule(s, when)
    return s


def test_a_due_run_starts_once(store):
    set_schedule(store, NOW, time="12:01", weekdays=["fri"])
    scheduler = Scheduler(store, 600, NOW, UTC)
    assert scheduler.tick(NOW + 30, "") == ([], [])
    start, missed = scheduler.tick(NOW + 65, "")
    assert [r.task_id for r in start] == ["r1_20261127_1201"] and missed == []
    scheduler.started_run(start[0], NOW + 66)
    assert scheduler.tick(NOW + 75, "") == ([], [])
    row = store.schedules()[0]
    assert (row["last_at"], row["last_task_id"]) == (at("2026-11-27 12:01"), "r1_20261127_1201")


def test_a_run_waits_for_a_running_task_then_starts_or_is_missed(store):
    set_schedule(store, NOW, time="12:01", weekdays=["fri"])
    scheduler = Scheduler(store, 300, NOW, UTC)
    assert scheduler.tick(NOW + 70, "task 'x' was running") == ([], [])
    start, _ = scheduler.tick(NOW + 200, "")
    assert [r.task_id for r in start] == ["r1_20261127_1201"]
    # next week: busy all through the grace
    scheduler.tick(at("2026-12-04 12:01") + 5, "task 'y' was running")
    start, missed = scheduler.tick(at("2026-12-04 12:01") + 301, "task 'y' was running")
    assert start == [] and [(r.task_id, why) for r, why in missed] == [
        ("r1_20261204_1201", "task 'y' was running past the grace of 300 s")]
    assert store.missed_runs("s1") == [{"schedule": "s1", "at": at("2026-12-04 12:01"),
                                        "reason": "task 'y' was running past the grace of 300 s"}]
    assert store.get_meta("missed_runs") == 1


def test_runs_while_task_manager_was_down_are_missed_at_start_up(store):
    set_schedule(store, NOW, time="12:01", weekdays=["mon", "tue", "wed", "thu", "fri", "sat", "sun"])
    Scheduler(store, 600, NOW, UTC).tick(NOW + 10, "")   # the last check before a two-day stop
    later = at("2026-11-29 12:05")                          # restarted 4 min after Sunday's run
    scheduler = Scheduler(store, 600, later, UTC)
    start, missed = scheduler.tick(later + 1, "")
    assert [(r.task_id, why) for r, why in missed] == [("r1_20261127_1201", REASON_NOT_RUNNING),
                                                       ("r1_20261128_1201", REASON_NOT_RUNNING)]
    assert [r.task_id for r in start] == ["r1_20261129_1201"]   # within the grace: started late
    assert [m["at"] for m in store.missed_runs("s1")] == [at("2026-11-28 12:01"), at("2026-11-27 12:01")]


def test_a_year_offline_is_one_write_and_counted(store):
    set_schedule(store, NOW, time="12:01", weekdays=["mon", "tue", "wed", "thu", "fri", "sat", "sun"])
    Scheduler(store, 600, NOW, UTC).tick(NOW + 10, "")
    later = NOW + 365 * 86400
    _, missed = Scheduler(store, 600, later, UTC).tick(later + 1, "")
    assert len(missed) == 365 and store.get_meta("missed_runs") == 365
    assert len(store.missed_runs("s1", limit=100)) == 20


def test_a_waiting_run_survives_a_restart_as_missed(store):
    set_schedule(store, NOW, time="12:01", weekdays=["fri"])
    Scheduler(store, 120, NOW, UTC).tick(NOW + 65, "task 'x' was running")   # waits, then the node dies
    scheduler = Scheduler(store, 120, NOW + 3600, UTC)
    _, missed = scheduler.tick(NOW + 3601, "")
    assert [(r.task_id, why) for r, why in missed] == [("r1_20261127_1201", REASON_NOT_RUNNING)]


def test_first_start_misses_nothing_and_a_new_schedule_has_no_past(store):
    set_schedule(store, NOW - 86400 * 3, time="11:00", weekdays=["fri"])
    scheduler = Scheduler(store, 600, NOW, UTC)     # no check time stored: nothing was missed
    assert scheduler.tick(NOW + 10, "") == ([], [])
    set_schedule(store, NOW + 20, time="12:00", weekdays=["fri"])   # 12:00 today passed 20 s ago
    assert scheduler.tick(NOW + 30, "") == ([], [])


def test_disabled_or_deleted_schedules_do_not_run(store):
    set_schedule(store, NOW, time="12:01", weekdays=["fri"], enabled=False)
    scheduler = Scheduler(store, 600, NOW, UTC)
    assert scheduler.tick(NOW + 65, "") == ([], [])
    set_schedule(store, NOW + 66, time="12:02", weekdays=["fri"])
    scheduler.tick(NOW + 125, "task 'x' was running")
    assert store.delete_schedule("s1")
    scheduler.forget("s1")
    assert scheduler.tick(NOW + 130, "") == ([], [])


def test_a_run_found_busy_at_submission_waits_again(store):
    set_schedule(store, NOW, time="12:01", weekdays=["fri"])
    scheduler = Scheduler(store, 600, NOW, UTC)
    start, _ = scheduler.tick(NOW + 61, "")
    scheduler.busy_run(start[0])            # a task was submitted while the run was being checked
    assert scheduler.tick(NOW + 62, "task 'x' was running") == ([], [])
    assert scheduler.tick(NOW + 100, "")[0] == start


def test_no_schedules_no_store_writes(store):
    Scheduler(store, 600, NOW, UTC).tick(NOW + 10, "")
    assert store.schedule_checked() is None


def test_failed_run_is_missed_with_the_reason(store):
    set_schedule(store, NOW, time="12:01", weekdays=["fri"])
    scheduler = Scheduler(store, 600, NOW, UTC)
    start, _ = scheduler.tick(NOW + 61, "")
    scheduler.failed_run(start[0], "unknown preset directory 'p1': gone", NOW + 62)
    assert store.missed_runs() == [{"schedule": "s1", "at": start[0].at,
                                    "reason": "unknown preset directory 'p1': gone"}]


def test_missed_runs_are_bounded_per_schedule(store):
    store.add_missed_runs([("s1", NOW + k, "r%d" % k) for k in range(25)], NOW, 20)
    runs = store.missed_runs("s1", limit=100)
    assert len(runs) == 20 and runs[0]["reason"] == "r24"
    assert store.get_meta("missed_runs") == 25


# --- store migration --------------------------------------------------------------------------------
OLD_SCHEMA = """
CREATE TABLE tasks (task_id TEXT PRIMARY KEY, priority TEXT NOT NULL, spec TEXT NOT NULL, state TEXT NOT NULL,
    reason TEXT NOT NULL DEFAULT '', submitted REAL NOT NULL, ended REAL, seq INTEGER NOT NULL);
CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
INSERT INTO tasks VALUES ('old', 'routine', '{}', 'done', '', 1.0, 2.0, 1);
INSERT INTO meta VALUES ('holds', '["operator"]');
"""


def test_a_store_without_schedule_tables_opens_and_keeps_its_rows(tmp_path):
    path = str(tmp_path / "old.sqlite")
    db = sqlite3.connect(path)
    db.executescript(OLD_SCHEMA)
    db.close()
    store = ResultStore(path)
    assert store.task_ids() == {"old"} and store.get_meta("holds") == ["operator"]
    assert store.routines() == [] and store.schedules() == [] and store.schedule_checked() is None
    store.save_routine("r1", {"stops": []}, 5.0)
    store.set_schedule({"name": "s1", "routine": "r1", "time": "08:00", "weekdays": ["mon"], "enabled": True}, 6.0)
    store.close()
    again = ResultStore(path)   # survives a restart
    assert again.routine("r1") == {"name": "r1", "task": {"stops": []}, "saved": 5.0}
    assert [s["name"] for s in again.schedules()] == ["s1"]


def test_replacing_a_schedule_keeps_its_history(store):
    set_schedule(store, NOW, time="12:01", weekdays=["fri"])
    store.set_schedule_run("s1", NOW + 60, "r1_20261127_1201")
    store.add_missed_runs([("s1", NOW, "x")], NOW, 20)
    set_schedule(store, NOW + 100, time="13:00", weekdays=["fri"])
    row = store.schedules()[0]
    assert (row["time"], row["last_task_id"], row["set_at"]) == ("13:00", "r1_20261127_1201", NOW + 100)
    assert len(store.missed_runs("s1")) == 1
    assert not store.delete_routine("nothing")


def test_local_zone_gives_the_offset_schedules_run_in():
    import datetime
    from inspection_robot.task.schedule import local_zone
    china = datetime.timezone(datetime.timedelta(hours=8), "CST")
    assert local_zone(1795680000.0, china) == {"name": "CST", "utc_offset_s": 28800}
    own = local_zone(1795680000.0)   # the machine's zone: whatever it is, named with an offset
    assert isinstance(own["name"], str) and own["utc_offset_s"] % 60 == 0
