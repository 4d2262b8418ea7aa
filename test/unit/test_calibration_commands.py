"""calibration_control: the calibration tool's operations as commands, confined, all-or-nothing."""
import json
import os

import cv2
import numpy as np
import pytest

from inspection_robot.camera.optics import ZoomOptics
from inspection_robot.files import write_atomic
from inspection_robot.inspection.calibration_commands import CalibrationCommands
from inspection_robot.inspection.preset import CALIB_INI, PresetInfo, load_preset

OPTICS = ZoomOptics([[1.0, 59.8], [2.0, 31.6], [4.0, 16.2]], 640, 360)
BOX = [100, 100, 200, 100, 200, 200, 100, 200]
PRESET = "presets/p1/20260101_120000"


@pytest.fixture
def robot(tmp_path):
    root = tmp_path / "data"
    preset = root / PRESET
    preset.mkdir(parents=True)
    info = PresetInfo("p1", "visible", False, "20260101_120000", 10.0, -5.0, 1.0, 0x4000, (1.0, 2.0, 0.5),
                      [1.0, 2.0], 640, 360)
    write_atomic(str(preset / "preset.ini"), info.to_ini())
    picture = np.random.RandomState(0).randint(0, 255, (360, 640, 3)).astype(np.uint8)
    (root / "captures").mkdir()
    cv2.imwrite(str(root / "captures" / "open.png"), picture)
    cv2.imwrite(str(root / "captures" / "closed.png"), 255 - picture)
    (tmp_path / "outside.png").write_bytes(open(str(root / "captures" / "open.png"), "rb").read())
    return CalibrationCommands(str(root), ["presets"], ["presets", "captures"], OPTICS), root


def call(commands, cmd, **fields):
    fields.setdefault("preset", PRESET)
    reply = commands.table.dispatch(cmd, json.dumps(fields))
    return reply.ack, (json.loads(reply.data) if reply.ack == "success" else reply.data)


def listing(root):
    return sorted(os.listdir(str(root / PRESET)))


def test_step_by_step_like_the_tool(robot):
    commands, root = robot
    assert call(commands, "mark_box", target=0, box=BOX)[0] == "success"
    assert call(commands, "set_zero", target=0, angle=-135, value=0)[0] == "success"
    assert call(commands, "set_full_scale", target=0, angle=135, value=1.6)[0] == "success"
    values = {"unit": "MPa", "name": "oil", "scale_table": [[0, -135], [0.8, 0], [1.6, 135]]}
    ack, out = call(commands, "set_values", target=0, values=values)
    assert ack == "success" and out["draft"][0]["unit"] == "MPa"
    assert call(commands, "mark_box", target=1, box=[300, 100, 360, 100, 360, 160, 300, 160])[0] == "success"
    assert call(commands, "set_meter_type", target=1, kind="switch")[0] == "success"
    pictures = {"open_picture": "captures/open.png", "closed_picture": "captures/closed.png"}
    assert call(commands, "set_values", target=1, values=pictures)[0] == "success"
    ack, out = call(commands, "apply")
    assert (ack, out) == ("success", {"preset": PRESET, "targets": 2, "kinds": ["pointer", "switch"]})
    preset = load_preset(str(root / PRESET))
    assert [t.kind for t in preset.targets] == ["pointer", "switch"]
    assert preset.targets[0].params["end_value"] == 1.6 and preset.targets[0].name == "oil"
    ack, out = call(commands, "get")
    assert out["calibrated"] and out["targets"][0]["box"] == [float(v) for v in BOX]
    assert out["info"]["preset_id"] == "p1" and out["info"]["pose"] == [1.0, 2.0, 0.5]
    assert out["targets"][1]["open_reference"] == "target_1_open.png"


def test_upload_writes_the_whole_calibration(robot):
    commands, root = robot
    targets = [{"kind": "lamp", "box": BOX, "colour": "red"}]
    ack, out = call(commands, "upload", targets=targets)
    assert ack == "success" and out["targets"] == 1
    assert load_preset(str(root / PRESET)).targets[0].kind == "lamp"
    assert call(commands, "get")[1]["draft"] == targets


@pytest.mark.parametrize("targets,reason", [
    ([], "no targets given"),
    ([{"kind": "pointer", "box": BOX}], "target 0 (pointer): missing key(s) start_angle, end_angle"),
    ([{"kind": "gauge", "box": BOX}], "unknown target kind"),
    ([{"kind": "lamp", "box": [0, 0, 1, 1], "colour": "red"}], "box must be a list of 8 numbers"),
    ([{"kind": "lamp", "box": [0, 0, 9000, 0, 9000, 10, 0, 10], "colour": "red"}], "outside the 640x360 picture"),
    ([{"kind": "lamp", "box": BOX, "colour": "red"},
      {"kind": "switch", "box": BOX, "open_picture": "captures/open.png", "closed_picture": "captures/nope.png"}],
     "closed_picture missing or unreadable"),
    ([{"kind": "switch", "box": BOX, "open_picture": "../outside.png", "closed_picture": "captures/open.png"}],
     "outside the allowed roots"),
    ("all", "targets must be a list"),
])
def test_bad_uploads_write_nothing(robot, targets, reason):
    commands, root = robot
    before = listing(root)
    ack, out = call(commands, "upload", targets=targets)
    assert ack == "failed" and reason in out
    assert listing(root) == before and CALIB_INI not in before


@pytest.mark.parametrize("cmd,fields,reason", [
    ("mark_box", {"target": 1, "box": BOX}, "target 1 does not exist"),
    ("set_zero", {"target": 0, "angle": -135, "value": 0}, "target 0 does not exist"),
    ("mark_box", {"target": 0, "box": [1, 2, 3]}, "box must be a list of 8 numbers"),
    ("mark_box", {"target": 0, "box": BOX + [float("nan")]}, "box must be a list of 8 numbers"),
    ("mark_box", {"target": "0", "box": BOX}, "target must be an integer"),
    ("mark_box", {"box": BOX}, "missing field(s) target"),
    ("mark_box", {"preset": "presets/p2/x", "target": 0, "box": BOX}, "preset directory not found"),
    ("mark_box", {"preset": "captures", "target": 0, "box": BOX}, "outside the allowed roots"),
    ("mark_box", {"preset": "../../etc", "target": 0, "box": BOX}, "outside the allowed roots"),
    ("apply", {}, "nothing written: no targets given"),
    ("get", {"colour": 1}, "unknown field(s) colour"),
])
def test_bad_edits_fail_clearly(robot, cmd, fields, reason):
    commands, root = robot
    before = listing(root)
    ack, out = call(commands, cmd, **fields)
    assert ack == "failed" and reason in out
    assert listing(root) == before


def test_bad_values_and_types(robot):
    commands, _root = robot
    call(commands, "mark_box", target=0, box=BOX)
    reason = call(commands, "set_meter_type", target=0, kind="dial")[1]
    assert "meter type must be one of pointer|lamp|switch|thermal" in reason
    assert "unknown key 'colr'" in call(commands, "set_values", target=0, values={"colr": "red"})[1]
    assert "radius must be a finite number" in call(commands, "set_values", target=0, values={"radius": "big"})[1]
    assert "value must be a finite number" in call(commands, "set_zero", target=0, angle=0, value=float("inf"))[1]
    ack, out = call(commands, "remove_target", target=0)
    assert ack == "success" and out["draft"] == []
    assert call(commands, "clear_draft")[1]["draft"] == []


def test_the_tool_runs_the_same_commands(robot, capsys):
    from inspection_robot.tools.calibrate_preset import run
    _commands, root = robot
    preset = str(root / PRESET)
    optics = str(root / "optics.yaml")
    open(optics, "w").write("camera_optics: {width: 640, height: 360, zoom_hfov_deg: [[1.0, 59.8], [2.0, 31.6]]}\n")
    assert run([preset, "--optics", optics, "--command", "mark_box", json.dumps({"target": 0, "box": BOX})]) == 0
    assert run([preset, "--optics", optics, "--command", "set_values",
                json.dumps({"target": 0, "values": {"colour": "green"}})]) == 0
    assert run([preset, "--optics", optics, "--command", "set_meter_type",
                json.dumps({"target": 0, "kind": "lamp"})]) == 0
    assert run([preset, "--optics", optics, "--command", "apply", "{}"]) == 0
    assert load_preset(preset).targets[0].params["colour"] == "green"
    assert run([preset, "--optics", optics, "--command", "set_zero", json.dumps({"target": 3})]) == 1
    assert "missing field(s) angle, value" in capsys.readouterr().err
