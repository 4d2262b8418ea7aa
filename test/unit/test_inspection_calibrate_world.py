"""calibrate_preset --from-world: calibration from the simulated world's ground truth."""
import json
import math
import os

import cv2
import numpy as np
import pytest

from inspection_robot.inspection.calibration_commands import CalibrationCommands
from inspection_robot.inspection.preset import CALIB_INI, load_preset
from inspection_robot.inspection.recorder import record_preset
from inspection_robot.tools.calibrate_preset import run
from inspection_robot.sim.inspection_sim import RenderedHead
from inspection_robot.sim.render import Renderer, ThermalRenderer
from inspection_robot.sim.world import World
from inspection_robot_testing.world_views import camera_optics, front_pose

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
WORLD = os.path.join(ROOT, "config", "sim_world.yaml")
WIDTH, HEIGHT = 800, 450


def _true_pose(yaw_offset=0.0):
    """3.5 m in front of breaker_1, facing it (plus ``yaw_offset``)."""
    x, y, yaw = front_pose(World.load(WORLD), "breaker_1", 3.5)
    return x, y, yaw + yaw_offset


def _record(tmp_path, yaw_offset=0.0, localizer_error=(0.0, 0.0, 0.0)):
    """A preset pictured from _true_pose; preset.ini gets that pose plus ``localizer_error`` (what
    preset_scale records: the localizer's pose)."""
    optics = camera_optics(WIDTH, HEIGHT)
    world = World.load(WORLD)
    pose = _true_pose(yaw_offset)
    tilt = math.degrees(math.atan2(1.2 - 1.8, 3.5))
    head = RenderedHead(Renderer(world, seed=2), optics, pose, 1.2, WIDTH, HEIGHT, ThermalRenderer(world))
    head.set_angles(0.0, tilt)
    head.set_zoom(1.5)
    reported = tuple(v + e for v, e in zip(pose, localizer_error))
    state = {"pan_deg": 0.0, "tilt_deg": tilt, "zoom": 1.5, "focus_position": 0, "pose": reported}
    return record_preset(head, str(tmp_path), "b1", "20260101_000000", state, infrared=True)


def test_from_world_calibrates_every_face_and_hot_spot_in_view(tmp_path, capsys):
    path = _record(tmp_path)
    assert run([path, "--from-world", WORLD]) == 0
    targets = load_preset(path).targets
    kinds = dict((t.name, t.kind) for t in targets)
    assert kinds == {"breaker_1/lamp_closed": "lamp", "breaker_1/lamp_open": "lamp", "breaker_1/position": "switch",
                     "breaker_1/sf6_pressure": "pointer", "breaker_1/terminal": "thermal"}
    assert "calibrated 5 target(s)" in capsys.readouterr().out
    assert os.path.isfile(os.path.join(path, "target_%d_open.png" % [t.name for t in targets].index(
        "breaker_1/position")))
    # the default world file, and a subset
    assert run([path, "--from-world", "--only", "breaker_1/sf6_pressure,breaker_1/terminal"]) == 0
    assert [t.name for t in load_preset(path).targets] == ["breaker_1/sf6_pressure", "breaker_1/terminal"]


def test_from_world_sees_from_the_true_pose_when_given(tmp_path, capsys):
    """preset.ini holds the localizer's pose, here 4 cm and 0.7 deg off the pose the picture was taken
    from (2 sigma of sim_localizer): --pose rebuilds the view where the robot stood, so the gauge's
    box is where the picture has it; from the recorded pose the box is off by pixels."""
    path = _record(tmp_path, localizer_error=(0.03, -0.03, math.radians(0.7)))
    only = ["--only", "breaker_1/sf6_pressure"]
    boxes = {}
    for name, extra in (("recorded", []), ("true", ["--pose", "%.6f,%.6f,%.6f" % _true_pose()])):
        assert run([path, "--from-world", WORLD] + only + extra) == 0, capsys.readouterr().err
        boxes[name] = load_preset(path).targets[0].boxes[0]
    exact_dir = tmp_path / "exact"
    exact_dir.mkdir()
    exact = _record(exact_dir)
    assert run([exact, "--from-world", WORLD] + only) == 0
    truth = load_preset(exact).targets[0].boxes[0]
    assert np.abs(boxes["true"] - truth).max() < 0.5
    assert np.abs(boxes["recorded"] - truth).max() > 5.0
    with pytest.raises(SystemExit):
        run([path, "--from-world", WORLD, "--pose", "1,2"])
    with pytest.raises(SystemExit):
        run([path, "--from-world", WORLD, "--pose", "1,2,nan"])


def test_from_world_with_nothing_in_view_fails_and_writes_nothing(tmp_path, capsys):
    path = _record(tmp_path, yaw_offset=math.pi)
    assert run([path, "--from-world"]) == 1
    assert "no face or hot spot" in capsys.readouterr().err
    assert not os.path.exists(os.path.join(path, CALIB_INI))
    assert run([path, "--from-world", "--only", "nothing/here"]) == 1


def test_from_world_argument_errors(tmp_path):
    with pytest.raises(SystemExit):
        run([str(tmp_path), "targets.yaml", "--from-world"])
    with pytest.raises(SystemExit):
        run([str(tmp_path)])
    assert run([str(tmp_path / "missing"), "--from-world"]) == 1


def test_calibration_checks_itself_against_the_operators_value(tmp_path):
    """calibration_control reads the calibration picture at once: the reader's value beside the
    operator's, a calibration more than 2 % of full scale off refused by name unless forced, and a
    picture with no gauge to read refused when a value is expected; nothing written when refused."""
    path = _record(tmp_path)
    assert run([path, "--from-world", "--only", "breaker_1/sf6_pressure"]) == 0
    optics = camera_optics(WIDTH, HEIGHT)
    commands = CalibrationCommands(str(tmp_path), ["."], ["."], optics)
    preset = os.path.relpath(path, str(tmp_path))

    def call(cmd, **fields):
        reply = commands.table.dispatch(cmd, json.dumps(dict(fields, preset=preset)))
        return reply.ack, (json.loads(reply.data) if reply.ack == "success" else reply.data)
    ack, got = call("get")
    target = dict(got["targets"][0])
    spec = {k: target[k] for k in ("kind", "name", "box", "start_angle", "end_angle", "start_value", "end_value",
                                   "centre", "radius", "unit") if k in target}
    truth = World.load(WORLD).faces["breaker_1/sf6_pressure"].value
    full_scale = abs(spec["end_value"] - spec["start_value"])
    ack, out = call("upload", targets=[spec], expected=[truth])
    assert ack == "success" and out["self_check"][0]["apart_fs_pct"] < 2.0, out
    assert abs(out["self_check"][0]["read"] - truth) < 0.02 * full_scale
    before = open(os.path.join(path, CALIB_INI)).read()
    ack, out = call("upload", targets=[spec], expected=[truth + 0.1 * full_scale])
    assert ack == "failed" and out.startswith("calibration refused, nothing written: target 0 "
                                              "(breaker_1/sf6_pressure): the reader reads") and "force: true" in out
    assert open(os.path.join(path, CALIB_INI)).read() == before
    ack, out = call("upload", targets=[spec], expected=[truth + 0.1 * full_scale], force=True)
    assert ack == "success" and out["self_check"][0]["apart_fs_pct"] > 9.0
    ack, out = call("upload", targets=[spec], expected=[truth, 1.0])
    assert ack == "failed" and "expected has 2 value(s) for 1 target(s)" in out
    assert call("apply", expected="10")[0] == "failed"
    cv2.imwrite(os.path.join(path, "zoom0.jpg"), np.full((HEIGHT, WIDTH, 3), 128, np.uint8))   # blank
    before = open(os.path.join(path, CALIB_INI)).read()
    ack, out = call("upload", targets=[spec], expected=[truth])
    assert ack == "failed" and "the reader cannot read the calibration picture" in out, out
    assert open(os.path.join(path, CALIB_INI)).read() == before


def test_the_transformer_bushings_calibrate_as_three_phases_and_grade_as_the_world_says(tmp_path):
    """The yard's three-phase bushing row (phase A hot) and its ambient plate, recorded as patrol_sim
    records transformer_1_thermal, calibrate as phases of one device and grade serious by DL/T 664."""
    from inspection_robot.inspection.reading import load_frame
    from inspection_robot.inspection.thermal_max import read_thermal_max
    from inspection_robot.task.checks import _target_entry
    from inspection_robot.task.rows import thermal_findings
    optics = camera_optics(WIDTH, HEIGHT)
    world = World.load(WORLD)
    pose = front_pose(world, "transformer_1", 3.0)
    tilt = math.degrees(math.atan2(1.2 - 2.95, 3.0))
    head = RenderedHead(Renderer(world, seed=2), optics, pose, 1.2, WIDTH, HEIGHT, ThermalRenderer(world))
    head.set_angles(0.0, tilt)
    head.set_zoom(2.0)
    state = {"pan_deg": 0.0, "tilt_deg": tilt, "zoom": 2.0, "focus_position": 0, "pose": pose}
    path = record_preset(head, str(tmp_path), "t1", "20260101_000000", state, infrared=True)
    assert run([path, "--from-world", WORLD]) == 0
    preset = load_preset(path)
    entries = [_target_entry(t) for t in preset.targets]
    phases = dict((e["name"], e.get("phase")) for e in entries if e["kind"] == "thermal")
    assert phases == {"transformer_1/bushing_a": "A", "transformer_1/bushing_b": "B", "transformer_1/bushing_c": "C",
                      "transformer_1/ambient_plate": "ambient"}
    frame = load_frame(os.path.join(path, preset.info.thermal_frame))
    values = [read_thermal_max(frame, t.params["thermal_box"], t.params.get("phase", "")).value
              if t.kind == "thermal" else None for t in preset.targets]
    truth = {"transformer_1/bushing_a": 78.0, "transformer_1/bushing_b": 48.0, "transformer_1/bushing_c": 47.0,
             "transformer_1/ambient_plate": 25.0}
    for entry, value in zip(entries, values):
        if entry["name"] in truth:
            assert abs(value - truth[entry["name"]]) < 1.0, (entry["name"], value)
    findings = thermal_findings(entries, values)
    hot = [findings[i] for i, e in enumerate(entries) if e["name"] == "transformer_1/bushing_a"][0]
    assert hot["grade"] == "serious" and hot["diagnosis"]["class"] == "bushing"
    assert hot["diagnosis"]["rule"].startswith("serious defect (bushing): hot spot 78")
    assert hot["diagnosis"]["delta_t"] == pytest.approx((78.0 - 47.0) / (78.0 - 25.0) * 100.0, abs=3.0)
