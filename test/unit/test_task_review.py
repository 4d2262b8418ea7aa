"""Uncertain readings through the patrol (retries, status, check alarms), the store (an old file
migrated, the review queue), the report (needs review first) and the review command (store and
correction file, every refusal writing nothing)."""
import json
import os
import sqlite3

import pytest

from inspection_robot.command import CommandError
from inspection_robot.inspection.reading import result_text, ReadOutcome, uncertain_reasons
from inspection_robot.task.patrol import OUTCOME_FAILED, OUTCOME_OK, STEP_INSPECT, Inspection, Patrol
from inspection_robot.task.report import picture_link, render_html, summary, write_reports
from inspection_robot.task.client_view import client_row
from inspection_robot.task.review import parse_query, review
from inspection_robot.task.store import ResultStore
from inspection_robot_testing.clock import FakeClock
from test_task_patrol import CONFIG, run_step, task

REASON = "two pointers 37 deg apart (set pointer_colour / ignore_colour in the calibration)"

# the readings table as the first release created it (no source, no review columns)
OLD_SCHEMA = """
CREATE TABLE tasks (
    task_id TEXT PRIMARY KEY, priority TEXT NOT NULL, spec TEXT NOT NULL, state TEXT NOT NULL,
    reason TEXT NOT NULL DEFAULT '', submitted REAL NOT NULL, ended REAL, seq INTEGER NOT NULL);
CREATE TABLE readings (
    id INTEGER PRIMARY KEY AUTOINCREMENT, task_id TEXT NOT NULL, stop INTEGER NOT NULL,
    stop_name TEXT NOT NULL, preset_index INTEGER NOT NULL, preset TEXT NOT NULL, target INTEGER NOT NULL,
    target_name TEXT NOT NULL, kind TEXT NOT NULL, status TEXT NOT NULL, value REAL, unit TEXT NOT NULL,
    alarm TEXT NOT NULL, low REAL, high REAL, confidence REAL, picture TEXT NOT NULL,
    x REAL, y REAL, yaw REAL, time REAL NOT NULL, reason TEXT NOT NULL,
    UNIQUE (task_id, stop, preset_index, target));
CREATE INDEX readings_time ON readings (time);
INSERT INTO readings (task_id, stop, stop_name, preset_index, preset, target, target_name, kind, status, value,
    unit, alarm, low, high, confidence, picture, x, y, yaw, time, reason)
    VALUES ('old', 0, 's', 0, '/p', 0, 'g', 'pointer', 'read', 0.5, 'MPa', 'normal', 0, 1, 90, '/a.jpg',
            1, 2, 0, 100, '');
"""


@pytest.fixture
def env(tmp_path):
    store = ResultStore(str(tmp_path / "results.sqlite"))
    clock = FakeClock(1000.0)
    patrol = Patrol(store, CONFIG, clock())
    patrol.set_mode(0)
    return store, clock, patrol


def inspect(patrol, clock, value, reason, outcome=OUTCOME_OK):
    """Run the next step, an inspection of p_gauge (target g, band [0.2, 0.8]) or p_lamp."""
    step = patrol.next_step(clock())
    assert step is not None and step.kind == STEP_INSPECT
    started = clock()
    clock.now += 2.0
    n = len(step.preset["targets"])
    detail = Inspection([value] * n, [30.0] * n, ["/pic/read_%d.jpg" % k for k in range(n)], (1.0, 2.0, 0.0), None,
                        [reason] + [""] * (n - 1), [{"picture": "/cap/zoom0.jpg", "roi": [1, 2, 3, 4, 5, 6, 7, 8]}] * n
                        ) if outcome == OUTCOME_OK else "find_scale: no match"
    patrol.step_done(step, outcome, detail, started, clock())
    return step


def settle_retry(clock):
    clock.now += CONFIG.retry_delay_s


def test_an_uncertain_reading_is_tried_again_then_kept_with_its_reason_and_a_check_alarm(env):
    store, clock, patrol = env
    patrol.submit(task("t1", stops=1), clock())
    run_step(patrol, clock)                                   # drive
    inspect(patrol, clock, 0.95, REASON)                       # uncertain: tried again
    assert store.readings(task_id="t1") == []
    assert patrol.next_step(clock()) is None                   # retry_delay_s apart
    settle_retry(clock)
    inspect(patrol, clock, 0.97, REASON)                       # uncertain again: kept (uncertain_retries 1)
    (row,) = store.readings(task_id="t1")
    assert (row["status"], row["value"], row["confidence"], row["reason"]) == ("uncertain", 0.97, 30.0, REASON)
    assert (row["alarm"], row["picture"]) == ("check", "/pic/read_0.jpg")   # outside [0.2, 0.8]: never silence
    assert (row["source_picture"], row["roi"]) == ("/cap/zoom0.jpg", "1.0,2.0,3.0,4.0,5.0,6.0,7.0,8.0")
    last = patrol.status()["last_result"]
    assert (last["uncertain"], last["alarms"], last["readings"][0]["reason"]) == (1, 1, REASON)
    assert [r["id"] for r in store.review_queue()] == [row["id"]]


def test_a_confident_retry_is_read_and_an_uncertain_one_within_band_raises_no_alarm(env):
    store, clock, patrol = env
    patrol.submit(task("t1", stops=1), clock())
    run_step(patrol, clock)
    inspect(patrol, clock, 0.95, REASON)
    settle_retry(clock)
    inspect(patrol, clock, 0.5, "")                            # the second look is confident
    (row,) = store.readings(task_id="t1")
    assert (row["status"], row["alarm"], row["value"], row["reason"]) == ("read", "normal", 0.5, "")
    inspect(patrol, clock, 0.5, "glare over 30 % of the dial")  # p_lamp: lamp uncertain, within no band
    settle_retry(clock)
    inspect(patrol, clock, 0.5, "glare over 30 % of the dial")
    rows = store.readings(task_id="t1")
    assert [(r["status"], r["alarm"]) for r in rows] == [("read", "normal"), ("uncertain", "none"), ("read", "none")]
    assert store.task("t1")["state"] == "done"                # uncertain is not failed


def test_uncertain_values_outlive_a_failed_retry_and_zero_retries_keep_them_at_once(env, tmp_path):
    store, clock, patrol = env
    patrol.submit(task("t1", stops=1, retries=0), clock())
    run_step(patrol, clock)
    inspect(patrol, clock, 0.6, REASON)
    settle_retry(clock)
    inspect(patrol, clock, None, "", OUTCOME_FAILED)           # the retry fails: the doubted value stays
    (row,) = store.readings(task_id="t1")
    assert (row["status"], row["value"], row["alarm"], row["reason"]) == ("uncertain", 0.6, "normal", REASON)
    store2 = ResultStore(str(tmp_path / "other.sqlite"))
    patrol2 = Patrol(store2, CONFIG._replace(uncertain_retries=0), clock())
    patrol2.set_mode(0)
    patrol2.submit(task("t2", stops=1), clock())
    run_step(patrol2, clock)
    inspect(patrol2, clock, 0.1, REASON)
    assert [(r["status"], r["alarm"]) for r in store2.readings(task_id="t2")] == [("uncertain", "check")]


def test_an_old_store_opens_with_the_new_columns_and_its_rows_intact(tmp_path):
    path = str(tmp_path / "old.sqlite")
    db = sqlite3.connect(path)
    db.executescript(OLD_SCHEMA)
    db.close()
    store = ResultStore(path)
    (row,) = store.readings()
    assert (row["task_id"], row["value"], row["source_picture"], row["review_time"]) == ("old", 0.5, "", None)
    assert store.review_queue() == []
    store.close()
    again = ResultStore(path)                                  # a second open changes nothing
    assert len(again.readings()) == 1
    columns = [r[1] for r in sqlite3.connect(path).execute("PRAGMA table_info(readings)")]
    assert columns[-15:] == ["source_picture", "roi", "review_value", "review_alarm", "review_by", "review_time",
                             "decimals", "grade", "diagnosis", "ack_by", "ack_time", "ack_note", "increment",
                             "alarm_low", "alarm_high"]


def uncertain_store(env, value=0.97):
    store, clock, patrol = env
    patrol.submit(task("t1", stops=1, retries=0), clock())
    run_step(patrol, clock)
    inspect(patrol, clock, value, REASON)
    settle_retry(clock)
    inspect(patrol, clock, value, REASON)
    (row,) = store.readings(task_id="t1")
    return store, row


def test_review_corrects_a_value_keeps_both_and_writes_a_correction_file(env, tmp_path):
    store, row = uncertain_store(env)
    folder = str(tmp_path / "corrections")
    got, path = review(store, folder, json.dumps({"id": row["id"], "value": 0.62, "by": "li"}), 5000.0)
    assert (got["value"], got["review_value"], got["review_alarm"], got["review_by"], got["review_time"]) == \
        (0.97, 0.62, "normal", "li", 5000.0)
    assert path == os.path.join(folder, "t1.%d.json" % row["id"])
    with open(path) as f:
        record = json.load(f)
    assert record == {"id": row["id"], "task_id": "t1", "time": row["time"], "preset": "/presets/p_gauge",
                      "target": 0, "target_name": "g", "kind": "pointer", "unit": "MPa", "picture": "/cap/zoom0.jpg",
                      "roi": [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0], "annotated_picture": "/pic/read_0.jpg",
                      "value": 0.97, "confidence": 30.0, "reason": REASON, "true_value": 0.62, "confirmed": False,
                      "by": "li", "reviewed": 5000.0}
    assert store.review_queue() == []
    with pytest.raises(CommandError, match=r"reading %d was already reviewed by li" % row["id"]):
        review(store, folder, json.dumps({"id": row["id"], "value": None, "by": "wang"}), 5001.0)
    assert store.reading(row["id"])["review_by"] == "li"


def test_review_confirms_the_robots_value(env, tmp_path):
    store, row = uncertain_store(env)
    got, path = review(store, str(tmp_path), json.dumps({"id": row["id"], "value": None, "by": "li"}), 5000.0)
    assert (got["review_value"], got["review_alarm"]) == (0.97, "alarm")   # confirmed outside the band: an alarm
    with open(path) as f:
        assert json.load(f)["confirmed"] is True


@pytest.mark.parametrize("data, reason", [
    ("not json", "review is not valid JSON"),
    ('{"id": 1, "value": 1}', "review must be a JSON object with keys id, value, by"),
    ('{"id": "1", "value": 1, "by": "li"}', "id must be a reading's id"),
    ('{"id": true, "value": 1, "by": "li"}', "id must be a reading's id"),
    ('{"id": 1, "value": "1", "by": "li"}', "value must be a number"),
    ('{"id": 1, "value": 1, "by": " "}', "by must be the reviewer's name"),
    ('{"id": 1, "value": 1, "by": "a\\nb"}', "by must be the reviewer's name"),
    ('{"id": 99, "value": 1, "by": "li"}', "no reading with id 99"),
])
def test_bad_reviews_are_refused_and_write_nothing(env, tmp_path, data, reason):
    store, row = uncertain_store(env)
    folder = tmp_path / "corrections"
    with pytest.raises(CommandError, match=reason):
        review(store, str(folder), data, 5000.0)
    assert not folder.exists()
    assert store.reading(row["id"])["review_time"] is None


def test_a_read_reading_needs_no_review(env, tmp_path):
    store, clock, patrol = env
    patrol.submit(task("t1", stops=1), clock())
    run_step(patrol, clock)
    run_step(patrol, clock)
    (row,) = store.readings(task_id="t1")
    with pytest.raises(CommandError, match=r"reading %d does not need review \(status read\)" % row["id"]):
        review(store, str(tmp_path / "c"), json.dumps({"id": row["id"], "value": 1.0, "by": "li"}), 1.0)
    assert not (tmp_path / "c").exists()


def test_report_lists_readings_needing_review_first_with_reason_and_picture(env, tmp_path):
    store, row = uncertain_store(env, value=0.5)
    _, clock, patrol = env
    run_step(patrol, clock, value=1.0)                         # p_lamp read
    readings = store.readings(task_id="t1")
    links = [dict(client_row(r, "/"), link=picture_link(r["picture"], str(tmp_path / "rep"), "/")) for r in readings]
    page = render_html(summary(store.task("t1"), readings, []), links).replace("<wbr>", "")   # break chances
    review_at = page.index("<h2>Needs attention (1)</h2>")
    assert review_at < page.index("<h2>Stops</h2>")
    assert review_at < page.index(REASON) < page.index("<h2>Stops</h2>")
    assert review_at < page.index(links[0]["link"]) < page.index("<h2>Stops</h2>")
    assert links[0]["link"].endswith("../pic/read_0.jpg")
    assert page.count('<tr class="review">') == 2   # in the attention list and at its stop
    review(store, str(tmp_path), json.dumps({"id": row["id"], "value": 0.55, "by": "li"}), 5000.0)
    paths = write_reports(str(tmp_path / "rep"), store.task("t1"), store.readings(task_id="t1"), [], "/", "test")
    with open(paths["report.html"]) as f:
        page = f.read()
    assert '<tr class="review">' not in page and "Needs attention (0)" in page and "reviewed by li: 0.55 MPa" in page
    with open(paths["report.json"]) as f:
        counts = json.load(f)["summary"]["counts"]
    assert (counts["uncertain"], counts["needs_review"]) == (1, 0)


def test_queries_share_one_set_of_rules():
    assert parse_query("", ("task_id", "limit"), 100) == {"limit": 100}
    assert parse_query('{"task_id": "t1", "limit": 5}', ("task_id", "limit"), 100) == {"task_id": "t1", "limit": 5}
    with pytest.raises(CommandError, match="query must be a JSON object with keys task_id, limit"):
        parse_query('{"from": 1}', ("task_id", "limit"), 100)
    with pytest.raises(CommandError, match=r"limit must be an integer in \[1, 5000\]"):
        parse_query('{"limit": 0}', ("task_id", "limit"), 100)
    with pytest.raises(CommandError, match="task_id must be a string"):
        parse_query('{"task_id": 3}', ("task_id", "limit"), 100)


def test_uncertain_reasons_undo_result_text():
    outcome = ReadOutcome([], [], [], [], [], [], ["", "pivot not found: a; b", "", REASON])
    text = result_text(outcome, "success")
    assert uncertain_reasons(text, 4, "success") == ["", "pivot not found: a; b", "", REASON]
    assert uncertain_reasons("success", 2, "success") == ["", ""]
    for bad in ("failed", "uncertain: ", "uncertain: box 4: x", "uncertain: box 0: "):
        with pytest.raises(ValueError):
            uncertain_reasons(bad, 4, "success")
