"""calibration_control: the calibration tool's operations as commands, confined, all-or-nothing."""
import configparser
import json
import os
import threading

import cv2
import numpy as np
import pytest

from inspection_robot.camera.optics import ZoomOptics
from inspection_robot.files import write_atomic
from inspection_robot.inspection import calibration_commands
from inspection_robot.inspection import calibration_schema as schema
from inspection_robot.inspection.calibration_commands import CalibrationCommands
from inspection_robot.inspection.preset import CALIB_INI, PresetError, PresetInfo, load_preset

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


def test_both_preset_path_forms_name_one_preset_and_answers_use_the_data_root_form(robot):
    commands, _root = robot
    for given in (PRESET, "p1/20260101_120000"):   # data-root-relative, and the older preset-root-relative
        ack, out = call(commands, "get", preset=given)
        assert (ack, out["preset"]) == ("success", PRESET)


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
    check = out.pop("self_check")
    assert (ack, out) == ("success", {"preset": PRESET, "targets": 2, "kinds": ["pointer", "switch"]})
    assert [(c["target"], c["name"]) for c in check] == [(0, "oil")]   # pointers only
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
    ("mark_box", {"target": 0, "box": BOX + [float("nan")]}, "box[8] must be a finite number, got NaN"),
    ("mark_box", {"target": "0", "box": BOX}, "target must be an integer"),
    ("mark_box", {"box": BOX}, "missing field(s) target"),
    ("mark_box", {"preset": "presets/p2/x", "target": 0, "box": BOX}, "preset directory not found"),
    ("mark_box", {"preset": "captures", "target": 0, "box": BOX}, "preset directory not found"),  # presets/captures
    ("mark_box", {"preset": "/etc", "target": 0, "box": BOX}, "outside the allowed roots"),
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


# --- strict calibration: one schema, every path; all-or-nothing writes -------------------------
POINTER = {"kind": "pointer", "box": BOX, "name": "oil", "start_angle": -135, "end_angle": 135,
           "start_value": 0, "end_value": 1.6, "unit": "MPa"}


def snapshot(folder):
    """{relative path: bytes} of every file under ``folder``: byte-identical or not."""
    out = {}
    for base, _dirs, files in os.walk(str(folder)):
        for name in files:
            path = os.path.join(base, name)
            with open(path, "rb") as f:
                out[os.path.relpath(path, str(folder))] = f.read()
    return out


def calibrated(robot):
    """The robot's preset with a first calibration (a pointer and a switch) and its snapshot."""
    commands, root = robot
    switch = {"kind": "switch", "box": [300, 100, 360, 100, 360, 160, 300, 160],
              "open_picture": "captures/open.png", "closed_picture": "captures/closed.png"}
    assert call(commands, "upload", targets=[POINTER, switch])[0] == "success"
    return snapshot(root / PRESET)


def with_pointer(**change):
    target = dict(POINTER)
    target.update(change)
    return [target]


@pytest.mark.parametrize("targets,reason", [
    (with_pointer(end_value=float("inf")), "targets[0].end_value must be a finite number, got Infinity"),
    (with_pointer(start_angle=float("nan")), "targets[0].start_angle must be a finite number, got NaN"),
    (with_pointer(end_value=1e300), "end_value must be in [-1e+09, 1e+09], got 1e+300"),
    (with_pointer(end_value=10 ** 400), "a number of 401 digits is too long"),
    (with_pointer(start_angle=400), "start_angle must be in [-360, 360]"),
    (with_pointer(radus=0.4), "unknown key 'radus'"),
    (with_pointer(colour="red"), "key 'colour' does not apply to a pointer target (lamp only)"),
    (with_pointer(scale_table=[[0, -135], [float("nan"), 0], [1.6, 135]]),
     "targets[0].scale_table[1][0] must be a finite number, got NaN"),
    (with_pointer(scale_table=[[0, -135], [1.0, 0], [0.5, 135]]), "scale_table values must be strictly monotonic"),
    (with_pointer(scale_table=[[0, -135]]), "scale_table needs at least 2 entries"),
    (with_pointer(scale_table=[[0, 100], [0.8, -135], [1.6, 135]]), "scale_table angles must increase along the sweep"),
    (with_pointer(marks=[[0, 0.2, 0.8], [1.6, 1.3, 0.8]]), "marks u must be in [0, 1], got 1.3"),
    (with_pointer(centre=[0.5, -0.1]), "centre must be in [0, 1], got -0.1"),
    (with_pointer(radius=0), "radius must be in (0, 1.5], got 0"),
    (with_pointer(aspect=100), "aspect must be in [0.05, 20], got 100"),
    (with_pointer(start_value=1.6), "start_value and end_value must differ"),
    (with_pointer(unit="MPa\n[target_1]"), "unit must be at most 200 characters without control characters"),
    (with_pointer(normal=[2, 1]), "normal must be [low, high], low 2 is above high 1"),
    (with_pointer(normal=[0, 1], alarm_band=[0.5, 1.5]),
     "alarm band [0.5, 1.5] must contain the normal band [0, 1] (a warning lies between them)"),
    (with_pointer(alarm_band=[0, 1.5]), "alarm_band needs a normal band inside it"),
    (with_pointer(normal=[0, 1], alarm_band=[float("nan"), 1.5]),
     "targets[0].alarm_band[0] must be a finite number, got NaN"),
    (with_pointer(normal=[0, 1], alarm_band=[2, -1]), "alarm_band must be [low, high], low 2 is above high -1"),
    (with_pointer(pointer_colour="purple"), "pointer_colour must be one of dark|light|red|black|white"),
    ([{"kind": "thermal", "box": BOX, "thermal_box": [5, 5, 30, 5, 30, float("nan"), 5, 30]}],
     "targets[0].thermal_box[5] must be a finite number, got NaN"),
    ([{"kind": "thermal", "box": BOX, "thermal_box": [-5, 5, 30, 5, 30, 30, -5, 30]}], "thermal_box lies outside"),
    ([{"kind": "thermal", "box": BOX, "thermal_box": [5, 5, 30, 5, 5, 30, 30, 30]}],
     "thermal_box is not a convex TL,TR,BR,BL quad"),
    ([{"kind": "lamp", "box": BOX, "colour": "purple"}], "colour must be one of red|green|yellow|blue|white"),
    ([{"kind": "lamp", "box": BOX, "colour": "red", "on_picture": "captures/open.png"}],
     "a lamp needs both on_reference and off_reference"),
    ([{"kind": "switch", "box": BOX, "open_reference": "../../preset.ini", "closed_reference": "x.png"}],
     "open_reference must be a file name in the preset directory"),
    ([{"kind": "switch", "box": BOX, "open_reference": "gone.png", "closed_reference": "gone.png"}],
     "open_reference gone.png is not in the preset directory"),
    ([{"box": BOX, "colour": "red"}], "target 0: missing key 'kind'"),
    ([{"kind": "lamp", "box": [100, 100, 200, 100, float("inf"), 200, 100, 200], "colour": "red"}],
     "targets[0].box[4] must be a finite number, got Infinity"),
    ([{"kind": "lamp", "box": [100, 100, 200, 200, 200, 100, 100, 200], "colour": "red"}],
     "box is not a convex TL,TR,BR,BL quad"),
])
def test_every_bad_value_is_refused_by_name_and_the_old_calibration_stays(robot, targets, reason):
    commands, root = robot
    before = calibrated(robot)
    ack, out = call(commands, "upload", targets=targets)
    # NaN / Infinity / huge numbers never get past the JSON decoding (command.parse_json), which names
    # where they were; anything else reaches the schema
    prefix = "" if "finite number, got" in reason or "digits is too long" in reason else \
        "calibration refused, nothing written: "
    assert ack == "failed" and out.startswith(prefix) and reason in out
    assert snapshot(root / PRESET) == before


@pytest.mark.parametrize("cmd,fields,reason", [
    ("set_zero", {"target": 0, "angle": float("nan"), "value": 0}, "angle must be a finite number, got NaN"),
    ("set_full_scale", {"target": 0, "angle": 135, "value": float("inf")}, "value must be a finite number, got "
                                                                           "Infinity"),
    ("set_full_scale", {"target": 0, "angle": 135, "value": -1e12}, "end_value must be in [-1e+09, 1e+09]"),
    ("set_values", {"target": 0, "values": {"radus": 0.4}}, "unknown key 'radus'"),
    ("set_values", {"target": 0, "values": {"scale_table": [[0, 1], [float("nan"), 2]]}},
     "values.scale_table[1][0] must be a finite number, got NaN"),
    ("set_values", {"target": 0, "values": {"thermal_box": [0, 0, 1, 0, 1, float("nan"), 0, 1]}},
     "values.thermal_box[5] must be a finite number, got NaN"),
    ("set_values", {"target": 0, "values": {"marks": [[0, 0.5, 1.5]]}}, "marks v must be in [0, 1]"),
    ("set_values", {"target": 0, "values": {"centre": [0.5, 2]}}, "centre must be in [0, 1]"),
    ("set_values", {"target": 0, "values": {"name": "a\x00b"}}, "name must be at most 200 characters"),
    ("mark_box", {"target": 0, "box": [100, 100, 100, 100, 100, 100, 100, 100]}, "box is not a convex"),
])
def test_bad_draft_edits_are_refused_by_name_and_the_draft_stays(robot, cmd, fields, reason):
    commands, root = robot
    call(commands, "mark_box", target=0, box=BOX)
    before = snapshot(root / PRESET)
    ack, out = call(commands, cmd, **fields)
    assert ack == "failed" and reason in out
    assert snapshot(root / PRESET) == before


def test_a_bad_draft_is_refused_at_apply_by_name(robot):
    commands, root = robot
    before = calibrated(robot)
    call(commands, "clear_draft")
    call(commands, "mark_box", target=0, box=BOX)
    call(commands, "set_values", target=0, values={"colour": "red"})     # a lamp key on a pointer
    call(commands, "set_zero", target=0, angle=-135, value=0)
    call(commands, "set_full_scale", target=0, angle=135, value=1.6)
    ack, out = call(commands, "apply")
    assert ack == "failed" and "target 0 (pointer): key 'colour' does not apply to a pointer target" in out
    assert snapshot(root / PRESET) == dict(before, **{"calibration_draft.json": snapshot(root / PRESET)[
        "calibration_draft.json"]})
    # changing the kind removes the keys the new kind does not take, and says which
    ack, out = call(commands, "set_meter_type", target=0, kind="lamp")
    assert ack == "success" and out["dropped"] == ["end_angle", "end_value", "start_angle", "start_value"]
    assert out["draft"][0] == {"kind": "lamp", "box": [float(v) for v in BOX], "colour": "red"}
    assert call(commands, "apply")[0] == "success"


@pytest.mark.parametrize("key,text,reason", [
    ("radus", "0.4", "unknown key 'radus'"),
    ("end_value", "inf", "end_value must be a finite number, got inf"),
    ("start_angle", "nan", "start_angle must be a finite number, got nan"),
    ("scale_table", "0:-135;nan:0;1.6:135", "scale_table value must be a finite number"),
    ("scale_table", "0:-135;0.8", "scale_table: cannot read"),
    ("marks", "0:0.2,0.8;1.6:1.2,0.8", "marks u must be in [0, 1], got 1.2"),
    ("centre", "0.5", "centre must be a list of 2 numbers, got [0.5]"),
    ("radius", "-1", "radius must be in (0, 1.5]"),
    ("colour", "red", "key 'colour' does not apply to a pointer target"),
    ("normal", "5,1", "normal must be [low, high]"),
])
def test_a_bad_calibration_file_is_refused_by_name(robot, key, text, reason):
    commands, root = robot
    calibrated(robot)
    ini = str(root / PRESET / CALIB_INI)
    config = configparser.ConfigParser(interpolation=None)
    config.read(ini)
    config["target_0"][key] = text
    with open(ini, "w") as f:
        config.write(f)
    with pytest.raises(PresetError) as err:
        load_preset(str(root / PRESET))
    assert "[target_0]" in str(err.value) and reason in str(err.value)
    ack, out = call(commands, "get")
    assert ack == "failed" and reason in out


def test_thermal_boxes_lie_inside_the_thermal_picture(robot):
    commands, root = robot
    preset = root / PRESET
    info = PresetInfo("p1", "infrared", True, "20260101_120000", 10.0, -5.0, 1.0, 0x4000, (1.0, 2.0, 0.5),
                      [1.0, 2.0], 640, 360, thermal_picture="thermal.jpg", thermal_frame="thermal.png")
    write_atomic(str(preset / "preset.ini"), info.to_ini())
    cv2.imwrite(str(preset / "thermal.jpg"), np.zeros((288, 384, 3), np.uint8))
    inside = {"kind": "thermal", "box": BOX, "thermal_box": [300, 200, 383, 200, 383, 287, 300, 287]}
    assert call(commands, "upload", targets=[inside])[0] == "success"
    outside = dict(inside, thermal_box=[300, 200, 390, 200, 390, 287, 300, 287])
    ack, out = call(commands, "upload", targets=[outside])
    assert ack == "failed" and "thermal_box lies outside the 384x288 thermal picture" in out
    phases = [dict(inside, phase="A", device="T1"), dict(inside, phase="B", device="T1"),
              dict(inside, phase="ambient", emissivity=0.95)]
    assert call(commands, "upload", targets=phases)[0] == "success"
    ack, out = call(commands, "upload", targets=phases + [dict(inside, phase="B", device="T1")])
    assert ack == "failed" and "thermal phases: device 'T1' has phase B twice (targets 1 and 3)" in out


def test_get_then_upload_round_trips(robot):
    """What get answers is a valid upload (references to patches already in the preset included)."""
    commands, root = robot
    calibrated(robot)
    targets = call(commands, "get")[1]["targets"]
    assert targets[1]["open_reference"] == "target_1_open.png"
    ack, out = call(commands, "upload", targets=targets)
    assert ack == "success" and out["kinds"] == ["pointer", "switch"]
    assert call(commands, "get")[1]["targets"] == targets


def test_limits_set_by_upload_reach_a_task(robot):
    """The console's limits editor: get, the limits changed, upload; a task then judges by them."""
    from inspection_robot.task.checks import resolve_preset
    commands, root = robot
    calibrated(robot)
    targets = call(commands, "get")[1]["targets"]
    targets[0].update(normal=[0.2, 1.2], alarm_band=[0.1, 1.4])
    targets[1].update(normal=[1, 1])   # the switch should be closed
    assert call(commands, "upload", targets=targets)[0] == "success"
    got = call(commands, "get")[1]["targets"]
    assert (got[0]["normal"], got[0]["alarm_band"], got[1]["normal"]) == ([0.2, 1.2], [0.1, 1.4], [1.0, 1.0])
    resolved = resolve_preset(str(root / "presets"), PRESET, str(root))
    assert resolved.alarms == {got[0]["name"]: {"normal": [0.2, 1.2], "alarm": [0.1, 1.4]}, got[1]["name"]: [1.0, 1.0]}
    del targets[0]["normal"], targets[0]["alarm_band"]   # limits removed by leaving the keys out
    assert call(commands, "upload", targets=targets)[0] == "success"
    assert "normal" not in call(commands, "get")[1]["targets"][0]


def test_the_tool_refuses_a_bad_yaml_by_name_and_writes_nothing(robot, capsys):
    from inspection_robot.tools.calibrate_preset import run
    _commands, root = robot
    before = calibrated(robot)
    optics = str(root / "optics.yaml")
    open(optics, "w").write("camera_optics: {width: 640, height: 360, zoom_hfov_deg: [[1.0, 59.8], [2.0, 31.6]]}\n")
    bad = str(root / "targets.yaml")
    open(bad, "w").write("targets:\n- {kind: pointer, box: %s, start_angle: -135, end_angle: 135, start_value: 0,\n"
                         "   end_value: .inf, radus: 0.4}\n" % BOX)
    assert run([str(root / PRESET), bad, "--optics", optics]) == 1
    assert "target 0 (pointer): end_value must be a finite number, got inf" in capsys.readouterr().err
    open(bad, "w").write("targets:\n- {kind: pointer, box: %s, start_angle: -135, end_angle: 135, start_value: 0,\n"
                         "   end_value: 1.6, radus: 0.4}\n" % BOX)
    assert run([str(root / PRESET), bad, "--optics", optics]) == 1
    assert "unknown key 'radus'" in capsys.readouterr().err
    assert snapshot(root / PRESET) == before


# --- fault injection: an OSError at each step of the write ---------------------------------------
FATAL = ("fdopen", "replace", "exchange")     # writing a file's data, renaming it, the swap


class Faults(object):
    """Counts the file-system calls of a write; raises OSError at call ``fail_at`` (once)."""

    NAMES = ("open", "fdopen", "fsync", "link", "replace", "rename", "mkdir", "symlink", "chmod")

    def __init__(self, monkeypatch, fail_at=None):
        import inspection_robot.dir_update as dir_update
        self.calls, self.fail_at, self.failed = [], fail_at, None
        for name in self.NAMES:
            monkeypatch.setattr(os, name, self._wrap(name, getattr(os, name)))
        monkeypatch.setattr(dir_update, "_exchange", self._wrap("exchange", dir_update._exchange))

    def _wrap(self, name, real):
        def call(*args, **kwargs):
            self.calls.append(name)
            if len(self.calls) - 1 == self.fail_at:
                self.failed = name
                raise OSError(5, "injected I/O error at %s" % name)
            return real(*args, **kwargs)
        return call


def test_a_failure_at_any_step_leaves_the_old_calibration_byte_identical(robot, tmp_path, monkeypatch):
    import shutil
    commands, root = robot
    before = calibrated(robot)
    pristine = str(tmp_path / "pristine")
    shutil.copytree(str(root / PRESET), pristine)
    parent = os.path.dirname(str(root / PRESET))
    siblings = sorted(os.listdir(parent))
    new = [dict(POINTER, end_value=2.5), {"kind": "lamp", "box": [300, 100, 360, 100, 360, 160, 300, 160],
                                          "colour": "green", "on_picture": "captures/open.png",
                                          "off_picture": "captures/closed.png"}]

    def attempt(fail_at):
        for name in set(os.listdir(parent)) - set(siblings):   # an old copy a failed clean-up left
            shutil.rmtree(os.path.join(parent, name))
        shutil.rmtree(str(root / PRESET))
        shutil.copytree(pristine, str(root / PRESET))
        with monkeypatch.context() as patch:
            faults = Faults(patch, fail_at)
            reply = call(commands, "upload", targets=new)
        return faults, reply

    faults, (ack, _out) = attempt(None)
    steps = list(faults.calls)
    assert ack == "success" and "exchange" in steps and len(steps) > 20
    outcomes = []
    for k in range(len(steps)):
        faults, (ack, out) = attempt(k)
        assert faults.failed == steps[k]
        if ack == "failed":
            assert "calibration not written, the preset is unchanged: " in out and "injected I/O error" in out
            assert snapshot(root / PRESET) == before, "step %d (%s)" % (k, steps[k])
            assert sorted(os.listdir(parent)) == siblings, "step %d (%s) left a staging copy" % (k, steps[k])
        else:   # a failure the write tolerates (a refused hard link: the file is copied; makedirs of the
            # existing folder; a best-effort folder fsync) or one after the swap (the parent's fsync,
            # removing the old copy): the new calibration is whole
            assert k > steps.index("exchange") or steps[k] not in FATAL, "step %d (%s) passed" % (k, steps[k])
            preset = load_preset(str(root / PRESET))
            assert [t.kind for t in preset.targets] == ["pointer", "lamp"]
            assert preset.targets[0].params["end_value"] == 2.5
            assert call(commands, "get")[1]["draft"] == new
        outcomes.append(ack)
    swap = steps.index("exchange")
    assert outcomes[swap - 1:swap + 1] == ["failed", "failed"]      # the staging copy's fsync, the swap
    assert outcomes[swap + 1:] == ["success"] * (len(steps) - swap - 1)
    assert outcomes.count("failed") > 20
    assert all(ack == "success" for ack in outcomes[swap + 1:])


def test_without_an_atomic_exchange_two_renames_replace_the_folder(robot, monkeypatch):
    """A file system without RENAME_EXCHANGE: the preset is renamed aside and the copy renamed in;
    the directory keeps its mode."""
    import errno
    import inspection_robot.dir_update as dir_update
    commands, root = robot
    calibrated(robot)
    os.chmod(str(root / PRESET), 0o750)

    def no_exchange(a, b):
        raise OSError(errno.EINVAL, "not supported")
    monkeypatch.setattr(dir_update, "_exchange", no_exchange)
    ack, out = call(commands, "upload", targets=with_pointer(end_value=4.0))
    assert ack == "success"
    assert load_preset(str(root / PRESET)).targets[0].params["end_value"] == 4.0
    assert os.stat(str(root / PRESET)).st_mode & 0o777 == 0o750
    assert sorted(os.listdir(os.path.dirname(str(root / PRESET)))) == ["20260101_120000"]


# --- limits: refused with the reason before any expensive work, a positive control beside each --
LAMP = {"kind": "lamp", "box": BOX, "colour": "red"}


def test_at_most_max_targets_per_preset_refused_before_any_target_is_looked_at(robot, monkeypatch):
    commands, root = robot
    assert schema.MAX_TARGETS == 64
    looked = []
    real_check_spec = schema.check_spec
    monkeypatch.setattr(schema, "check_spec", lambda *args: looked.append(1) or real_check_spec(*args))
    before = listing(root)
    ack, out = call(commands, "upload", targets=[LAMP] * 65)
    assert (ack, out) == ("failed", "calibration refused, nothing written: 65 targets given, at most 64 per preset")
    assert looked == [] and listing(root) == before
    ack, out = call(commands, "upload", targets=[LAMP] * 64)                 # positive control
    assert ack == "success" and out["targets"] == 64 and len(looked) == 64
    for i in range(64):                                                      # the draft is capped too
        assert call(commands, "mark_box", target=i, box=BOX)[0] == "success"
    assert call(commands, "mark_box", target=64, box=BOX) == (
        "failed", "the draft has 64 targets, at most 64 per preset")


def test_a_request_larger_than_max_request_bytes_is_refused_before_it_is_parsed(robot, monkeypatch):
    commands, root = robot
    parsed = []
    monkeypatch.setattr(calibration_commands, "parse_json", lambda data: parsed.append(1) or json.loads(data))
    name = "n" * 150
    big = json.dumps({"preset": PRESET, "targets": [dict(LAMP, name=name)] * 7000})
    reply = commands.table.dispatch("upload", big)
    assert reply == ("failed", "request of %d bytes refused, at most 1048576 (a preset has at most 64 targets)"
                     % len(big))
    assert parsed == [] and CALIB_INI not in listing(root)
    ack, _out = call(commands, "upload", targets=[dict(LAMP, name=name)] * 64)   # positive control
    assert ack == "success" and parsed == [1]


def test_a_reference_named_in_the_preset_must_decode_as_the_reader_decodes_it(robot):
    commands, root = robot
    preset = root / PRESET
    (preset / "notes.png").write_text("not a picture: the switch would fail only on patrol")
    patch = np.random.RandomState(1).randint(0, 255, (64, 64)).astype(np.uint8)
    cv2.imwrite(str(preset / "open.png"), patch)
    cv2.imwrite(str(preset / "closed.png"), 255 - patch)
    switch = {"kind": "switch", "box": BOX, "open_reference": "notes.png", "closed_reference": "closed.png"}
    before = listing(root)
    ack, out = call(commands, "upload", targets=[switch])
    assert ack == "failed" and out == ("calibration refused, nothing written: target 0: open_reference notes.png "
                                       "is not a picture the reader can decode (PNG, JPEG, ...)")
    assert listing(root) == before
    lamp = dict(LAMP, on_reference="preset.ini", off_reference="closed.png")
    refused = call(commands, "upload", targets=[lamp])[1]
    assert "on_reference preset.ini is not a picture the reader can decode" in refused
    ack, _out = call(commands, "upload", targets=[dict(switch, open_reference="open.png")])   # positive control
    assert ack == "success"
    loaded = load_preset(str(preset))
    assert loaded.reference("open.png") == (preset / "open.png").read_bytes()


@pytest.mark.parametrize("given", ["presets/p1/.20260101_120000.update.x1", "presets/p1/.tmp_20260101_130000_ab"])
def test_a_hidden_preset_folder_is_never_calibrated(robot, given):
    commands, root = robot
    hidden = root / given
    hidden.mkdir()
    (hidden / "preset.ini").write_bytes((root / PRESET / "preset.ini").read_bytes())
    ack, out = call(commands, "upload", preset=given, targets=[LAMP])
    assert ack == "failed" and "has the hidden name '%s'" % given.split("/")[-1] in out
    assert sorted(os.listdir(str(hidden))) == ["preset.ini"]
    assert call(commands, "upload", targets=[LAMP])[0] == "success"          # positive control


# --- one calibration, read as one ---------------------------------------------------------------
def test_a_reader_sees_the_old_or_the_new_calibration_never_a_mix(robot):
    """Uploads alternating 1 and 3 targets (different boxes and names) swap the preset directory
    while a reader loads it in a loop: every load is one of the two, whole."""
    commands, root = robot
    one = [dict(LAMP, name="one_0")]
    three = [dict(LAMP, name="three_%d" % i, box=[100 + 10 * i, 100, 200 + 10 * i, 100, 200 + 10 * i, 200,
                                                  100 + 10 * i, 200]) for i in range(3)]
    expected = {("one_0",): [100.0], ("three_0", "three_1", "three_2"): [100.0, 110.0, 120.0]}
    assert call(commands, "upload", targets=one)[0] == "success"
    stop = threading.Event()
    uploads = []

    def upload_loop():
        while not stop.is_set():
            uploads.append(call(commands, "upload", targets=three if len(uploads) % 2 else one)[0])

    writer = threading.Thread(target=upload_loop)
    writer.start()
    mixes, failures, loads = [], [], 0
    try:
        while loads < 2000 or len(uploads) < 200:
            try:
                preset = load_preset(str(root / PRESET))
            except PresetError as err:
                failures.append(str(err))
                continue
            finally:
                loads += 1
            names = tuple(t.name for t in preset.targets)
            lefts = [float(t.boxes[0][0][0]) for t in preset.targets]
            if expected.get(names) != lefts:
                mixes.append((names, lefts))
    finally:
        stop.set()
        writer.join(30.0)
    assert set(uploads) == {"success"} and len(uploads) >= 200
    assert (mixes, failures) == ([], []), "%d mixes, %d failures in %d loads" % (len(mixes), len(failures), loads)
