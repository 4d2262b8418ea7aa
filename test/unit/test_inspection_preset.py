"""Preset directory formats: preset.ini, calibration, zoomX.xml; atomic directory creation; bad files."""
import os

import numpy as np
import pytest
import yaml

from inspection_robot_testing import fixtures as S
from inspection_robot.inspection.calibration import derive_zoom_boxes
from inspection_robot.inspection.preset import CALIB_INI, PresetDirWriter, PresetError, PresetInfo, \
    check_preset_id, load_preset
from inspection_robot.tools.calibrate_preset import run as calibrate_cli

SIZE = (480, 270)


def _info(levels=(4.0, 2.0, 1.0)):
    return PresetInfo("meter_1", "visible", True, "20260101_120000", 12.5, -3.25, levels[0], 0x3000,
                      (1.5, -2.0, 0.7), list(levels), SIZE[0], SIZE[1], extra_data="0",
                      thermal_picture="thermal.jpg", thermal_frame="thermal.npy")


def test_preset_ini_round_trip():
    info = PresetInfo.from_ini(_info().to_ini())
    assert info.preset_id == "meter_1" and info.infrared
    assert (info.pan_deg, info.tilt_deg, info.zoom, info.focus_position) == (12.5, -3.25, 4.0, 0x3000)
    assert info.pose == pytest.approx((1.5, -2.0, 0.7))
    assert info.zoom_levels == [4.0, 2.0, 1.0]
    assert info.thermal_frame == "thermal.npy"
    with pytest.raises(PresetError):
        PresetInfo.from_ini("[preset]\npreset_id = x\n")


def test_writer_is_atomic(tmp_path):
    root = str(tmp_path)
    with pytest.raises(RuntimeError):
        with PresetDirWriter(root, "p1", "20260101_000000") as writer:
            open(writer.file("zoom0.jpg"), "w").close()
            raise RuntimeError("camera failed")
    assert os.listdir(os.path.join(root, "p1")) == []
    with PresetDirWriter(root, "p1", "20260101_000000") as writer:
        open(writer.file("preset.ini"), "w").close()
        final = writer.commit()
    assert os.listdir(os.path.join(root, "p1")) == ["20260101_000000"]
    assert os.path.isfile(os.path.join(final, "preset.ini"))
    with pytest.raises(PresetError):
        PresetDirWriter(root, "p1", "20260101_000000")
    with pytest.raises(PresetError):
        PresetDirWriter(root, "../evil", "20260101_000001")


@pytest.mark.parametrize("preset_id", ["", ".", "..", ".hidden", "a/b", "../x", "a\n", "a\x00b", "\t", "a" * 129])
def test_a_preset_id_that_cannot_name_its_folder_is_refused_before_anything_is_written(tmp_path, preset_id):
    # "a\n" once made a folder with a newline in its name and broke preset.ini (security suite, #28.5)
    with pytest.raises(PresetError, match="invalid preset_id"):
        PresetDirWriter(str(tmp_path), preset_id, "20260101_000000")
    assert os.listdir(str(tmp_path)) == []


def test_preset_ids_in_use_stay_valid():
    for preset_id in ("cabinet_1", "transformer-1", "p1", "a" * 128, "表计_1", "gauge 2"):
        assert check_preset_id(preset_id) is None


def test_commit_fsyncs_the_preset_folder_so_the_rename_survives_a_power_cut(tmp_path, monkeypatch):
    from inspection_robot import files
    synced = []
    real_fsync = os.fsync

    def fsync(fd):
        synced.append(os.readlink("/proc/self/fd/%d" % fd))
        return real_fsync(fd)
    monkeypatch.setattr(files.os, "fsync", fsync)
    with PresetDirWriter(str(tmp_path), "p1", "20260101_000000") as writer:
        staging = writer.path
        final = writer.commit()
    # the preset's own names before the rename that publishes them, then the rename itself
    assert synced == [staging, str(tmp_path / "p1")] and final == str(tmp_path / "p1" / "20260101_000000")


def test_zoom_boxes_scale_about_the_centre():
    optics = S.linear_optics(*SIZE)
    box = [[200, 100], [280, 100], [280, 170], [200, 170]]
    boxes = derive_zoom_boxes(box, [4.0, 2.0], optics, *SIZE)
    centre = np.array([(SIZE[0] - 1) / 2.0, (SIZE[1] - 1) / 2.0])
    assert np.allclose(boxes[1], centre + (np.array(box) - centre) / 2.0)


def _recorded(tmp_path):
    rng = np.random.default_rng(5)
    scene = S.PlanarScene(rng, targets=S.demo_targets())
    optics = S.linear_optics(*SIZE)
    return S.record_synthetic_preset(str(tmp_path), "meter_1", "20260101_120000", scene, (1200, 750),
                                     [1.5, 0.75, 0.375], SIZE, optics), scene


def test_recorded_and_calibrated_preset_loads(tmp_path):
    path, scene = _recorded(tmp_path)
    preset = load_preset(path)
    assert [t.kind for t in preset.targets] == ["pointer", "lamp", "switch"]
    assert sorted(preset.targets[0].boxes) == [0, 1, 2]
    matrix = scene.homography((1200, 750), 1.5, SIZE)
    assert np.allclose(preset.targets[0].boxes[0], scene.quad_in_view(scene.targets[0], matrix), atol=0.01)
    for name in ("zoom0.xml", "zoom2.xml", "target_2_open.png", "target_2_closed.png", CALIB_INI):
        assert os.path.isfile(os.path.join(path, name)), name


@pytest.mark.parametrize("damage,reason", [
    ("rm:preset.ini", "preset.ini missing"),
    ("rm:preset_calib_info.ini", "not calibrated"),
    ("rm:zoom0.xml", "zoom0.xml"),
    ("write:preset_calib_info.ini:[calibration]\ntarget_count = x\n", "corrupt calibration"),
    ("write:zoom0.xml:<zoom><target index='0'>", "corrupt calibration"),
    ("write:preset.ini:garbage", "corrupt preset.ini"),
])
def test_damaged_presets_give_reasons(tmp_path, damage, reason):
    path, _scene = _recorded(tmp_path)
    parts = damage.split(":", 2)
    if parts[0] == "rm":
        os.unlink(os.path.join(path, parts[1]))
    else:
        with open(os.path.join(path, parts[1]), "w") as f:
            f.write(parts[2])
    with pytest.raises(PresetError) as err:
        load_preset(path)
    assert reason in str(err.value)
    with pytest.raises(PresetError):
        load_preset(str(tmp_path / "nowhere"))


def test_cli_calibrates_and_rejects_bad_boxes(tmp_path, capsys):
    path, scene = _recorded(tmp_path)
    optics_file = tmp_path / "optics.yaml"
    optics = {"width": SIZE[0], "height": SIZE[1], "zoom_hfov_deg": [[1.0, 40.0], [30.0, 1.4]]}
    optics_file.write_text(yaml.safe_dump({"camera_optics": optics}))
    good = tmp_path / "targets.yaml"
    good.write_text(yaml.safe_dump({"targets": [
        {"kind": "lamp", "colour": "green", "box": [10, 10, 40, 10, 40, 40, 10, 40]},
        {"kind": "pointer", "box": [100, 50, 200, 50, 200, 150, 100, 150], "start_angle": 225, "end_angle": 135,
         "start_value": 0, "end_value": 10, "unit": "%RH", "scale_table": [[0, 225], [5, 0], [10, 135]]}]}))
    assert calibrate_cli([path, str(good), "--optics", str(optics_file)]) == 0
    preset = load_preset(path)
    assert preset.targets[1].scale.value(0) == pytest.approx(5)
    assert preset.targets[1].params["unit"] == "%RH"     # a percent sign is text, not ini interpolation
    outside = tmp_path / "outside.yaml"
    outside.write_text(yaml.safe_dump(
        {"targets": [{"kind": "lamp", "colour": "red", "box": [470, 10, 500, 10, 500, 40, 470, 40]}]}))
    assert calibrate_cli([path, str(outside), "--optics", str(optics_file)]) == 1
    assert "outside" in capsys.readouterr().err
    unknown = tmp_path / "unknown.yaml"
    unknown.write_text(yaml.safe_dump({"targets": [{"kind": "dial", "box": [10, 10, 40, 10, 40, 40, 10, 40]}]}))
    assert calibrate_cli([path, str(unknown), "--optics", str(optics_file)]) == 1
    assert "unknown target kind" in capsys.readouterr().err


def test_pointer_marks_round_trip_and_old_files_load():
    """The optional scale marks' positions survive the calibration file; a file without them loads
    (no marks); malformed marks are refused with a reason."""
    from inspection_robot.inspection.preset import Target
    box = {0: [[0, 0], [100, 0], [100, 100], [0, 100]]}
    params = dict(start_angle=225.0, end_angle=135.0, start_value=0.0, end_value=10.0)
    marks = [(0.0, 0.18, 0.82), (5.0, 0.5, 0.08), (10.0, 0.82, 0.82)]
    target = Target("pointer", box, name="m", marks=marks, **params)
    again = Target.from_section(target.section(), box)
    assert again.params["marks"] == [pytest.approx(list(m)) for m in marks]
    old = dict(target.section())
    del old["marks"]
    assert Target.from_section(old, box).params["marks"] == []
    for bad in ([(1.0, 0.5)], [("x", 0.1, 0.2)], [(1.0, float("nan"), 0.2)], 7):
        with pytest.raises(PresetError) as err:
            Target("pointer", box, marks=bad, **params)
        assert "marks" in str(err.value)
