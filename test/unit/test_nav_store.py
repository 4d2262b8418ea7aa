"""Virtual obstacle commands, atomic persistence, goal parsing, localization checks, map files."""
import json
import math
import os

import numpy as np
import pytest
import yaml

from inspection_robot.command import CommandError
from inspection_robot import files
from inspection_robot.nav.gridmap import GridMap, MapError, load_map, save_map
from inspection_robot.angles import quaternion_from_yaw
from inspection_robot.inspection.find_goal import parse_find_goal
from inspection_robot.nav.goal import move_goal_data, parse_move_goal
from inspection_robot.nav.localization import LocalizationMonitor
from inspection_robot.nav.virtual_obstacles import NOT_REPLAYED, REPLAY_REFUSAL, VirtualObstacles, replay_table
from inspection_robot.sim.nav_yard import occupancy_map

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
WALL = {"id": "wall", "points": [[1, 1], [2, 2.5]], "closed": False}


def test_commands_round_trip_through_the_file(tmp_path):
    path = str(tmp_path / "vo.json")
    changes = []
    store = VirtualObstacles(path, on_change=changes.append)
    assert store.table.dispatch("add", json.dumps(WALL)).ack == "success"
    square = {"id": "sq", "points": [[0, 0], [1, 0], [1, 1]], "closed": True}
    assert store.table.dispatch("add", json.dumps(square)).ack == "success"
    assert store.table.dispatch("modify", json.dumps(dict(WALL, points=[[0, 0], [5, 5]]))).ack == "success"
    reloaded = VirtualObstacles(path)
    reloaded.load()
    listing = json.loads(reloaded.table.dispatch("query", "").data)
    assert [o["id"] for o in listing] == ["sq", "wall"]
    assert listing[1]["points"] == [[0.0, 0.0], [5.0, 5.0]] and listing[0]["closed"] is True
    one = json.loads(reloaded.table.dispatch("query", '{"id":"sq"}').data)
    assert one == [{"id": "sq", "points": [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]], "closed": True}]
    assert reloaded.table.dispatch("delete", '{"id":"sq"}').ack == "success"
    assert reloaded.table.dispatch("clear", "").ack == "success"
    again = VirtualObstacles(path)
    again.load()
    assert again.listing() == []
    assert len(changes) == 3
    assert os.listdir(str(tmp_path)) == ["vo.json"]  # no temporary file left


@pytest.mark.parametrize("cmd,data,reason", [
    ("add", "not json", "not valid JSON"),
    ("add", "[1]", "JSON object"),
    ("add", '{"points":[[0,0]]}', "id must be"),
    ("add", '{"id":"a","points":[]}', "points must be"),
    ("add", '{"id":"a","points":[[0,"x"]]}', "points[0]"),
    ("add", '{"id":"a","points":[[0,NaN]]}', "points[0]"),
    ("add", '{"id":"a","points":[[0,0],[1,1]],"closed":true}', "at least 3"),
    ("add", '{"id":"a","points":[[0,0]],"closed":"yes"}', "closed must be"),
    ("add", '{"id":"a","points":[[2,2],[1e8,2]]}', "points[1] is 1e+08 m"),
    ("add", '{"id":"a","points":[[2,2],[1e300,2]]}', "at most 100000 m"),
    ("add", '{"id":"a","points":' + "[" * 100000 + "]" * 100000 + '}', "not valid JSON"),
    ("add", '{"id":"a","points":' + json.dumps([[1.5, 2.5]] * 2000000) + '}', "at most 1000000 (10000 points)"),
    ("add", '{"id":"a","points":' + json.dumps([[1.5, 2.5]] * 10001) + '}', "points must be a list of 1..10000"),
    ("modify", '{"id":"ghost","points":[[0,0]]}', "no virtual obstacle"),
    ("delete", '{"id":"ghost"}', "no virtual obstacle"),
    ("query", '{"id":"ghost"}', "no virtual obstacle"),
    ("erase", "", "unknown command"),
])
def test_bad_commands_fail_with_reason(tmp_path, cmd, data, reason):
    store = VirtualObstacles(str(tmp_path / "vo.json"))
    reply = store.table.dispatch(cmd, data)
    assert reply.ack == "failed" and reason in reply.data


def test_duplicate_add_fails(tmp_path):
    store = VirtualObstacles(str(tmp_path / "vo.json"))
    store.table.dispatch("add", json.dumps(WALL))
    assert "already exists" in store.table.dispatch("add", json.dumps(WALL)).data


def test_failed_write_keeps_old_file_and_state(tmp_path, monkeypatch):
    path = str(tmp_path / "vo.json")
    store = VirtualObstacles(path)
    store.table.dispatch("add", json.dumps(WALL))
    before = open(path).read()

    def crash(*_args, **_kwargs):
        raise OSError("disk full")
    monkeypatch.setattr(files.os, "fsync", crash)
    reply = store.table.dispatch("clear", "")
    assert reply.ack == "failed" and "disk full" in reply.data
    assert open(path).read() == before
    assert [o["id"] for o in store.listing()] == ["wall"]
    assert sorted(os.listdir(str(tmp_path))) == ["vo.json"]


def test_corrupt_file_raises(tmp_path):
    path = tmp_path / "vo.json"
    path.write_text('[{"id": 1}]')
    with pytest.raises(ValueError):
        VirtualObstacles(str(path)).load()


def goal_json(**over):
    obj = {"with_direction": 1, "precision": 0, "move_style": 0, "velocity_x": 0.8, "velocity_yaw": 0.5,
           "goal_pose": {"position": {"x": 3.0, "y": -2.0, "z": 0},
                         "orientation": dict(zip("xyzw", quaternion_from_yaw(1.2)))}}
    obj.update(over)
    return json.dumps(obj)


def parse(data, goal_type="move"):
    return parse_move_goal(goal_type, data, 0.5, 0.5, 1.0, 1.0)


def test_a_replay_answers_query_from_the_recorded_list_and_refuses_changes(tmp_path):
    recorded = [{"id": "b", "points": [[0.0, 0.0], [1.0, 0.0]], "closed": False},
                {"id": "a", "points": [[2.0, 2.0], [3.0, 2.0], [3.0, 3.0]], "closed": True}]
    obstacles, known = VirtualObstacles(""), []
    table = replay_table(obstacles, lambda: bool(known))
    assert (table.dispatch("query", "").ack, table.dispatch("query", "").data) == ("failed", NOT_REPLAYED)
    obstacles.replace(recorded, "the bag")
    known.append(True)
    reply = table.dispatch("query", "")
    assert reply.ack == "success" and [o["id"] for o in json.loads(reply.data)] == ["a", "b"]
    assert json.loads(table.dispatch("query", '{"id": "a"}').data) == [recorded[1]]
    assert table.dispatch("query", '{"id": "zz"}').data == "no virtual obstacle with id 'zz'"
    assert table.dispatch("query", "{").data.startswith("data is not valid JSON")
    for cmd, data in (("add", '{"id": "c", "points": [[0, 0]]}'), ("modify", json.dumps(recorded[0])),
                      ("delete", '{"id": "a"}'), ("clear", "")):
        assert (table.dispatch(cmd, data).ack, table.dispatch(cmd, data).data) == ("failed", REPLAY_REFUSAL)
    assert REPLAY_REFUSAL.startswith("not_allowed: replay")
    assert table.dispatch("frobnicate", "").data == "unknown command 'frobnicate'"
    assert [o["id"] for o in json.loads(table.dispatch("query", "{}").data)] == ["a", "b"]   # nothing changed
    with pytest.raises(ValueError, match="the bag: points"):
        obstacles.replace([{"id": "x", "points": []}], "the bag")
    assert len(json.loads(table.dispatch("query", "").data)) == 2   # a bad list changes nothing
    with pytest.raises(ValueError, match="expected a JSON list"):
        obstacles.replace({"id": "x"}, "the bag")


def test_goal_parsing():
    g = parse(goal_json())
    assert (g.x, g.y) == (3.0, -2.0) and g.yaw == pytest.approx(1.2)
    assert g.with_direction and not g.precision and not g.backward and g.velocity_x == 0.8
    assert parse(goal_json(velocity_x=5.0)).velocity_x == 1.0   # clamped to the maximum
    assert parse(goal_json(move_style=1)).backward
    minimal = parse('{"goal_pose":{"position":{"x":1,"y":2}}}')
    assert minimal.velocity_x == 0.5 and minimal.yaw == 0.0 and not minimal.with_direction


@pytest.mark.parametrize("data,goal_type,reason", [
    ("{", "move", "not valid JSON"),
    ("[]", "move", "JSON object"),
    ('{"goal_pose":{}}', "move", "goal_pose.position"),
    (goal_json(), "fly", "goal type"),
    (goal_json(velocity_x=-1), "move", "velocity_x must be positive"),
    (goal_json(velocity_yaw="fast"), "move", "velocity_yaw"),
    (goal_json(move_style=2), "move", "move_style"),
    (goal_json(precision=3), "move", "precision"),
    ('{"goal_pose":{"position":{"x":1,"y":2},"orientation":{"x":0,"y":0,"z":0,"w":0}}}', "move", "quaternion"),
    ('{"goal_pose":{"position":{"x":"1","y":2}}}', "move", "position.x"),
])
def test_bad_goals(data, goal_type, reason):
    with pytest.raises(CommandError, match=reason):
        parse(data, goal_type)


@pytest.mark.parametrize("data, reason", [
    (goal_json(speed=99), "goal data: unknown key(s) speed (allowed: goal_pose, with_direction, precision, "
                          "move_style, velocity_x, velocity_yaw)"),
    ('{"goal_pose":{"position":{"x":1,"y":2},"heading":1}}',
     "goal_pose: unknown key(s) heading (allowed: position, orientation)"),
    ('{"goal_pose":{"position":{"x":1,"y":2,"yaw":1}}}', "goal_pose.position: unknown key(s) yaw (allowed: x, y, z)"),
    ('{"goal_pose":{"position":{"x":1,"y":2},"orientation":{"w":1,"yaw":3}}}',
     "goal_pose.orientation: unknown key(s) yaw (allowed: x, y, z, w)"),
])
def test_a_goal_key_nobody_reads_is_refused_by_name_not_ignored(data, reason):
    with pytest.raises(CommandError) as err:
        parse(data)
    assert str(err.value) == reason
    assert parse(goal_json()).velocity_x == 0.8   # positive control: every documented key


def test_a_find_goal_takes_only_preset_path(tmp_path):
    assert parse_find_goal("find_scale", json.dumps({"preset_path": str(tmp_path)}), [str(tmp_path)])[1] \
        == str(tmp_path)
    with pytest.raises(CommandError) as err:
        parse_find_goal("find_scale", json.dumps({"preset_path": str(tmp_path), "zoom": 2}), [str(tmp_path)])
    assert str(err.value) == "goal data: unknown key(s) zoom (allowed: preset_path)"


def test_localization_monitor():
    mon = LocalizationMonitor(max_xy_std_m=0.3, max_yaw_std_rad=0.2, stale_timeout_s=0.5)
    assert "no pose" in mon.problem(0.0)
    cov = [0.0] * 36
    cov[0] = cov[7] = 0.01
    mon.update(1.0, 1.0, 2.0, 4.0, cov)
    assert mon.problem(1.2) is None and mon.pose[2] == pytest.approx(4.0 - 2 * math.pi)
    assert "stale" in mon.problem(1.6)
    cov[0] = 0.5
    mon.update(2.0, 1.0, 2.0, 0.0, cov)
    assert "position uncertainty" in mon.problem(2.0)
    cov[0], cov[35] = 0.01, 0.1
    mon.update(3.0, 1.0, 2.0, 0.0, cov)
    assert "heading uncertainty" in mon.problem(3.0)


def test_map_round_trip_and_sample_map_matches_world(tmp_path):
    occ = np.zeros((30, 40), dtype=np.int8)
    occ[5, 7] = 100
    occ[10:12, :] = -1
    save_map(GridMap(occ, 0.1, (-1.5, 2.0, 0.0)), str(tmp_path / "m.yaml"))
    back = load_map(str(tmp_path / "m.yaml"))
    assert (back.occupancy == occ).all() and back.resolution == 0.1 and back.origin == (-1.5, 2.0, 0.0)
    assert back.world_to_cell(-1.5 + 0.75, 2.0 + 0.55) == (5, 7)
    with pytest.raises(MapError):
        load_map(str(tmp_path / "missing.yaml"))
    shipped = load_map(os.path.join(ROOT, "config", "maps", "substation.yaml"))
    with open(os.path.join(ROOT, "config", "sim_world.yaml")) as f:
        world = yaml.safe_load(f)["world"]
    expected = occupancy_map(world, shipped.resolution)
    assert (shipped.occupancy == expected.occupancy).all()
    row, col = shipped.world_to_cell(20.0, 10.0)   # transformer_1
    assert shipped.occupancy[row, col] == 100
    row, col = shipped.world_to_cell(*world["robot"]["start_pose"][:2])
    assert shipped.occupancy[row, col] == 0


def test_move_goal_data_is_what_parse_move_goal_reads():
    goal = parse_move_goal("move", move_goal_data(2.2, 5.0, math.pi, precision=True, velocity_x=0.2,
                                                  velocity_yaw=0.4), 0.5, 0.5, 1.0, 1.0)
    assert (goal.x, goal.y, abs(goal.yaw)) == pytest.approx((2.2, 5.0, math.pi))
    assert (goal.with_direction, goal.precision, goal.backward, goal.velocity_x, goal.velocity_yaw) == (
        True, True, False, 0.2, 0.4)
    goal = parse_move_goal("move", move_goal_data(3.7, 5.0, 0.5, backward=True, with_direction=False),
                           0.5, 0.5, 1.0, 1.0)
    assert (goal.with_direction, goal.precision, goal.backward, goal.velocity_x) == (False, False, True, 0.5)
    assert goal.yaw == pytest.approx(0.5)
