"""task.alarms: open alarms listed newest first, acknowledged once with who, when and a note, the
count task_status carries, and the report's line; every bad request refused with nothing written."""
import json

import pytest

from inspection_robot.command import CommandError
from inspection_robot.task.alarms import ALARM_STATES, OpenAlarms, acknowledge, parse_alarms_query
from inspection_robot.task.client_view import client_row
from inspection_robot.task.patrol import Inspection
from inspection_robot.task.report import render_html, summary
from inspection_robot.task.review import review
from inspection_robot.task.rows import reading_rows
from inspection_robot.task.store import ResultStore

PRESET = {"preset": "p", "directory": "/d/presets/p/1", "foreign": False,
          "targets": [{"name": "oil", "kind": "pointer", "unit": "C", "decimals": 1},
                      {"name": "sf6", "kind": "pointer", "unit": "MPa", "decimals": 2},
                      {"name": "amps", "kind": "pointer", "unit": "A", "decimals": 0}],
          "alarms": {"oil": [0.0, 85.0], "sf6": [0.4, 0.8], "amps": [0.0, 500.0]}}


@pytest.fixture
def store(tmp_path):
    s = ResultStore(str(tmp_path / "r.sqlite"))
    # task t1: oil out of band (alarm), sf6 uncertain and out of band (check), amps normal
    s.add_readings(reading_rows("t1", 0, "s1", 0, PRESET, Inspection([118.0, 0.97, 320.0], [90.0, 40.0, 90.0],
                                                                     ["", "", ""], (0.0, 0.0, 0.0), None,
                                                                     ["", "glare", ""]), "", 100.0))
    s.add_readings(reading_rows("t2", 0, "s1", 0, PRESET, Inspection([90.0, 0.5, 320.0], [90.0] * 3, ["", "", ""],
                                                                     (0.0, 0.0, 0.0)), "", 200.0))
    yield s
    s.close()


def ids(rows):
    return [(r["task_id"], r["target_name"]) for r in rows]


def test_open_alarms_newest_first_and_acknowledged_once(store):
    assert ids(store.alarm_rows(ALARM_STATES)) == [("t2", "oil"), ("t1", "sf6"), ("t1", "oil")]
    clock = [0.0]
    open_alarms = OpenAlarms(store, lambda: clock[0])
    assert open_alarms.count() == 3
    oil = store.alarm_rows(ALARM_STATES, task_id="t1")[1]
    row = acknowledge(store, json.dumps({"id": oil["id"], "by": " li ", "note": "sensor checked, oil is hot"}), 300.0)
    assert (row["ack_by"], row["ack_time"], row["ack_note"]) == ("li", 300.0, "sensor checked, oil is hot")
    assert open_alarms.count() == 2 and ids(store.alarm_rows(ALARM_STATES, acknowledged=True)) == [("t1", "oil")]
    with pytest.raises(CommandError) as err:
        acknowledge(store, json.dumps({"id": oil["id"], "by": "wang"}), 301.0)
    assert str(err.value) == "reading %d was already acknowledged by li" % oil["id"]
    assert store.reading(oil["id"])["ack_by"] == "li"


def test_a_check_corrected_into_its_band_is_no_longer_an_alarm(store, tmp_path):
    sf6 = [r for r in store.alarm_rows(ALARM_STATES) if r["target_name"] == "sf6"][0]
    review(store, str(tmp_path / "corrections"), json.dumps({"id": sf6["id"], "value": 0.62, "by": "li"}), 250.0)
    assert ids(store.alarm_rows(ALARM_STATES)) == [("t2", "oil"), ("t1", "oil")]
    with pytest.raises(CommandError) as err:
        acknowledge(store, json.dumps({"id": sf6["id"], "by": "li"}), 260.0)
    assert "reading %d is not an alarm to acknowledge (alarm normal)" % sf6["id"] in str(err.value)


@pytest.mark.parametrize("data,reason", [
    ("", "acknowledge is not valid JSON"),
    ("{bad", "acknowledge is not valid JSON"),
    ("[]", "acknowledge must be a JSON object with keys id, by and optionally note"),
    ('{"id": 1}', "keys id, by and optionally note"),
    ('{"id": 1, "by": "li", "when": 5}', "keys id, by and optionally note"),
    ('{"id": true, "by": "li"}', "id must be a reading's id"),
    ('{"id": 0, "by": "li"}', "id must be a reading's id"),
    ('{"id": 1, "by": "  "}', "by must be the operator's name"),
    ('{"id": 1, "by": "li\\u0000"}', "by must be the operator's name"),
    ('{"id": 1, "by": "li", "note": 5}', "note must be text of at most 500"),
    ('{"id": 1, "by": "li", "note": "%s"}' % ("x" * 501), "note must be text of at most 500"),
    ('{"id": 999, "by": "li"}', "no reading with id 999"),
])
def test_bad_acknowledgements_are_refused_and_write_nothing(store, data, reason):
    before = store.commits
    with pytest.raises(CommandError) as err:
        acknowledge(store, data, 300.0)
    assert reason in str(err.value)
    assert store.commits == before


def test_a_normal_reading_is_not_an_alarm(store):
    amps = [r for r in store.readings(task_id="t1") if r["target_name"] == "amps"][0]
    with pytest.raises(CommandError) as err:
        acknowledge(store, json.dumps({"id": amps["id"], "by": "li"}), 300.0)
    assert "(alarm normal)" in str(err.value)


def test_the_alarms_query_rules():
    assert parse_alarms_query("") == (None, False, 100)
    assert parse_alarms_query('{"task_id": "t1", "acknowledged": true, "limit": 5}') == ("t1", True, 5)
    for data, reason in [('{"acknowledged": 1}', "acknowledged must be true or false"),
                         ('{"target": "oil"}', "query must be a JSON object with keys task_id, limit, acknowledged"),
                         ('{"limit": 0}', "limit must be an integer")]:
        with pytest.raises(CommandError) as err:
            parse_alarms_query(data)
        assert reason in str(err.value)


def test_the_report_names_who_acknowledged_an_alarm(store):
    oil = [r for r in store.alarm_rows(ALARM_STATES, task_id="t1") if r["target_name"] == "oil"][0]
    acknowledge(store, json.dumps({"id": oil["id"], "by": "li", "note": "<fan off>"}), 300.0)
    rows = store.readings(task_id="t1")
    task = {"task_id": "t1", "priority": "routine", "state": "done", "reason": "", "submitted": 10.0, "ended": 130.0,
            "spec": {"stops": [{"name": "s1", "x": 0.0, "y": 0.0}], "planned_length_m": 1.0}}
    page = render_html(summary(task, rows, []), [dict(client_row(r, "/d"), link="", history=[]) for r in rows], "",
                       task["spec"]["stops"])
    assert '<div class="ack">acknowledged by li, ' in page and ": &lt;fan off&gt;</div>" in page
    assert page.count('class="ack"') == 1


def test_the_count_follows_another_process_within_its_max_age(store, tmp_path):
    clock = [0.0]
    open_alarms = OpenAlarms(store, lambda: clock[0], max_age_s=10.0)
    assert open_alarms.count() == 3
    other = ResultStore(store.path)   # another process: its commits do not tick this store's counter
    oil = store.alarm_rows(ALARM_STATES)[0]
    assert other.acknowledge(oil["id"], "li", "", 5.0)
    other.close()
    clock[0] = 9.0
    assert open_alarms.count() == 3
    clock[0] = 10.5
    assert open_alarms.count() == 2


def test_a_warning_between_the_bands_is_stored_listed_and_acknowledged(tmp_path):
    s = ResultStore(str(tmp_path / "w.sqlite"))
    preset = dict(PRESET, alarms={"oil": {"normal": [0.0, 85.0], "alarm": [-10.0, 95.0]}, "sf6": [0.4, 0.8]})
    s.add_readings(reading_rows("t3", 0, "s1", 0, preset, Inspection([90.0, 0.5, 320.0], [90.0] * 3, ["", "", ""],
                                                                     (0.0, 0.0, 0.0)), "", 100.0))
    oil, sf6, amps = s.readings(task_id="t3")
    assert (oil["alarm"], oil["low"], oil["high"], oil["alarm_low"], oil["alarm_high"]) == (
        "warning", 0.0, 85.0, -10.0, 95.0)
    assert (sf6["alarm"], sf6["alarm_low"], amps["alarm"], amps["low"]) == ("normal", None, "none", None)
    assert ids(s.alarm_rows(ALARM_STATES)) == [("t3", "oil")]
    acknowledge(s, json.dumps({"id": oil["id"], "by": "li"}), 120.0)
    assert s.alarm_rows(ALARM_STATES) == []
    s.close()
