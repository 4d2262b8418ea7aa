"""The simulated world's foreign-object hook (sim.world ForeignObject, drawn by sim.render) and
foreign-object detection on it end to end without ROS: present -> detected, absent -> not."""
import math
import os

import cv2
import numpy as np
import pytest

from inspection_robot.inspection.calibration import calibrate
from inspection_robot.inspection.finder import Finder
from inspection_robot.inspection.locate import Locator
from inspection_robot.inspection.preset import load_preset
from inspection_robot.inspection.reading import ScaleReader
from inspection_robot.sim.inspection_sim import world_specs
from inspection_robot.sim.render import PinholeCamera, Renderer, ground_truth
from inspection_robot.sim.world import World, WorldError
from inspection_robot_testing.world_views import front_pose, recorded_preset

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
WIDTH, HEIGHT = 800, 450
NEST = "breaker_1,front,0.22,1.66,0.22,0.16"


@pytest.fixture()
def world():
    return World.load(os.path.join(ROOT, "config", "sim_world.yaml"))


def test_foreign_object_values_are_validated(world):
    assert world.set_value("foreign/nest", " %s " % NEST) == NEST
    assert world.values()["foreign/nest"] == NEST
    assert world.set_value("foreign/nest", "") == ""
    assert world.values()["foreign/nest"] == ""          # stays listed so the renderers hear the removal
    for bad in ("breaker_9,front,0,1,0.1,0.1", "breaker_1,top,0,1,0.1,0.1", "breaker_1,front,0,1,0,0.1",
                "breaker_1,front,0,1,x,0.1", "breaker_1,front,0,1", "breaker_1,front,0,1,3,0.1"):
        with pytest.raises(WorldError):
            world.set_value("foreign/nest", bad)
    with pytest.raises(WorldError):
        world.set_value("foreign/", NEST)


def test_foreign_object_is_drawn_where_the_ground_truth_says(world):
    renderer = Renderer(world, seed=1, noise_sigma=0.0, lighting_variation=0.0)
    camera = PinholeCamera.from_pose(front_pose(world, "breaker_1", 3.0), 0.0, math.radians(-8.0), 1.2, 700.0,
                                     WIDTH, HEIGHT)
    before = renderer.render(camera, frame_index=0)
    world.set_value("foreign/nest", NEST)
    after = renderer.render(camera, frame_index=0)
    entry = ground_truth(world, camera)["foreign"]["foreign/nest"]
    assert entry["visible"]
    changed = np.any(cv2.absdiff(before, after) > 30, axis=2)
    ys, xs = np.nonzero(changed)
    corners = np.asarray(entry["corners"])
    assert xs.min() >= corners[:, 0].min() - 2 and xs.max() <= corners[:, 0].max() + 2
    assert ys.min() >= corners[:, 1].min() - 2 and ys.max() <= corners[:, 1].max() + 2
    assert changed.sum() > 0.5 * cv2.contourArea(corners.astype(np.float32))
    world.set_value("foreign/nest", "")
    assert np.array_equal(renderer.render(camera, frame_index=0), before)


def test_find_both_then_read_detects_the_foreign_object_only_when_present(tmp_path, world):
    presets, pictures = str(tmp_path / "presets"), str(tmp_path / "pictures")
    path, head, optics, pose = recorded_preset(world, presets, "b1", "breaker_1", 3.5, 1.6, 2.0, WIDTH, HEIGHT)
    calibrate(path, world_specs(world, head, switch_picture_path=str(tmp_path / "%s_%s.png")), optics)
    preset = load_preset(path)
    back = (pose[0] + 0.3 * math.sin(pose[2]), pose[1] - 0.3 * math.cos(pose[2]), pose[2] + math.radians(5.0))
    head.pose = back
    finder = Finder(head, optics, Locator("orb"), pictures, max_moves=4)
    reader = ScaleReader([presets], [pictures], pictures)
    counts = []
    for i, placement in enumerate((NEST, "")):
        world.set_value("foreign/nest", placement)
        stamp = "20260102_00000%d" % i
        found = finder.find(preset, "find_foreign", math.degrees(pose[2] - back[2]), stamp, cv2.imread)
        assert found.filename == "" and found.roi_vertex == []
        out = reader.read(path, 1, [], [found.foreign_filename], [], [], stamp)
        counts.append(out.foreign_scale[0])
        assert 0 <= out.foreign_possibility[0] <= 100
    assert counts == [1.0, 0.0], counts
