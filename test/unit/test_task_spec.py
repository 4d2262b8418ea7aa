"""Task submission checks (every malformed task refused with a clear reason) and the store's queries."""
import json

import pytest

from inspection_robot.command import CommandError
from inspection_robot.task.spec import ResolvedPreset, check_task_id, parse_task, split_limits
from inspection_robot.task.states import alarm_state
from inspection_robot.task.store import ResultStore

TARGETS = [{"name": "cab/ammeter", "kind": "pointer", "unit": "A"}]


def resolve(name):
    if name != "cab":
        raise CommandError("unknown preset directory '%s': preset directory not found" % name)
    return ResolvedPreset("/p/cab/20260101_000000", TARGETS, {"cab/ammeter": [0.0, 500.0]})


def reachable(x, y):
    return None if 0 <= x <= 60 and 0 <= y <= 40 else "outside the map"


def good(**changes):
    task = {"id": "t-1", "priority": "routine",
            "stops": [{"name": "a", "pose": {"x": 1.0, "y": 2.0, "yaw": 0.5}, "precision": 1,
                       "presets": [{"preset": "cab", "alarms": {"cab/ammeter": [10, 400]}, "foreign": True}]}]}
    task.update(changes)
    return task


def limits(value):
    """A task whose one preset gives ``value`` as the limits of cab/ammeter."""
    return good(stops=[{"pose": {"x": 1, "y": 2, "yaw": 0},
                        "presets": [{"preset": "cab", "alarms": {"cab/ammeter": value}}]}])


def parse(obj, known=()):
    return parse_task(obj if isinstance(obj, str) else json.dumps(obj), resolve, reachable, 2, known)


def test_a_good_task_is_resolved_with_bands_from_the_task_over_the_preset():
    t = parse(good())
    assert (t.task_id, t.priority, t.retries) == ("t-1", "routine", 2)
    preset = t.stops[0]["presets"][0]
    assert preset["directory"] == "/p/cab/20260101_000000" and preset["alarms"] == {"cab/ammeter": [10.0, 400.0]}
    assert t.stops[0]["precision"] == 1 and preset["foreign"] is True
    short = parse(good(stops=[{"pose": {"x": 1, "y": 2, "yaw": 0}, "presets": ["cab"]}]))
    assert short.stops[0]["presets"][0]["alarms"] == {"cab/ammeter": [0.0, 500.0]}
    assert short.stops[0]["name"] == "stop_1"


def test_limits_carry_an_alarm_band_around_the_normal_one():
    preset = parse(limits({"normal": [10, 400], "alarm": [0, 450]})).stops[0]["presets"][0]
    assert preset["alarms"] == {"cab/ammeter": {"normal": [10.0, 400.0], "alarm": [0.0, 450.0]}}
    assert split_limits(preset["alarms"]["cab/ammeter"]) == ([10.0, 400.0], [0.0, 450.0])
    assert split_limits([1.0, 2.0]) == ([1.0, 2.0], None) and split_limits(None) == (None, None)
    equal = parse(limits({"normal": [10, 400], "alarm": [10, 400]})).stops[0]["presets"][0]["alarms"]
    assert equal == {"cab/ammeter": {"normal": [10.0, 400.0], "alarm": [10.0, 400.0]}}   # no warning zone
    assert parse(limits({"normal": [1, 2]})).stops[0]["presets"][0]["alarms"] == {"cab/ammeter": {"normal": [1.0, 2.0]}}


@pytest.mark.parametrize("value, band, alarm_band, uncertain, state", [
    (5.0, [0, 10], None, False, "normal"),
    (11.0, [0, 10], None, False, "alarm"),
    (11.0, [0, 10], [-5, 12], False, "warning"),
    (-5.0, [0, 10], [-5, 12], False, "warning"),
    (12.5, [0, 10], [-5, 12], False, "alarm"),
    (11.0, [0, 10], [-5, 12], True, "check"),
    (5.0, None, None, False, "none"),
    (None, [0, 10], [-5, 12], False, "failed"),
])
def test_alarm_state_has_a_warning_zone_between_the_bands(value, band, alarm_band, uncertain, state):
    assert alarm_state(value, band, uncertain, alarm_band) == state


@pytest.mark.parametrize("task, reason", [
    ("{not json", "task is not valid JSON"),
    ("[1, 2]", "task must be a JSON object, got a list"),
    (good(id=""), "task id must be 1-64 characters"),
    (good(id="a/b"), "task id must be 1-64 characters"),
    (good(priority="urgent"), "priority must be one of routine|special"),
    (good(order="fastest"), "order must be one of given|shortest"),
    (good(retries=-1), "retries out of range [0, 10]: -1"),
    (good(stops=[]), "stops must be a non-empty list"),
    (good(extra=1), "task: unknown key(s) extra"),
    (good(stops=[{"pose": {"x": 1, "y": 2, "yaw": 0}, "presets": ["nope"]}]), "unknown preset directory 'nope'"),
    (good(stops=[{"pose": {"x": 1, "y": 2, "yaw": 0}, "presets": []}]), "stop 1: presets must be a non-empty list"),
    (good(stops=[{"pose": {"x": 1, "y": 2, "yaw": 0}, "precision": -1, "presets": ["cab"]}]),
     "stop 1: precision must be 0 or 1, got -1"),
    (good(stops=[{"pose": {"x": 1, "y": 2}, "presets": ["cab"]}]), "stop 1 pose: missing yaw"),
    (good(stops=[{"pose": {"x": "1", "y": 2, "yaw": 0}, "presets": ["cab"]}]), "stop 1 pose x must be a number"),
    (good(stops=[{"pose": {"x": 1e300, "y": 2, "yaw": 0}, "presets": ["cab"]}]), "stop 1 pose x out of range"),
    (good(stops=[{"pose": {"x": 99, "y": 2, "yaw": 0}, "presets": ["cab"]}]),
     "stop 1 (stop_1): pose (99.00, 2.00) is unreachable: outside the map"),
    (good(stops=[{"pose": {"x": 1, "y": 2, "yaw": 0}, "presets": [{"preset": "cab", "alarms": {"x": [1, 2]}}]}]),
     "alarm for unknown target 'x' of preset 'cab'"),
    (good(stops=[{"pose": {"x": 1, "y": 2, "yaw": 0}, "presets": [{"preset": "cab",
                                                                   "alarms": {"cab/ammeter": [5, 1]}}]}]),
     "low 5 is above high 1"),
    (good(stops=[{"pose": {"x": 1, "y": 2, "yaw": 0}, "presets": [{"preset": "cab", "foreign": "yes"}]}]),
     "foreign must be true or false"),
    (limits({"normal": [0, 10], "alarm": [2, 12]}),
     "alarm band [2, 12] must contain the normal band [0, 10] (a warning lies between them)"),
    (limits({"alarm": [0, 12]}), "missing normal (the band the value should be in)"),
    (limits({"normal": [0, 10], "warn": [0, 12]}), "unknown key(s) warn (allowed: normal, alarm)"),
    (limits({"normal": [0, 10], "alarm": [12, -1]}), "alarm of cab/ammeter alarm: low 12 is above high -1"),
    (limits([0, "10"]), "alarm of cab/ammeter high must be a number"),
    (limits(7), "alarm of cab/ammeter must be [low, high], got 7"),
    (json.dumps(good()).replace("[10, 400]", "[NaN, 400]"), "must be a finite number, got NaN"),
    (json.dumps(good()).replace("[10, 400]", "[10, Infinity]"), "must be a finite number, got Infinity"),
])
def test_malformed_tasks_are_refused_with_the_reason(task, reason):
    with pytest.raises(CommandError) as err:
        parse(task)
    assert reason in str(err.value)


@pytest.mark.parametrize("task_id", [".", "..", "t-1\n", "t.1", "a/b", "", "x" * 65, " t1", "t1 ", "\u00e91",
                                     "t\x001", 7, None, ["t1"]])
def test_task_ids_name_a_report_folder_so_only_plain_names_pass(task_id):
    with pytest.raises(CommandError) as err:
        parse(good(id=task_id))
    assert str(err.value).startswith("task id must be 1-64 characters of A-Z a-z 0-9 _ -, got ")
    assert "\n" not in str(err.value)   # the value is shown escaped (repr), on one line
    with pytest.raises(CommandError):
        check_task_id(task_id)


@pytest.mark.parametrize("task_id", ["t", "T_2026-01-01_0800", "x" * 64])
def test_plain_task_ids_pass(task_id):
    assert parse(good(id=task_id)).task_id == task_id == check_task_id(task_id)


def test_duplicate_id_is_refused():
    with pytest.raises(CommandError, match="duplicate task id 't-1'"):
        parse(good(), known={"t-1"})


def test_unreachable_is_checked_after_every_preset(monkeypatch):
    calls = []
    task = good(stops=[{"pose": {"x": 99, "y": 2, "yaw": 0}, "presets": ["nope"]}])
    with pytest.raises(CommandError, match="unknown preset"):
        parse_task(json.dumps(task), resolve, lambda x, y: calls.append((x, y)), 1)
    assert calls == []


def test_store_queries_by_task_and_time(tmp_path):
    store = ResultStore(str(tmp_path / "s.sqlite"))
    base = {"stop_name": "a", "preset": "/p", "target_name": "g", "kind": "pointer", "status": "read", "unit": "A",
            "alarm": "none", "low": None, "high": None, "confidence": 90.0, "picture": "", "x": 1.0, "y": 2.0,
            "yaw": 0.0, "reason": "", "source_picture": "", "roi": ""}
    rows = [dict(base, task_id=t, stop=0, preset_index=j, target=0, value=float(j), time=100.0 + j)
            for t in ("a", "b") for j in range(3)]
    assert store.add_readings(rows) == 6
    assert store.add_readings(rows[:1]) == 0          # the same reading twice is stored once
    assert [r["value"] for r in store.readings(task_id="b", since=101.0)] == [1.0, 2.0]
    assert len(store.readings(until=100.5)) == 2
    assert store.done_presets("a") == {(0, 0), (0, 1), (0, 2)}


def test_reachability_on_the_shipped_map():
    import os
    from inspection_robot.task.checks import Reachability
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    reachable = Reachability(os.path.join(root, "config", "maps", "substation.yaml"), 0.45, (5.0, 5.0))
    assert reachable(20.0, 21.4) is None
    assert reachable(20.0, 10.0) == "inside an obstacle or too close to one"   # transformer_1
    assert reachable(500.0, 5.0) == "outside the map"


def test_reachability_with_move_base_virtual_obstacles():
    """Stops inside a virtual obstacle, or fenced off from home by one, are refused; the layer is
    move_base's (its rasterised cells), and a check without one waits, then says so."""
    import os
    from inspection_robot.nav.costmap import Costmap
    from inspection_robot.task.checks import Reachability
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    map_file = os.path.join(root, "config", "maps", "substation.yaml")
    reachable = Reachability(map_file, 0.45, (5.0, 5.0), virtual_wait_s=0.01)
    assert reachable(20.0, 21.4) == "virtual obstacles not known (no virtual_obstacle_map from move_base yet)"
    move_base = Costmap(reachable.costmap.grid, 0.45, 0.3)   # as move_base rasterises them

    def publish(polylines):
        move_base.set_virtual(polylines)
        reachable.set_virtual(move_base.virtual.copy())

    publish([])
    assert reachable(20.0, 21.4) is None
    publish([([[19.0, 21.4], [21.0, 21.4]], False)])   # a wall through the stop
    assert reachable(20.0, 21.4) == "inside a virtual obstacle or too close to one"
    publish([([[18.5, 20.0], [21.5, 20.0], [21.5, 23.0], [18.5, 23.0]], True)])   # a fence around it
    assert reachable(20.0, 21.4) == "cut off from the home pose by virtual obstacles"
    assert reachable(20.0, 10.0) == "inside an obstacle or too close to one"   # the map's reason first
    assert reachable(10.0, 5.0) is None
    publish([])   # removed again
    assert reachable(20.0, 21.4) is None


def test_unknown_or_outside_preset_directories_are_refused(tmp_path):
    from inspection_robot.task.checks import resolve_preset
    with pytest.raises(CommandError, match="unknown preset directory 'nope': preset directory not found"):
        resolve_preset(str(tmp_path), "nope")
    with pytest.raises(CommandError, match="unknown preset directory '../x': path '../x' is outside the allowed"):
        resolve_preset(str(tmp_path), "../x")
    (tmp_path / "p" / "20260101_000000").mkdir(parents=True)
    (tmp_path / "p" / "20260101_000000" / "preset.ini").write_text("[preset]\n")
    with pytest.raises(CommandError, match="unknown preset directory 'p': "):
        resolve_preset(str(tmp_path), "p")
