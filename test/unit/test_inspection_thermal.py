"""Thermal presets end to end without ROS: the thermal box mapping of the finder against the
rendered ground truth after a pose error, and the maximum temperature read in it."""
import math
import os

import cv2
import numpy as np
import pytest
import yaml

from inspection_robot.camera.optics import ZoomOptics
from inspection_robot.inspection.calibration import calibrate
from inspection_robot.inspection.finder import Finder, ThermalGeometry
from inspection_robot.inspection.geometry import quads_from_flat
from inspection_robot.inspection.locate import Locator
from inspection_robot.inspection.preset import load_preset
from inspection_robot.inspection.reading import ScaleReader
from inspection_robot.inspection.recorder import record_preset
from inspection_robot.camera.optics import focal_for_hfov
from inspection_robot.sim.inspection_sim import RenderedHead, world_specs
from inspection_robot.sim.render import Renderer, ThermalRenderer, ground_truth
from inspection_robot.sim.world import World

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
WIDTH, HEIGHT = 800, 450
SPOT = "breaker_1/terminal"


def test_visible_thermal_pixel_map_round_trip():
    geo = ThermalGeometry(800.0, 384, 288, offset_px=(3.0, -2.0))
    pts = np.array([[0.0, 0.0], [799.0, 449.0], [399.5, 224.5]])
    thermal = geo.from_visible(pts, 1600.0, 800, 450)
    # the visible optical axis lands on the thermal centre + offset, at half the scale
    assert np.allclose(thermal[2], [191.5 + 3.0, 143.5 - 2.0])
    assert np.allclose(thermal[1] - thermal[2], (pts[1] - pts[2]) * 0.5)
    assert np.allclose(geo.to_visible(thermal, 1600.0, 800, 450), pts)


@pytest.mark.parametrize("lateral_m,dyaw_deg,temperature", [(0.3, 5.0, 71.5), (-0.3, -5.0, 38.0)])
def test_thermal_box_follows_the_hot_spot_after_a_pose_error(tmp_path, lateral_m, dyaw_deg, temperature):
    with open(os.path.join(ROOT, "config", "camera_optics.yaml")) as f:
        table = yaml.safe_load(f)["camera_optics"]
    optics = ZoomOptics(table["zoom_hfov_deg"], WIDTH, HEIGHT)
    world = World.load(os.path.join(ROOT, "config", "sim_world.yaml"))
    head_renderer, thermal_renderer = Renderer(world, seed=3), ThermalRenderer(world, seed=3)
    spot = world.hot_spots[SPOT]
    normal = spot.quad.normal
    p = spot.quad.centre + normal * 3.5
    pose = (p[0], p[1], math.atan2(-normal[1], -normal[0]))
    tilt = math.degrees(math.atan2(1.2 - 1.9, 3.5))
    head = RenderedHead(head_renderer, optics, pose, 1.2, WIDTH, HEIGHT, thermal_renderer)
    head.set_angles(0.0, tilt)
    head.set_zoom(1.5)
    state = {"pan_deg": 0.0, "tilt_deg": tilt, "zoom": 1.5, "focus_position": 0, "pose": pose}
    path = record_preset(head, str(tmp_path / "presets"), "b1", "20260101_000000", state, infrared=True)
    assert os.path.isfile(os.path.join(path, "thermal.jpg"))
    frame = cv2.imread(os.path.join(path, "thermal.png"), cv2.IMREAD_UNCHANGED)
    assert frame.dtype == np.uint16 and frame.shape == (288, 384)
    specs = world_specs(world, head)
    assert [s["name"] for s in specs if s["kind"] == "thermal"] == [SPOT]
    calibrate(path, specs, optics)
    preset = load_preset(path)

    world.set_value(SPOT, temperature)
    back = (pose[0] + lateral_m * math.sin(pose[2]), pose[1] - lateral_m * math.cos(pose[2]),
            pose[2] + math.radians(dyaw_deg))
    head.pose = back
    geometry = ThermalGeometry(focal_for_hfov(384, 25.0), 384, 288)
    finder = Finder(head, optics, Locator("orb"), str(tmp_path / "pictures"), max_moves=4, thermal=geometry)
    result = finder.find(preset, "find_scale", math.degrees(pose[2] - back[2]), "20260102_000000", cv2.imread)
    assert result.infrared_filename.endswith(".png")
    (box,) = quads_from_flat(result.infrared_roi_vertex)
    truth = ground_truth(world, head.thermal_camera())["hot_spots"][SPOT]
    error = np.linalg.norm(box.mean(axis=0) - truth["center"])
    assert error < 3.0, (error, box, truth)   # px; the hot core's radius is ~14 px
    reader = ScaleReader([str(tmp_path / "presets")], [str(tmp_path / "pictures")], str(tmp_path / "pictures"))
    out = reader.read(path, 0, [result.filename, result.infrared_filename], [], result.roi_vertex,
                      result.infrared_roi_vertex, "20260102_000001")
    thermal_index = [t.kind for t in preset.targets].index("thermal")
    assert abs(out.scale[thermal_index] - temperature) < 1.0, out.scale
