"""task.trend: a meter drifting toward its band warns before it is an alarm; the patrol marks it."""
import json

import pytest

from inspection_robot.task.patrol import OUTCOME_OK, STEP_INSPECT, Inspection, Patrol, PatrolConfig
from inspection_robot.task.report import write_reports
from inspection_robot.task.report_pictures import sparkline
from inspection_robot.task.spec import ResolvedPreset, Task, parse_task
from inspection_robot.task.store import ResultStore
from inspection_robot.task.trend import DAY_S, DEFAULT_TREND, TrendConfig, fit_line, trend_text, trend_warning

HOUR = 3600.0


def daily(values, start=1.0e9):
    return [(start + i * DAY_S, v) for i, v in enumerate(values)]


def test_the_line_through_the_readings():
    slope, now = fit_line(daily([10.0, 11.0, 12.0, 13.0]))
    assert slope * DAY_S == pytest.approx(1.0) and now == pytest.approx(13.0)
    assert fit_line([(5.0, 2.0), (5.0, 4.0)]) == (0.0, 3.0)


def test_rising_and_falling_meters_warn_before_their_band():
    rising = trend_warning(daily([80.0, 83.0, 86.0, 89.0, 92.0]), [0.0, 100.0])
    assert rising["limit"] == "high" and rising["days"] == pytest.approx(8.0 / 3.0, abs=0.01)
    assert rising["slope_per_day"] == pytest.approx(3.0)
    falling = trend_warning(daily([0.5, 0.45, 0.4, 0.35]), [0.2, 1.0])
    assert falling["limit"] == "low" and falling["days"] == pytest.approx(3.0, abs=0.01)
    assert trend_text(rising, "C") == "trend: rising 3 C/day, reaches its high limit in 2.7 days"


@pytest.mark.parametrize("points,band,why", [
    (daily([80.0, 80.2, 79.9, 80.1]), [0.0, 100.0], "flat"),
    (daily([50.0, 52.0, 54.0, 56.0]), [0.0, 100.0], "22 days away, beyond the 7-day horizon"),
    (daily([95.0, 98.0, 101.0, 104.0]), [0.0, 100.0], "outside already: an alarm"),
    (daily([80.0, 85.0, 90.0]), [0.0, 100.0], "too few readings"),
    ([(1.0e9 + i * 60.0, 80.0 + i) for i in range(5)], [0.0, 100.0], "five minutes of readings"),
    (daily([80.0, 85.0, 90.0, 95.0]), None, "no band"),
    (daily([90.0, 85.0, 80.0, 75.0]), [0.0, 100.0], "moving away from the high limit, low one 15 days away"),
])
def test_no_warning(points, band, why):
    assert trend_warning(points, band) is None, why


def test_only_the_newest_window_counts():
    old_jump = daily([10.0, 90.0] + [50.0] * 10)
    assert trend_warning(old_jump, [0.0, 100.0], TrendConfig(10, 4, 7.0, 600.0)) is None


def resolve(name):
    return ResolvedPreset("/presets/" + name, [{"name": "oil", "kind": "pointer", "unit": "C"}], {})


def daily_patrols(store, values, resolver, target, band, prefix):
    """One patrol a day of one preset whose one target reads each of ``values``; the rows, in order."""
    now = 1.0e9
    patrol = Patrol(store, PatrolConfig(1.0, (0.0, 0.0, 0.0), 20.0, 10.0, 1), now)
    patrol.set_mode(0)
    rows = []
    for day, value in enumerate(values):
        now = 1.0e9 + day * DAY_S
        preset = {"preset": "p", "alarms": {target: band}}
        patrol.submit(parse_task(json.dumps({"id": "%s%d" % (prefix, day), "stops": [
            {"pose": {"x": 1.0, "y": 1.0, "yaw": 0.0}, "presets": [preset]}]}), resolver, lambda x, y: None, 0), now)
        while True:
            step = patrol.next_step(now)
            if step is None:
                break
            detail = Inspection([value], [90.0], ["/pic.jpg"], (1.0, 1.0, 0.0)) if step.kind == STEP_INSPECT else ""
            patrol.step_done(step, OUTCOME_OK, detail, now, now + 1.0)
        rows += store.readings(task_id="%s%d" % (prefix, day))
    return rows, now


def test_the_patrol_marks_a_drifting_meter_and_the_store_keeps_its_history(tmp_path):
    store = ResultStore(str(tmp_path / "r.sqlite"))
    assert PatrolConfig(1.0, (0.0, 0.0, 0.0), 20.0, 10.0, 1).trend == DEFAULT_TREND
    rows, now = daily_patrols(store, [70.0, 75.0, 80.0, 85.0, 90.0], resolve, "oil", [0, 100], "d")
    row = rows[-1]
    assert [r["alarm"] for r in rows] == ["normal", "normal", "normal", "trend", "trend"]   # 4 needed; 85 -> 100 in 3 d
    assert row["reason"] == "trend: rising 5 C/day, reaches its high limit in 2.0 days"
    assert [v for _t, v in store.meter_values("oil", now + 10.0, 3)] == [90.0, 85.0, 80.0]   # newest first
    assert store.meter_values("oil", 1.0e9, 10) == []   # before the first reading


def test_the_report_draws_each_meters_recent_readings_beside_it(tmp_path):
    store = ResultStore(str(tmp_path / "r.sqlite"))
    rows = []
    for day, value in enumerate([0.3, 0.35, 0.5, 0.6]):
        row = {"task_id": "t%d" % day, "stop": 0, "stop_name": "s", "preset_index": 0, "preset": "/p/a/1", "target": 0,
               "target_name": "oil", "kind": "pointer", "status": "read", "value": value, "unit": "MPa",
               "alarm": "normal", "low": 0.2, "high": 0.8, "confidence": 90.0, "picture": "", "x": 0.0, "y": 0.0,
               "yaw": 0.0, "time": 1.0e9 + day * DAY_S, "reason": "", "source_picture": "", "roi": ""}
        store.add_readings([row])
        rows.append(row)
    store.add_task(Task("t3", "routine", 0, []), "done", 1.0e9)
    history = store.meter_histories(store.readings(task_id="t3"), 3)
    assert [v for _t, v in history["oil"]] == [0.35, 0.5, 0.6]   # oldest first, up to this task's reading
    paths = write_reports(str(tmp_path / "rep"), store.task("t3"), store.readings(task_id="t3"), [], "/", "v", history)
    page = open(paths["report.html"]).read()
    assert page.count('<svg class="trend"') == 1 and "stroke-dasharray" in page   # the band's limits dashed
    assert sparkline([(0.0, 1.0)]) == ""


def test_a_year_of_one_meters_readings_comes_in_bounded_pages(tmp_path):
    """The trend query of issue #29's bad input: a year of hourly readings answers page by page
    (query_results' limit and after_id), each row once, in order, a page never more than its limit."""
    import tracemalloc
    from inspection_robot.task.review import parse_query
    from inspection_robot.task.store import WRITTEN_COLUMNS
    store = ResultStore(str(tmp_path / "r.sqlite"))
    hours = 365 * 24
    base = dict((c, None) for c in WRITTEN_COLUMNS)
    base.update(stop=1, stop_name="s", preset="presets/p/1", kind="pointer", status="read", unit="C",
                alarm="normal", confidence=90.0, picture="", x=0.0, y=0.0, yaw=0.0, reason="", source_picture="",
                roi="")
    rows = []
    for hour in range(hours):   # one task a day, 24 readings each (its presets), two meters
        for target, name in enumerate(("oil", "winding")):
            rows.append(dict(base, task_id="day%d" % (hour // 24), preset_index=hour % 24, target=target,
                             target_name=name,
                             value=60.0 + hour % 50, time=1.0e9 + hour * 3600.0))
    assert store.add_readings(rows) == 2 * hours
    query = parse_query(json.dumps({"target": "oil", "limit": 1000}), ("target", "limit", "after_id"), 1000)
    seen, pages, after = [], 0, None
    tracemalloc.start()
    while True:
        page = store.readings(limit=query["limit"], target=query["target"], after_id=after)
        if not page:
            break
        assert len(page) <= 1000 and all(r["target_name"] == "oil" for r in page)
        seen.extend(r["time"] for r in page)
        after, pages = page[-1]["id"], pages + 1
        del page
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert seen == [1.0e9 + h * 3600.0 for h in range(hours)]   # every reading once, in recording order
    assert pages == 9
    assert peak < 8 * 1024 * 1024   # a page at a time: far below the year's ~17,500 rows held at once


def test_a_counter_stores_its_increment_raises_no_trend_and_a_count_that_went_down_is_an_alarm(tmp_path):
    """Issue #42: an arrester's discharge counter, read every day: the count since the previous reading
    is stored beside it (and shown in the report); a count that went down is an alarm."""
    store = ResultStore(str(tmp_path / "r.sqlite"))

    def counter(name):
        return ResolvedPreset("/presets/" + name, [{"name": "arrester_a", "kind": "digital", "unit": "",
                                                    "decimals": 0, "counter": True}], {})
    rows, _now = daily_patrols(store, [12.0, 12.0, 15.0, 18.0, 21.0, 9.0], counter, "arrester_a", [0, 30], "c")
    assert [r["increment"] for r in rows] == [None, 0.0, 3.0, 3.0, 3.0, -12.0]
    assert [r["alarm"] for r in rows] == ["normal"] * 5 + ["alarm"]   # rising steadily to its limit: no trend
    assert rows[-1]["reason"].startswith("counter went down from 21 to 9 since its previous reading")
    paths = write_reports(str(tmp_path / "rep"), store.task("c3"), store.readings(task_id="c3"), [], "/", "v")
    assert "+3 since the previous reading" in open(paths["report.html"]).read()
