"""A connector going bad over days, seen by the simulated thermal imager and graded as a patrol
grades it (task.rows): the world's busbar clamp row (config/sim_world.yaml), phase A 7.5 K warmer
every day, read from rendered radiometric frames through the calibrated boxes; each day's grade
must be the one the true temperatures give, on the very day each boundary is crossed."""
import pytest

from inspection_robot.inspection.thermal_max import read_thermal_max
from inspection_robot.inspection.geometry import quads_from_flat
from inspection_robot.sim.inspection_sim import RenderedHead, world_specs
from inspection_robot.sim.render import Renderer, ThermalRenderer
from inspection_robot.sim.world import World, WorldError
from inspection_robot.task.rows import thermal_findings
from inspection_robot.thermal.diagnosis import DEFAULT_RULES, diagnose
from inspection_robot_testing.world_views import SENSOR_HEIGHT_M, camera_optics, front_pose
from inspection_robot_testing.yard_patrol import config_file

WIDTH, HEIGHT = 800, 450
DEVICE = "busbar_clamps"
HOT = "busbar_support/clamp_a"
AIM_HEIGHT_M, DISTANCE_M = 2.7, 4.0


@pytest.fixture(scope="module")
def view():
    world = World.load(config_file("sim_world.yaml"))
    optics = camera_optics(WIDTH, HEIGHT)
    head = RenderedHead(Renderer(world, seed=5), optics, front_pose(world, "busbar_support", DISTANCE_M),
                        SENSOR_HEIGHT_M, WIDTH, HEIGHT, ThermalRenderer(world, seed=5))
    head.set_angles(0.0, -15.0)   # up at the clamps, 2.7 m high, from 4 m
    head.set_zoom(1.5)
    targets = [dict(spec, name=spec["name"]) for spec in world_specs(world, head)
               if spec["kind"] == "thermal" and spec.get("device") == DEVICE]
    return world, head, targets


def test_the_clamp_row_is_in_view_with_its_ambient_plate(view):
    _world, _head, targets = view
    assert sorted(t["phase"] for t in targets) == ["A", "B", "C", "ambient"]
    assert all(t.get("equipment_class", "connector") == "connector" for t in targets)


def test_each_day_is_graded_as_its_true_temperatures_are(view):
    world, head, targets = view
    rule = DEFAULT_RULES["connector"]
    phases = dict((t["phase"], t["name"]) for t in targets if t["phase"] != "ambient")
    ambient = next(t["name"] for t in targets if t["phase"] == "ambient")
    graded, crossings, previous = [], [], ""
    try:
        for day in range(0, 13):
            assert world.set_value("day", str(day)) == day
            frame = head.thermal_renderer.render(head.thermal_camera())
            values = [read_thermal_max(frame, quads_from_flat(t["thermal_box"])[0], t["phase"]).value
                      for t in targets]
            for target, value in zip(targets, values):
                assert abs(value - world.hot_spots[target["name"]].temperature) < 0.5, (day, target["name"], value)
            findings = thermal_findings(targets, values)
            hot = findings[[t["name"] for t in targets].index(HOT)]
            truth = diagnose(dict((p, world.hot_spots[n].temperature) for p, n in phases.items()),
                             world.hot_spots[ambient].temperature, rule, "connector")
            assert hot["diagnosis"]["hot_phase"] == "A" or truth.grade == "", (day, hot)
            assert hot["grade"] == truth.grade, (day, hot["diagnosis"]["rule"], truth.rule)
            graded.append(hot["grade"])
            if hot["grade"] != previous:
                crossings.append((day, hot["grade"], hot["diagnosis"]["rule"]))
            previous = hot["grade"]
    finally:
        world.set_value("day", "0")
    # the world is built to cross every boundary of the connector class, a day apart from each
    assert [(d, g) for d, g, _rule in crossings] == [(1, "general"), (6, "serious"), (10, "critical")], crossings
    assert "dt" in crossings[0][2] and "hot spot 81." in crossings[1][2] and "C > 80 C" in crossings[1][2] \
        and "hot spot 111." in crossings[2][2] and "C > 110 C" in crossings[2][2], crossings
    assert graded[0] == ""


def test_the_day_is_a_whole_number_in_range_and_a_hand_set_spot_lasts_until_it_changes():
    world = World.load(config_file("sim_world.yaml"))
    for bad in ("-1", "3651", "two", "1.5"):
        with pytest.raises(WorldError):
            world.set_value("day", bad)
    assert world.get_value("day") == 0 and world.hot_spots[HOT].temperature == 36.5
    world.set_value(HOT, "50")
    assert world.hot_spots[HOT].temperature == 50.0
    world.set_value("day", "2")
    assert world.hot_spots[HOT].temperature == 51.5 and world.hot_spots["busbar_support/clamp_b"].temperature == 36.0
    assert world.values()["day"] == 2
    world.apply_values({HOT: 60.0, "day": 3})   # the day first: a value beside it is that day's
    assert world.hot_spots[HOT].temperature == 60.0
