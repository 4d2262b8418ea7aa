"""The simulated world and its renderers: projection geometry, determinism, thermal truth, values."""
import math
import os

import numpy as np
import pytest

from inspection_robot.camera.optics import ZoomOptics
from inspection_robot.sim.render import PinholeCamera, Renderer, ThermalRenderer, ground_truth
from inspection_robot.thermal.commands import false_colour
from inspection_robot.sim.world import World, WorldError

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
TABLE = [[1.0, 59.8], [2.0, 31.6], [4.0, 16.2], [8.0, 8.2], [16.0, 4.1], [30.0, 2.2]]
WIDTH, HEIGHT = 320, 180


@pytest.fixture(scope="module")
def world():
    return World.load(os.path.join(ROOT, "config", "sim_world.yaml"))


def aim_at(world, quad, distance, zoom, width=WIDTH, height=HEIGHT, focal=None):
    """A camera ``distance`` m in front of ``quad`` (along its normal), optical axis through its centre."""
    x, y, z = quad.centre
    nx, ny = quad.normal[0], quad.normal[1]
    pose = (x + nx * distance, y + ny * distance, math.atan2(-ny, -nx))
    tilt = math.atan2(world.sensor_height - z, distance)
    focal = ZoomOptics(TABLE, 1920, 1080).focal_px(zoom, width) if focal is None else focal
    return PinholeCamera.from_pose(pose, 0.0, tilt, world.sensor_height, focal, width, height)


@pytest.mark.parametrize("pan_deg,tilt_deg,zoom", [(0, 0, 1), (30, 10, 2), (-75, -20, 4), (170, 45, 16), (-120, 5, 30)])
def test_world_point_lands_where_the_pinhole_model_says(pan_deg, tilt_deg, zoom):
    optics = ZoomOptics(TABLE, 1920, 1080)
    pose = (3.0, -2.0, 0.7)
    cam = PinholeCamera.from_pose(pose, math.radians(pan_deg), math.radians(tilt_deg), 1.2,
                                  optics.focal_px(zoom, 1920), 1920, 1080)
    heading, tilt = pose[2] + math.radians(pan_deg), math.radians(tilt_deg)
    forward = np.array([math.cos(heading) * math.cos(tilt), math.sin(heading) * math.cos(tilt), -math.sin(tilt)])
    left = np.array([-math.sin(heading), math.cos(heading), 0.0])
    up = np.cross(forward, left)
    centre = np.array([3.0, -2.0, 1.2])
    # a point 10 m ahead, 0.05 m to the left and 0.02 m up: left of and above the centre
    point = centre + 10.0 * forward + 0.05 * left + 0.02 * up
    uv, depth = cam.project(point)
    focal = optics.focal_px(zoom, 1920)
    assert depth[0] == pytest.approx(10.0)
    assert uv[0][0] == pytest.approx(960 - focal * 0.05 / 10.0)
    assert uv[0][1] == pytest.approx(540 - focal * 0.02 / 10.0)
    # the picture edge is half the horizontal field of view away from the axis
    half = math.radians(optics.hfov_deg(zoom) / 2.0)
    edge = centre + math.cos(half) * forward - math.sin(half) * left
    assert cam.project(edge)[0][0][0] == pytest.approx(1920.0)


def test_pan_is_counter_clockwise_and_tilt_down_positive(world):
    cam = PinholeCamera.from_pose((0.0, 0.0, 0.0), math.radians(90), math.radians(30), 1.2, 500, 640, 480)
    uv, depth = cam.project([0.0, 10.0, 1.2 - 10.0 * math.tan(math.radians(30))])
    assert depth[0] > 0
    assert uv[0] == pytest.approx([320, 240])


def test_ground_truth_gauge_scales_with_zoom(world):
    face = world.faces["transformer_1/oil_temp"]
    sizes = {}
    for zoom in (2.0, 8.0):
        cam = aim_at(world, face.quad, 5.0, zoom, 1920, 1080)
        truth = ground_truth(world, cam)["faces"][face.id]
        assert truth["visible"]
        assert truth["center"] == pytest.approx([960, 540])
        corners = np.array(truth["corners"])
        sizes[zoom] = np.linalg.norm(corners[1] - corners[0])
        expected = cam.focal_px * face.quad.width / 5.0
        assert sizes[zoom] == pytest.approx(expected, rel=0.01)
    optics = ZoomOptics(TABLE, 1920, 1080)
    assert sizes[8.0] / sizes[2.0] == pytest.approx(optics.focal_px(8.0) / optics.focal_px(2.0), rel=0.01)


def test_rendered_needle_is_dark_on_a_white_dial_and_moves_with_the_value(world):
    face = world.faces["transformer_1/oil_temp"]
    cam = aim_at(world, face.quad, 4.0, 1.0, 320, 320, focal=900)
    renderer = Renderer(world, seed=3, noise_sigma=0, blur_sigma=0, lighting_variation=0)
    old = face.value
    try:
        for value in (0.0, 100.0):
            face.set_value(value)
            truth = ground_truth(world, cam)["faces"][face.id]
            img = renderer.render(cam).astype(int)
            pivot, tip = np.array(truth["pivot"]), np.array(truth["needle_tip"])
            mid = pivot + 0.6 * (tip - pivot)
            across = pivot + 0.6 * np.array([-(tip - pivot)[0], (tip - pivot)[1]])   # mirrored: dial only
            assert img[int(round(mid[1])), int(round(mid[0]))].sum() < 200
            assert img[int(round(across[1])), int(round(across[0]))].sum() > 450
    finally:
        face.set_value(old)


def test_renderer_is_deterministic_for_a_seed(world):
    cam = PinholeCamera.from_pose(world.start_pose, 0.1, 0.05, world.sensor_height, 300, WIDTH, HEIGHT)
    first = Renderer(world, seed=11).render(cam, frame_index=4)
    again = Renderer(world, seed=11).render(cam, frame_index=4)
    other = Renderer(world, seed=12).render(cam, frame_index=4)
    assert first.shape == (HEIGHT, WIDTH, 3) and first.dtype == np.uint8
    assert np.array_equal(first, again)
    assert not np.array_equal(first, other)
    assert first.std() > 10   # structure, not a flat picture


def test_thermal_spot_max_min_match_the_world(world):
    spot = world.hot_spots["busbar_support/joint"]
    cam = aim_at(world, spot.quad, 6.0, 1.0, 384, 288, focal=384 / 2.0 / math.tan(math.radians(12.5)))
    frame = ThermalRenderer(world, seed=1, noise_sigma=0.0).render(cam)
    truth = ground_truth(world, cam)["hot_spots"][spot.id]
    assert truth["visible"] and truth["radius_px"] > 2
    u, v = (int(round(c)) for c in truth["center"])
    assert frame[v, u] == pytest.approx(95.0, abs=0.05)
    assert frame.max() == pytest.approx(95.0, abs=0.05)
    assert frame.min() == pytest.approx(world.sky_c, abs=0.05)   # looking up: sky in the top rows
    old = spot.value
    try:
        world.set_value(spot.id, "120.5")
        hotter = ThermalRenderer(world, seed=1, noise_sigma=0.05).render(cam)
        assert hotter[v, u] == pytest.approx(120.5, abs=0.3)
    finally:
        spot.set_value(old)
    colour = false_colour(frame)
    assert colour.shape == (288, 384, 3)


@pytest.mark.parametrize("item,value", [
    ("transformer_1/oil_temp", "abc"), ("transformer_1/oil_temp", "141"), ("transformer_1/oil_temp", "nan"),
    ("breaker_1/lamp_open", "blinking"), ("breaker_1/position", "on"), ("busbar_support/joint", "9999"),
    ("cabinet_1/temp_controller", "151"), ("cabinet_1/temp_controller", "-20.5"), ("cabinet_1/temp_controller", "x"),
    ("no_such/face", "1")])
def test_bad_world_values_are_refused(world, item, value):
    with pytest.raises(WorldError):
        world.set_value(item, value)


def test_world_values_round_trip(world):
    assert world.set_value("breaker_1/lamp_open", "on") == "on"
    assert world.set_value("breaker_2/position", "closed") == "closed"
    assert world.values()["breaker_2/position"] == "closed"
    world.apply_values({"breaker_1/lamp_open": "off", "breaker_2/position": "open"})
    assert world.get_value("breaker_1/lamp_open") == "off"


def test_a_display_shows_its_value_right_aligned_at_its_places(world):
    display = world.faces["cabinet_1/temp_controller"]
    assert display.display_text() == " 36.4"
    assert world.set_value("cabinet_1/temp_controller", "-7.34") == -7.3 and display.display_text() == " -7.3"
    assert display.display_text(123.4) == "123.4"


def test_malformed_world_descriptions_are_refused():
    base = {"equipment": [{"id": "a", "position": [0, 0, 0], "footprint": [1, 1], "height": 1}]}
    bad_faces = [{"id": "a/g", "equipment": "a", "side": "top", "center": [0, 1], "size": [0.2, 0.2], "type": "lamp"},
                 {"id": "a/g", "equipment": "b", "side": "front", "center": [0, 1], "size": [0.2, 0.2],
                  "type": "lamp", "value": "on"},
                 {"id": "a/g", "equipment": "a", "side": "front", "center": [0, 1], "size": [0.2, 0.2],
                  "type": "gauge", "range": [5, 1], "value": 2},
                 {"id": "a/d", "equipment": "a", "side": "front", "center": [0, 1], "size": [0.2, 0.1],
                  "type": "display", "digits": 2, "decimals": 2, "range": [0, 9], "value": 1},
                 {"id": "a/d", "equipment": "a", "side": "front", "center": [0, 1], "size": [0.2, 0.1],
                  "type": "display", "polarity": "green", "range": [0, 9], "value": 1}]
    for face in bad_faces:
        with pytest.raises(WorldError):
            World(dict(base, faces=[face]))
