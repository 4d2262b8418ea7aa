"""The patrol report's meaning: values at their meter's resolution (from the calibration), the driven
path (thinned, its length, its table in an older store), the summary's counts and the yard map."""
import json
import math
import sqlite3

import numpy as np
import pytest

from inspection_robot.inspection import calibration_schema as schema
from inspection_robot.inspection.preset import PresetError, Target
from inspection_robot.nav.gridmap import GridMap
from inspection_robot.task.client_view import client_row
from inspection_robot.task import display
from inspection_robot.task.display import reading_text
from inspection_robot.task.patrol import Inspection
from inspection_robot.task.rows import reading_rows, result_summary
from inspection_robot.task.report import (map_cells, reading_state, render_html, summary, worst_state, write_reports,
                                          yard_svg)
from inspection_robot.task.spec import Task
from inspection_robot.task.store import ResultStore
from inspection_robot.task.track import DEFAULT_TRACK, PathThinner, TrackConfig, path_length

BOX = {0: [[0, 0], [100, 0], [100, 100], [0, 100]]}


def pointer(**params):
    """A pointer's params as preset_calib_info.ini gives them: through the schema, defaults filled."""
    base = {"start_angle": -135.0, "end_angle": 135.0, "start_value": 0.0, "end_value": 1.6}
    base.update(params)
    return schema.check_params("pointer", base)


# --- resolution -------------------------------------------------------------------------------------
@pytest.mark.parametrize("marks,decimals", [
    ([0.0, 0.05, 0.1, 0.15], 2),          # 0.05 MPa divisions
    ([0.0, 0.2, 0.4, 0.6, 0.8], 1),       # 0.2: one place (0.1 + 0.2 noise does not make two)
    ([0.0, 0.1, 0.2, 0.3], 1),
    ([0.0, 0.025, 0.05], 3),
    ([0.0, 5.0, 10.0, 1.6], 1),           # the smallest division counts, wherever it lies
    ([0.8, 0.8, 0.0], 1),                 # duplicate marks are one mark: the division is 0.8
])
def test_the_smallest_division_between_marks_gives_the_places(marks, decimals):
    params = pointer(end_value=10.0, marks=[[v, 0.5, 0.5] for v in marks])
    assert display.display_decimals("pointer", params) == decimals


def test_divisions_that_no_decimal_writes_get_one_place_more_than_their_first_digit():
    assert display.division_decimals(1.0 / 3.0) == 2
    assert display.division_decimals(0.125) == 2
    assert display.division_decimals(5.0) == 0 and display.division_decimals(20.0) == 0
    assert display.division_decimals(1e-9) == display.MAX_DIGITS


def test_a_scale_without_marks_is_read_to_a_hundredth_of_its_span_and_negative_ranges_count_their_width():
    assert display.display_decimals("pointer", pointer()) == 2                        # 0..1.6 -> 0.016
    assert display.display_decimals("pointer", pointer(start_value=-0.1, end_value=0.0)) == 3   # vacuum, 0.001
    assert display.display_decimals("pointer", pointer(start_value=100.0, end_value=-100.0)) == 0   # falling scale
    with pytest.raises(schema.SchemaError, match="start_value and end_value must differ"):
        pointer(start_value=1.0, end_value=1.0)   # a zero range is refused with the calibration


def test_a_non_linear_scale_counts_its_finest_stretch_and_two_entries_are_only_its_ends():
    table = [[0.0, -135.0], [1.0, -45.0], [1.5, 0.0], [1.75, 45.0], [2.0, 135.0]]   # square-root flow scale
    assert display.display_decimals("pointer", pointer(end_value=2.0, scale_table=table)) == 2   # 0.25
    ends = [[0.0, -135.0], [16.0, 135.0]]
    assert display.display_decimals("pointer", pointer(end_value=16.0, scale_table=ends)) == 1   # 16 / 100


def test_digits_overrides_and_is_checked_with_the_rest_of_the_calibration():
    params = pointer(digits=3, marks=[[0.0, 0.1, 0.9], [0.5, 0.5, 0.1]])
    assert display.display_decimals("pointer", params) == 3
    assert display.display_decimals("thermal", {"digits": 0}) == 0
    assert display.display_decimals("thermal", {}) == 1 and display.display_decimals("lamp", {}) == 0
    assert schema.from_text("digits", "2") == 2 and schema.to_text("digits", 2) == "2"
    for bad, reason in ((7, r"digits must be in \[0, 6\], got 7"), (1.5, "whole number of decimal places"),
                        (-1, r"digits must be in \[0, 6\]"), ("2", "digits must be a finite number"),
                        (True, "digits must be a finite number")):
        with pytest.raises(schema.SchemaError, match=reason):
            pointer(digits=bad)
    with pytest.raises(PresetError, match="key 'digits' does not apply to a lamp target"):
        Target("lamp", BOX, colour="red", digits=1)
    target = Target.from_section(dict(Target("pointer", BOX, **pointer(digits=2)).section()), BOX)
    assert target.params["digits"] == 2   # through preset_calib_info.ini's text and back


def test_the_text_of_a_value_is_rounded_with_its_unit_and_states_are_words():
    assert reading_text(0.80273, "MPa", 2, "pointer") == "0.80 MPa"
    assert reading_text(55.1963, "C", 1, "thermal") == "55.2 C"
    assert reading_text(-0.0004, "MPa", 3, "pointer") == "0.000 MPa"    # no minus zero
    assert reading_text(-0.05, "MPa", 2, "pointer") == "-0.05 MPa"
    assert reading_text(12.5, "", 0, "pointer") == "12"                 # even rounding of .5 is Python's
    assert reading_text(0.80273, "MPa", None, "pointer") == "0.8027 MPa"  # stored before decimals: 4 digits
    assert reading_text(None, "MPa", 2, "pointer") == ""
    assert [reading_text(v, "", 0, "lamp") for v in (0.0, 1.0, 5.0, 9.0)] == ["off", "lit red", "lit white",
                                                                              "lamp code 9"]
    assert [reading_text(v, "", 0, "switch") for v in (0.0, 1.0)] == ["open", "closed"]
    assert reading_text(1.0, "objects", 0, "foreign") == "1 object"


def rows_of(decimals=2, value=0.80273, alarms=None):
    preset = {"directory": "/d/presets/p/1", "targets": [{"name": "g", "kind": "pointer", "unit": "MPa",
                                                          "decimals": decimals}], "alarms": alarms or {}}
    return reading_rows("t1", 0, "s1", 0, preset, Inspection([value], [90.0], ["/d/pictures/p/a.jpg"], (1.0, 2.0, 0.0)),
                        "", 100.0)


def test_rows_keep_the_raw_value_and_carry_its_text_to_every_client():
    (row,) = rows_of()
    assert row["decimals"] == 2 and row["value"] == 0.80273
    assert client_row(row, "/d")["display"] == "0.80 MPa"
    assert result_summary([row])["readings"][0]["display"] == "0.80 MPa"   # task_status last_result


# --- the driven path ----------------------------------------------------------------------------------
def test_the_path_keeps_a_pose_every_half_metre_or_turn_and_nothing_while_standing():
    track = PathThinner("t1")
    kept = [track.add(t * 0.1, t * 0.08, 0.0, 0.0) for t in range(100)]   # 0.8 m/s for 10 s at 10 Hz
    poses = track.take()
    assert kept[0] and len(poses) == 15 and track.take() == []           # 7.92 m: the start + every 0.56 m
    assert all(0.5 <= b[1] - a[1] < 0.5 + 0.08 for a, b in zip(poses, poses[1:]))
    for t in range(100, 400):                                             # stands 30 s, jitter of 1 cm
        track.add(t * 0.1, 7.92 + 0.01 * (t % 2), 0.0, 0.0)
    assert [p[1] for p in track.take()] == [7.92]   # once: the 8 cm since the last kept pose, after 5 s
    assert track.add(40.1, 7.92, 0.0, 1.0)                                # a turn on the spot is kept
    assert track.add(46.0, 7.98, 0.0, 1.0)                                # 6 cm after 5 s: kept
    assert not track.add(47.0, 8.0, 0.0, float("nan"))
    assert not track.add(47.1, 8.1, 0.0, 1.0)
    assert len(track.take()) == 2
    assert track.take(final=True) == [(47.1, 8.1, 0.0, 1.0)]             # the task ended: where it ended
    assert track.take(final=True) == []


def test_distance_driven_is_the_kept_paths_length_within_a_percent_on_a_curve():
    track = PathThinner("t1")
    radius = 2.0
    for i in range(2001):   # a half circle at 10 Hz, 1 mm steps of angle
        a = math.pi * i / 2000.0
        track.add(i * 0.01, radius * math.cos(a), radius * math.sin(a), a + math.pi / 2)
    driven = path_length(track.take(final=True))
    assert math.pi * radius * 0.99 < driven <= math.pi * radius
    assert path_length([]) == 0.0 and path_length([(0.0, 1.0, 1.0, 0.0)]) == 0.0


def test_a_full_buffer_drops_its_oldest_and_counts_them():
    track = PathThinner("t1", DEFAULT_TRACK._replace(buffer=3))
    for i in range(5):
        track.add(float(i), float(i), 0.0, 0.0)
    assert [p[1] for p in track.take()] == [2.0, 3.0, 4.0] and track.dropped == 2
    track.give_back([(9.0, 9.0, 0.0, 0.0)] * 4)
    assert track.pending == 3 and track.dropped == 3
    assert TrackConfig._fields == DEFAULT_TRACK._fields


OLD_SCHEMA = """
CREATE TABLE tasks (task_id TEXT PRIMARY KEY, priority TEXT NOT NULL, spec TEXT NOT NULL, state TEXT NOT NULL,
    reason TEXT NOT NULL DEFAULT '', submitted REAL NOT NULL, ended REAL, seq INTEGER NOT NULL);
CREATE TABLE readings (id INTEGER PRIMARY KEY AUTOINCREMENT, task_id TEXT NOT NULL, stop INTEGER NOT NULL,
    stop_name TEXT NOT NULL, preset_index INTEGER NOT NULL, preset TEXT NOT NULL, target INTEGER NOT NULL,
    target_name TEXT NOT NULL, kind TEXT NOT NULL, status TEXT NOT NULL, value REAL, unit TEXT NOT NULL,
    alarm TEXT NOT NULL, low REAL, high REAL, confidence REAL, picture TEXT NOT NULL,
    x REAL, y REAL, yaw REAL, time REAL NOT NULL, reason TEXT NOT NULL, UNIQUE (task_id, stop, preset_index, target));
CREATE TABLE steps (id INTEGER PRIMARY KEY AUTOINCREMENT, task_id TEXT NOT NULL, stop INTEGER NOT NULL,
    preset_index INTEGER NOT NULL, kind TEXT NOT NULL, outcome TEXT NOT NULL, started REAL NOT NULL,
    ended REAL NOT NULL, reason TEXT NOT NULL);
CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
INSERT INTO tasks VALUES ('old', 'routine', '{"id": "old", "priority": "routine", "retries": 1, "stops": []}',
    'done', '', 10.0, 20.0, 1);
INSERT INTO readings (task_id, stop, stop_name, preset_index, preset, target, target_name, kind, status, value, unit,
    alarm, low, high, confidence, picture, x, y, yaw, time, reason)
    VALUES ('old', 0, 's', 0, '/p/a/1', 0, 'g', 'pointer', 'read', 0.80273, 'MPa', 'none', NULL, NULL, 90.0, '',
    0.0, 0.0, 0.0, 15.0, '');
"""


def test_an_older_store_gets_the_path_table_and_its_readings_keep_four_digits(tmp_path):
    path = str(tmp_path / "old.sqlite")
    db = sqlite3.connect(path)
    db.executescript(OLD_SCHEMA)
    db.close()
    store = ResultStore(path)
    (row,) = store.readings(task_id="old")
    assert row["decimals"] is None and client_row(row, "/")["display"] == "0.8027 MPa"
    assert store.driven_path("old") == []
    assert summary(store.task("old"), [row], [], store.driven_path("old"))["distance_driven_m"] is None
    store.add_poses("new", [(1.0, 0.0, 0.0, 0.0), (2.0, 3.0, 4.0, 0.5)])
    store.add_readings(rows_of())
    store.close()
    again = ResultStore(path)   # a second open changes nothing
    assert again.driven_path("new") == [(1.0, 0.0, 0.0, 0.0), (2.0, 3.0, 4.0, 0.5)]
    assert [r["decimals"] for r in again.readings()] == [None, 2]
    tables = set(r[0] for r in sqlite3.connect(path).execute("SELECT name FROM sqlite_master WHERE type = 'table'"))
    assert {"poses", "readings", "tasks", "steps", "meta"} <= tables


# --- summary, attention, map ---------------------------------------------------------------------------
def reading(stop, status="read", alarm="normal", value=0.5, review=None, target=0):
    return {"id": stop * 10 + target, "task_id": "t1", "stop": stop, "stop_name": "s%d" % stop, "preset_index": 0,
            "preset": "/d/presets/p%d/1" % stop, "target": target, "target_name": "m%d_%d" % (stop, target),
            "kind": "pointer", "status": status, "value": None if status == "failed" else value, "unit": "MPa",
            "alarm": alarm, "low": 0.2, "high": 0.8, "confidence": 80.0, "picture": "", "x": 0.0, "y": 0.0,
            "yaw": 0.0, "time": 100.0 + stop, "reason": "why %d" % stop, "source_picture": "", "roi": "",
            "review_value": review, "review_alarm": "normal" if review is not None else "", "review_by": "li",
            "review_time": 200.0 if review is not None else None, "decimals": 2}


def test_the_summary_counts_each_kind_of_attention_and_the_distance_driven():
    rows = [reading(0), reading(0, alarm="alarm", value=0.9, target=1), reading(1, status="uncertain"),
            reading(1, status="uncertain", alarm="check", value=0.95, target=1),
            reading(2, status="failed", alarm="failed"), reading(2, alarm="trend", target=1),
            reading(3, status="uncertain", review=0.55), dict(reading(3, alarm="warning", value=0.85, target=1),
                                                              alarm_low=0.1, alarm_high=0.9)]
    task = {"task_id": "t1", "priority": "routine", "state": "done", "reason": "", "submitted": 10.0, "ended": 130.0,
            "spec": {"stops": [{"name": "s%d" % i, "x": float(i), "y": 0.0} for i in range(5)],
                     "planned_length_m": 12.34}}
    info = summary(task, rows, [], [(0.0, 0.0, 0.0, 0.0), (1.0, 3.0, 4.0, 0.0), (2.0, 3.0, 10.0, 0.0)])
    assert info["counts"] == {"readings": 8, "read": 4, "uncertain": 3, "needs_review": 2, "failed": 1, "alarms": 1,
                              "checks": 1, "warnings": 1, "trends": 1}
    assert info["thermal_defects"] == {"general": 0, "serious": 0, "critical": 0}
    assert (info["distance_driven_m"], info["planned_length_m"], info["duration_s"]) == (11.0, 12.34, 120.0)
    assert [reading_state(r) for r in rows] == ["normal", "alarm", "review", "check", "failed", "trend", "normal",
                                                "warning"]
    assert [worst_state([r for r in rows if r["stop"] == i]) for i in range(5)] == [
        "alarm", "check", "failed", "warning", "not read"]
    shown = [dict(client_row(r, "/d"), link="", history=[]) for r in rows]
    page = render_html(info, shown, yard_svg(None, [], task["spec"]["stops"], shown), task["spec"]["stops"])
    attention = page[page.index("Needs attention (6)"):page.index("<h2>Yard map</h2>")]
    order = [attention.index('<tr class="%s">' % s) for s in ("alarm", "check", "warning", "failed", "review", "trend")]
    assert order == sorted(order)
    assert "0.2 .. 0.8 MPa; alarm outside 0.1 .. 0.9 MPa" in attention and "<b>1</b>warnings" in page
    assert "0.90 MPa" in attention and "11.0 m" in page and "12.3 m" in page and "2 min 00 s" in page
    stops = page[page.index("<h2>Stops</h2>"):]
    assert stops.index("1 s0") < stops.index("2 s1") < stops.index("5 s4") and "no readings" in stops
    assert "reviewed by li: 0.55 MPa" in stops


def test_the_yard_map_outlines_the_map_and_colours_each_stop_by_its_worst_reading():
    occupancy = np.zeros((400, 600), np.int8)     # 30 x 20 m at 5 cm
    occupancy[:, :5] = 100
    occupancy[200:210, 100:300] = 100
    occupancy[390:, :] = -1
    grid = GridMap(occupancy, 0.05, (-1.0, -1.0, 0.0))
    cells, size, corner = map_cells(grid, [(5.0, 5.0)])
    assert max(cells.shape) <= 240 and size == pytest.approx(0.15)
    assert cells[:, 0].all() and cells[-1].tolist().count(2) > 0     # the wall, the unknown strip on top
    assert corner == pytest.approx((-1.0, -1.0))
    stops = [{"name": "a", "x": 2.0, "y": 3.0}, {"name": "b <x>", "x": 8.0, "y": 3.0}]
    rows = [reading(0, alarm="alarm", value=0.9), reading(0)]
    svg = yard_svg(grid, [(0.0, 0.0, 0.0, 0.0), (1.0, 2.0, 3.0, 0.0), (2.0, 8.0, 3.0, 0.0)], stops, rows)
    assert svg.startswith('<svg class="yard"') and svg.count('<g class="stop ') == 2
    assert '<g class="stop alarm"><title>1 a: alarm</title>' in svg and "#c62828" in svg
    assert '<title>2 b &lt;x&gt;: not read</title>' in svg and 'class="driven"' in svg
    assert yard_svg(None, [], [], []) == ""


def test_the_report_files_carry_the_rounded_text_beside_the_raw_value(tmp_path):
    store = ResultStore(str(tmp_path / "r.sqlite"))
    store.add_task(Task("t1", "routine", 0, [{"name": "s1", "x": 1.0, "y": 2.0, "yaw": 0.0, "presets": []}]),
                   "done", 100.0)
    store.add_readings(rows_of(alarms={"g": [0.2, 0.7]}))
    store.add_poses("t1", [(100.0, 0.0, 0.0, 0.0), (101.0, 1.0, 2.0, 0.0)])
    paths = write_reports(str(tmp_path / "rep"), store.task("t1"), store.readings(task_id="t1"), [], "/d", "v",
                          path=store.driven_path("t1"))
    data = json.load(open(paths["report.json"]))
    assert (data["readings"][0]["value"], data["readings"][0]["display"]) == (0.80273, "0.80 MPa")
    assert data["summary"]["distance_driven_m"] == 2.2
    lines = open(paths["report.csv"]).read().splitlines()
    assert lines[0].endswith(",decimals,grade,diagnosis,ack_by,ack_time,ack_note,increment,alarm_low,alarm_high,"
                             "display,review_display")
    assert lines[1].endswith(",2,,,,,,,,,0.80 MPa,")
    page = open(paths["report.html"]).read()
    assert "0.80 MPa" in page and "0.80273" not in page and '<svg class="yard"' in page


def test_thermal_defects_are_counted_by_grade_and_get_a_tile():
    rows = [dict(reading(0, alarm="alarm", value=55.0), kind="thermal", unit="C", grade="serious",
                 reason="serious defect (connector): dt 83 % >= 80 % (phase B 55.0 C, coolest sister 30.0 C, "
                        "ambient 25.0 C)"),
            dict(reading(0, value=30.0, target=1), kind="thermal", unit="C", grade="")]
    task = {"task_id": "t1", "priority": "routine", "state": "done", "reason": "", "submitted": 10.0, "ended": 130.0,
            "spec": {"stops": [{"name": "s0", "x": 0.0, "y": 0.0}], "planned_length_m": 1.0}}
    info = summary(task, rows, [])
    assert info["thermal_defects"] == {"general": 0, "serious": 1, "critical": 0}
    shown = [dict(client_row(r, "/d"), link="", history=[]) for r in rows]
    page = render_html(info, shown, "", task["spec"]["stops"])
    assert '<div class="tile hot"><b>1</b>serious thermal defects</div>' in page
    assert "general thermal defects" not in page and "dt 83 % &gt;= 80 %" in page


def test_a_corrected_check_counts_with_its_reviewed_alarm_and_no_limits_is_not_normal():
    """Issue #41: after an uncertain 118 C check was corrected to 55 the tile said "1 checks" while the
    section below said nothing needed attention, and "Every reading is normal" was printed of readings
    that had no limits at all."""
    corrected = dict(reading(0, status="uncertain", alarm="check", value=1.18, review=0.55))
    unlimited = dict(reading(1), alarm="none", low=None, high=None)
    task = {"task_id": "t1", "priority": "routine", "state": "done", "reason": "", "submitted": 10.0, "ended": 130.0,
            "spec": {"stops": [{"name": "s%d" % i, "x": float(i), "y": 0.0} for i in range(2)],
                     "planned_length_m": 3.0}}

    def page(rows):
        info = summary(task, rows, [])
        shown = [dict(client_row(r, "/d"), link="", history=[]) for r in rows]
        return info, render_html(info, shown, "", task["spec"]["stops"])

    info, html_page = page([corrected])
    assert (info["counts"]["checks"], info["counts"]["alarms"]) == (0, 0)
    assert "Needs attention (0)" in html_page and "Every reading is within its limits." in html_page
    _info, html_page = page([unlimited])
    assert "no reading had limits to compare with" in html_page and "within its limits" not in html_page
    _info, html_page = page([corrected, unlimited])
    assert "1 reading(s) within their limits, 1 without limits" in html_page


def test_the_planned_route_beside_the_distance_driven_leaves_the_way_home_apart():
    """Issue #41: 'distance driven 35.8 m' stood beside 'planned route 51.5 m' that included the leg
    home, which a patrol never drives."""
    task = {"task_id": "t1", "priority": "routine", "state": "done", "reason": "", "submitted": 10.0, "ended": 130.0,
            "spec": {"stops": [{"name": "s0", "x": 0.0, "y": 0.0}], "order": "shortest", "planned_length_m": 51.5,
                     "home_leg_m": 15.7}}
    page = render_html(summary(task, [], []), [], "", task["spec"]["stops"])
    assert ("<dt>planned route</dt><dd>35.8 m (shortest order, from the robot through every stop; driving home "
            "from the last stop would add 15.7 m, which a patrol does not drive)</dd>") in page
    del task["spec"]["home_leg_m"]   # a task planned before the home leg was kept
    page = render_html(summary(task, [], []), [], "", task["spec"]["stops"])
    assert "51.5 m (shortest order, from the robot through every stop and home)" in page
