"""The pipeline end to end on the simulated yard without ROS: record, calibrate from ground truth,
come back with a pose error, find, read; every reading checked against the world's truth."""
import math
import os

import cv2
import numpy as np
import pytest
import yaml

from inspection_robot.camera.optics import ZoomOptics
from inspection_robot.inspection.calibration import calibrate
from inspection_robot.inspection.finder import Cancelled, Finder, FindError, ThermalGeometry
from inspection_robot.inspection.gauge import GaugeScale
from inspection_robot.inspection.locate import Locator
from inspection_robot.inspection.preset import load_preset
from inspection_robot.inspection.reading import ScaleReader
from inspection_robot.inspection.pointer import PointerReader
from inspection_robot.inspection.recorder import record_preset, zoom_ladder
from inspection_robot.sim.inspection_sim import RenderedHead, world_specs
from inspection_robot.sim.render import Renderer, ThermalRenderer
from inspection_robot.sim.world import World

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
WIDTH, HEIGHT = 800, 450


def _optics():
    with open(os.path.join(ROOT, "config", "camera_optics.yaml")) as f:
        table = yaml.safe_load(f)["camera_optics"]
    return ZoomOptics(table["zoom_hfov_deg"], WIDTH, HEIGHT)


def test_zoom_ladder():
    assert zoom_ladder(8.0, 1.0) == [8.0, 4.0, 2.0, 1.0]
    assert zoom_ladder(1.0, 1.0) == [1.0]
    assert zoom_ladder(3.0, 1.0) == [3.0, 1.5, 1.0]
    assert len(zoom_ladder(30.0, 1.0)) == 6


def _aim(face, dist):
    normal = face.quad.normal
    spot = face.quad.centre + normal * dist
    tilt = math.degrees(math.atan2(1.2 - face.quad.centre[2], dist))
    return (spot[0], spot[1], math.atan2(-normal[1], -normal[0])), tilt


@pytest.fixture(scope="module")
def yard():
    world = World.load(os.path.join(ROOT, "config", "sim_world.yaml"))
    return world, Renderer(world, seed=3), ThermalRenderer(world, seed=3)


@pytest.mark.parametrize("face_id,dist,zoom", [("breaker_1/sf6_pressure", 3.0, 4.0),
                                               ("transformer_1/oil_level", 4.0, 3.0),
                                               ("breaker_2/sf6_pressure", 3.5, 2.0)])   # + lamps, switch
def test_record_find_read_with_pose_error(tmp_path, yard, face_id, dist, zoom):
    world, renderer, thermal = yard
    optics = _optics()
    face = world.faces[face_id]
    pose, tilt = _aim(face, dist)
    head = RenderedHead(renderer, optics, pose, 1.2, WIDTH, HEIGHT, thermal)
    head.set_angles(0.0, tilt)
    head.set_zoom(zoom)
    presets, pictures = str(tmp_path / "presets"), str(tmp_path / "pictures")
    state = {"pan_deg": 0.0, "tilt_deg": tilt, "zoom": zoom, "focus_position": 0x5000, "pose": pose}
    path = record_preset(head, presets, "p1", "20260101_100000", state)
    specs = world_specs(world, head, switch_picture_path=str(tmp_path / "%s_%s.png"))
    assert any(s["kind"] == "pointer" for s in specs)
    if face_id.startswith("breaker_2"):
        assert sorted(s["kind"] for s in specs) == ["digital", "lamp", "lamp", "pointer", "switch"]   # + a drum
    calibrate(path, specs, optics)
    preset = load_preset(path)
    # values change, the robot comes back 0.3 m / 5 deg off
    truth = {}
    for spec in specs:
        f = world.faces[spec["name"]]
        if f.type == "gauge":
            truth[f.id] = f.set_value(f.range[0] + 0.37 * (f.range[1] - f.range[0]))
        elif f.type == "lamp":
            truth[f.id] = f.set_value("off" if f.value == "on" else "on")
        elif f.type == "switch":
            truth[f.id] = f.set_value("open" if f.value == "closed" else "closed")
        elif f.type == "display":
            truth[f.id] = f.set_value(f.value + 5)
    back = (pose[0] + 0.3 * math.sin(pose[2]), pose[1] - 0.3 * math.cos(pose[2]), pose[2] + math.radians(5))
    head.pose = back
    events = []
    finder = Finder(head, optics, Locator("orb"), pictures, max_moves=4, feedback=lambda c, d: events.append((c, d)))
    correction = math.degrees(pose[2] - back[2])
    result = finder.find(preset, "find_both", correction, "20260102_100000", cv2.imread)
    # spec order: "0" preset set (with the heading correction applied), then "1" finding
    assert events[0] == ("0", {"pan": events[0][1]["pan"], "tilt": round(tilt, 2), "zoom": zoom,
                               "heading_correction_deg": round(correction, 2)})
    assert [c for c, _ in events[1:]] == ["1"] * (len(events) - 1) and len(events) >= 2
    assert os.path.basename(result.filename).startswith("zoom0_20260102_100000_")
    assert len(result.roi_vertex) == 8 * len(preset.targets)
    assert result.foreign_filename
    # the second look: the found view again, a new picture (its own sensor noise) from the same pose
    assert result.second_filename == result.filename.replace(".jpg", "_look2.jpg")
    assert not np.array_equal(cv2.imread(result.filename), cv2.imread(result.second_filename))
    reader = ScaleReader([presets], [pictures], pictures)
    out = reader.read(path, 2, [result.filename, result.second_filename], [result.foreign_filename],
                      result.roi_vertex, [], "20260102_100001")
    assert out.uncertain == [""] * len(preset.targets), out.uncertain   # the two looks agree
    for target, value in zip(preset.targets, out.scale):
        f = world.faces[target.name]
        if f.type == "gauge":
            assert abs(value - truth[f.id]) / (f.range[1] - f.range[0]) * 100 < 1.0, (f.id, value, truth[f.id])
        elif f.type == "lamp":
            assert (value > 0) == (truth[f.id] == "on"), (f.id, value)
        elif f.type == "display":
            assert value == truth[f.id], (f.id, value)
        else:
            assert value == (1.0 if truth[f.id] == "closed" else 0.0), (f.id, value)
    assert out.foreign_scale == [0.0], out.foreign_picture_path


def test_find_fails_with_a_reason_when_the_view_is_gone(tmp_path, yard):
    world, renderer, _thermal = yard
    optics = _optics()
    face = world.faces["breaker_1/sf6_pressure"]
    pose, tilt = _aim(face, 3.0)
    head = RenderedHead(renderer, optics, pose, 1.2, WIDTH, HEIGHT)
    head.set_angles(0.0, tilt)
    head.set_zoom(4.0)
    state = {"pan_deg": 0.0, "tilt_deg": tilt, "zoom": 4.0, "pose": pose}
    path = record_preset(head, str(tmp_path), "p2", "20260101_100000", state)
    calibrate(path, world_specs(world, head), optics)
    head.pose = (pose[0], pose[1], pose[2] + math.pi)   # facing away, and we claim no correction
    finder = Finder(head, optics, Locator("orb"), str(tmp_path / "pic"), max_moves=2)
    with pytest.raises(FindError) as err:
        finder.find(load_preset(path), "find_scale", 0.0, "20260102_000000", cv2.imread)
    assert "not found" in str(err.value)
    cancelled = Finder(head, optics, Locator("orb"), str(tmp_path / "pic"), is_cancelled=lambda: True)
    with pytest.raises(Cancelled):
        cancelled.find(load_preset(path), "find_scale", 0.0, "20260102_000001", cv2.imread)
    assert ThermalGeometry(500, 384, 288).width == 384


@pytest.mark.parametrize("shift,turn_deg", [(0.0, 0.0), (0.1, 0.0), (-0.1, 3.0)])
def test_red_needle_beside_a_white_number_reads_its_own_line(yard, shift, turn_deg):
    # issue 19: winding_temp (black dial, red needle) at 18 % of its scale lies 3 deg from the
    # white "25": fitted to every pixel unlike the dial, the needle's outer half leaned onto the
    # number and read 1.1-1.3 % FS low at the e2e preset (3 m, zoom 1.5)
    world, renderer, _thermal = yard
    face = world.faces["transformer_1/winding_temp"]
    state = face.value
    truth = face.set_value(face.range[0] + 0.18 * (face.range[1] - face.range[0]))
    try:
        pose, tilt = _aim(face, 3.0)
        head = RenderedHead(renderer, _optics(), (pose[0] + shift, pose[1], pose[2] + math.radians(turn_deg)),
                            1.2, WIDTH, HEIGHT)
        head.set_angles(0.0, tilt)
        head.set_zoom(1.5)
        spec = [s for s in world_specs(world, head) if s["name"] == face.id][0]
        scale = GaugeScale(spec["start_angle"], spec["end_angle"], spec["start_value"], spec["end_value"])
        reading = PointerReader().read(renderer.render(head.camera()), np.reshape(spec["box"], (4, 2)), scale,
                                       spec["centre"], spec["radius"], spec["aspect"])
    finally:
        face.set_value(state)
    assert scale.error_percent_fs(reading.value, truth) < 0.5, reading
    assert reading.confidence >= 80, reading


def _panel_preset(tmp_path, world):
    """patrol_sim's cabinet_1 preset (inspection_robot_testing.yard_patrol.YARD_STOPS): the stop's
    pose, aimed 1.55 m high from 3 m, zoom 2, the simulator's 1920x1080 camera; calibrated from
    ground truth."""
    optics = ZoomOptics(yaml.safe_load(open(os.path.join(ROOT, "config", "camera_optics.yaml")))
                        ["camera_optics"]["zoom_hfov_deg"], 1920, 1080)
    stop = (20.0, 21.4, math.pi / 2)
    tilt = math.degrees(math.atan2(world.sensor_height - 1.55, 3.0))
    head = RenderedHead(Renderer(world, seed=0), optics, stop, world.sensor_height, 1920, 1080)
    head.set_angles(0.0, tilt)
    head.set_zoom(2.0)
    path = record_preset(head, str(tmp_path), "cabinet_1", "20260101_000000",
                         {"pan_deg": 0.0, "tilt_deg": tilt, "zoom": 2.0, "pose": stop}, min_zoom=optics.min_zoom)
    calibrate(path, world_specs(world, head), optics)
    return path, optics, stop


def test_panel_meters_read_within_half_a_percent_after_the_patrol_stop(tmp_path):
    """issue 26.6: patrol_sim read cabinet_1/voltmeter 10.36 kV for 10.5 (1.1 % FS). On a 90 deg
    panel meter 1 % FS is 0.9 deg: the numeral "10" beside the needle pulled its line (0.5 % FS
    low on average), and the box matched at half the picture's size was 1-3 px off (up to 1 %
    FS). Back at the stop 0.15 m / 3 deg off, found and read with two looks as a patrol does,
    both panel meters read within 0.5 % FS (before: 39 of 80 such reads beyond it)."""
    from inspection_robot.inspection.reading import request_filenames
    world = World.load(os.path.join(ROOT, "config", "sim_world.yaml"))
    path, optics, stop = _panel_preset(tmp_path, world)
    preset = load_preset(path)
    reader = ScaleReader([str(tmp_path)], [str(tmp_path)], str(tmp_path / "out"))
    rng = np.random.default_rng(26)
    worst = (0.0, None)
    for k in range(8):
        back = (stop[0] + rng.uniform(-0.15, 0.15), stop[1] + rng.uniform(-0.15, 0.15),
                stop[2] + math.radians(rng.uniform(-3.0, 3.0)))
        head = RenderedHead(Renderer(world, seed=100 + k), optics, back, world.sensor_height, 1920, 1080)
        found = Finder(head, optics, Locator("orb"), str(tmp_path / "pic"), max_moves=3).find(
            preset, "find_scale", math.degrees(stop[2] - back[2]), "20260102_%06d" % k, cv2.imread)
        files = request_filenames([t.kind for t in preset.targets], found.filename, "", found.second_filename)
        out = reader.read(path, 0, files, [], found.roi_vertex, [], "20260102_%06d" % k)
        for target, value, why in zip(preset.targets, out.scale, out.uncertain):
            face = world.faces[target.name]
            if face.type == "gauge":
                assert why == "", (target.name, why)
                error = 100.0 * abs(value - face.value) / (face.range[1] - face.range[0])
                worst = max(worst, (error, (target.name, k, value, face.value)))
    assert worst[0] < 0.5, worst


def test_a_numeral_beside_the_needle_does_not_pull_its_line():
    """The voltmeter's face painted frontally at 400 px, the needle swept across its numerals
    (black on white, like the needle: colour cannot tell them apart): the centroid at each radius
    follows only the needle's own run of pixels and the line drops the radii a numeral shifts,
    so every reading stays within 0.6 % FS (before: up to 1.3 % FS beside a numeral)."""
    from inspection_robot.sim.faces import paint_face
    world = World.load(os.path.join(ROOT, "config", "sim_world.yaml"))
    face = world.faces["cabinet_1/voltmeter"]
    low, high = face.range
    scale = GaugeScale(face.start_angle, face.end_angle, low, high)
    fx, fy, radius_m = face.dial_layout()
    reader, worst = PointerReader(), (0.0, None)
    for value in np.linspace(low + 0.02 * (high - low), high - 0.02 * (high - low), 25):
        face.set_value(float(value))
        image = paint_face(face, 400)
        h, w = image.shape[:2]
        quad = np.array([[-0.5, -0.5], [w - 0.5, -0.5], [w - 0.5, h - 0.5], [-0.5, h - 0.5]])   # pixel edges
        reading = reader.read(image, quad, scale, (fx, fy), radius_m / face.quad.width,
                              face.quad.width / face.quad.height)
        worst = max(worst, (scale.error_percent_fs(reading.value, value), value, reading.value))
    assert worst[0] < 0.6, worst


class SettlingHead(RenderedHead):
    """The robot still turning after its arrival: after each picture its heading moves on by the
    next of ``turns`` (deg); each picture's camera is kept to check the boxes found in it."""

    def __init__(self, turns, *args, **kwargs):
        super(SettlingHead, self).__init__(*args, **kwargs)
        self.turns, self.cameras = list(turns), {}

    def capture(self, path):
        self.cameras[path] = self.camera()
        image = super(SettlingHead, self).capture(path)
        x, y, yaw = self.pose
        self.pose = (x, y, yaw + math.radians(self.turns.pop(0) if self.turns else 0.0))
        return image


@pytest.mark.parametrize("turns,settles", [([0.7, 0.5], True), ([0.6] * 40, False)])
def test_a_view_that_moves_before_the_second_look_is_found_again(tmp_path, turns, settles):
    """Simulated patrols had 4 of 762 second looks 45-83 px over their found picture (the robot
    still settling after its arrival); read_scale then read the second look at boxes found in the
    first. Now the second look is checked against the found picture: a view that moved is found
    again in the later picture and looked at once more; one that never holds still gives no second
    look. Either way the boxes are those of the picture returned as found."""
    from inspection_robot.inspection.finder import STILL_SHIFT
    from inspection_robot.inspection.locate import view_shift
    from inspection_robot.sim.render import ground_truth
    world = World.load(os.path.join(ROOT, "config", "sim_world.yaml"))
    path, optics, stop = _panel_preset(tmp_path, world)
    preset = load_preset(path)
    # back at the stop as recorded: the first picture is the found one, then the robot turns
    head = SettlingHead(turns, Renderer(world, seed=7), optics, stop, world.sensor_height, 1920, 1080)
    found = Finder(head, optics, Locator("orb"), str(tmp_path / "pic"), max_moves=3).find(
        preset, "find_scale", 0.0, "20260103_000000", cv2.imread)
    if settles:
        assert found.filename.endswith("_00_still2.jpg") and found.second_filename, found
        first, second = cv2.imread(found.filename), cv2.imread(found.second_filename)
        assert view_shift(first, second) <= STILL_SHIFT * first.shape[1]
    else:
        assert found.second_filename == "", found
    # a found picture "<base>_still<k>.jpg" was taken as the second look of the one before it
    base, k = found.filename[:-len(".jpg")].rsplit("_still", 1) if "_still" in found.filename else (None, 0)
    taken_as = found.filename if base is None else \
        "%s%s_look2.jpg" % (base, "_still%d" % (int(k) - 1) if int(k) > 1 else "")
    truth = ground_truth(world, head.cameras[taken_as])["faces"]
    pointers = [(t, k) for t, k in zip(preset.targets, range(0, len(found.roi_vertex), 8)) if t.kind == "pointer"]
    assert len(pointers) == 2
    for target, k in pointers:   # a gauge's box is its face (a display's, the digits' window in it)
        if target.name in truth:
            box = np.reshape(found.roi_vertex[k:k + 8], (4, 2))
            assert np.abs(box - np.asarray(truth[target.name]["corners"])).max() < 6.0, target.name
