"""read_scale's core on a recorded synthetic preset: readings, foreign objects, every bad input."""
import os

import cv2
import numpy as np
import pytest

from inspection_robot_testing import fixtures as S
from inspection_robot.inspection.geometry import flat_from_quads
from inspection_robot.inspection.locate import Locator
from inspection_robot.inspection.preset import load_preset
from inspection_robot.inspection.reading import ReadError, ScaleReader

SIZE = (480, 270)
STAMP = "20260102_080000"


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    root = tmp_path_factory.mktemp("inspection")
    presets, pictures = str(root / "presets"), str(root / "pictures")
    os.makedirs(pictures)
    rng = np.random.default_rng(8)
    scene = S.PlanarScene(rng, targets=S.demo_targets())
    optics = S.linear_optics(*SIZE)
    path = S.record_synthetic_preset(presets, "meter_1", "20260101_120000", scene, (1200, 750),
                                     [1.5, 0.75, 0.375], SIZE, optics)
    # the robot comes back: the head points a little off, the meter reads 1.234, lamp off, switch open
    scene.targets[0]["value"], scene.targets[1]["on"], scene.targets[2]["closed"] = 1.234, False, False
    matrix = scene.homography((1185, 760), 1.6, SIZE)
    picture = os.path.join(pictures, "zoom0_20260102_080000_01.jpg")
    cv2.imwrite(picture, scene.render(matrix, SIZE), [cv2.IMWRITE_JPEG_QUALITY, 95])
    preset = load_preset(path)
    located = Locator("orb").locate(cv2.imread(preset.picture(0)), cv2.imread(picture),
                                    [t.boxes[0] for t in preset.targets])
    reader = ScaleReader([presets], [pictures, presets], pictures)
    return reader, path, picture, flat_from_quads(located.quads), scene


def test_reads_every_box(setup):
    reader, path, picture, roi, _scene = setup
    out = reader.read(path, 0, [picture], [], roi, [], STAMP)
    assert abs(out.scale[0] - 1.234) / 1.6 * 100 < 1.0
    assert out.scale[1:] == [0.0, 0.0]          # lamp off, switch open
    assert len(out.possibility) == 3 and all(0 <= p <= 100 for p in out.possibility)
    assert out.possibility[0] > 50
    assert all(os.path.isfile(p) and "/meter_1/" in p for p in out.picture_path)
    assert out.foreign_scale == []


def _picture_with_value(scene, value, name):
    """The setup's view again with the meter at ``value`` (the scene is left as it was)."""
    before = scene.targets[0]["value"]
    scene.targets[0]["value"] = value
    try:
        image = scene.render(scene.homography((1185, 760), 1.6, SIZE), SIZE)
    finally:
        scene.targets[0]["value"] = before
    cv2.imwrite(name, image, [cv2.IMWRITE_JPEG_QUALITY, 95])
    return name


def test_a_picture_out_of_focus_is_uncertain_and_a_dim_one_is_not(setup):
    """The same view blurred (the camera's focus lost, the head shaking) reads a value but is
    uncertain with the reason; the same view at half the light is as sharp and reads as before."""
    reader, path, picture, roi, _scene = setup
    image = cv2.imread(picture)
    blurred = picture.replace("_01.jpg", "_01_blur.jpg")
    cv2.imwrite(blurred, cv2.GaussianBlur(image, (0, 0), 2.5), [cv2.IMWRITE_JPEG_QUALITY, 95])
    out = reader.read(path, 0, [blurred], [], roi, [], STAMP)
    assert "picture out of focus or shaken" in out.uncertain[0] and out.possibility[0] <= 40, out
    assert out.uncertain[1:] == ["", ""]   # the lamp and the switch, no needles, read clearly blurred too
    dim = picture.replace("_01.jpg", "_01_dim.jpg")
    cv2.imwrite(dim, (image * 0.5).astype(np.uint8), [cv2.IMWRITE_JPEG_QUALITY, 95])
    out = reader.read(path, 0, [dim], [], roi, [], STAMP)
    assert "out of focus" not in out.uncertain[0] and abs(out.scale[0] - 1.234) / 1.6 * 100 < 1.0, out


def test_a_second_look_that_agrees_gives_the_mean(setup):
    reader, path, picture, roi, scene = setup
    one = reader.read(path, 0, [picture], [], roi, [], STAMP)
    second = _picture_with_value(scene, 1.234, picture.replace("_01.jpg", "_01_look2.jpg"))
    two = reader.read(path, 0, [picture, second], [], roi, [], STAMP)
    assert two.uncertain == ["", "", ""]
    assert abs(two.scale[0] - 1.234) / 1.6 * 100 < 1.0
    assert abs(two.scale[0] - one.scale[0]) / 1.6 * 100 <= 0.5   # the mean of two looks 1 % FS apart at most
    assert two.scale[1:] == one.scale[1:]                          # lamp and switch: read once


def test_a_second_look_that_disagrees_makes_the_reading_uncertain_with_both_values(setup):
    reader, path, picture, roi, scene = setup
    second = _picture_with_value(scene, 1.30, picture.replace("_01.jpg", "_01_look2b.jpg"))   # 4 % FS off
    # the per-target form twice: first looks, then second looks (lamp and switch entries ignored there)
    two = reader.read(path, 0, [picture] * 3 + [second] * 3, [], roi, [], STAMP)
    why = two.uncertain[0]
    assert why.startswith("two looks disagree: ") and "% FS)" in why, why
    first_value, second_value = [float(v) for v in why.split(": ")[1].split(" (")[0].split(" and ")]
    assert abs(first_value - 1.234) < 0.016 and abs(second_value - 1.30) < 0.016
    assert two.scale[0] in (pytest.approx(first_value, abs=1e-3), pytest.approx(second_value, abs=1e-3))
    assert two.uncertain[1:] == ["", ""]


def test_an_unreadable_second_look_makes_the_reading_uncertain(setup):
    reader, path, picture, roi, _scene = setup
    blank = os.path.join(os.path.dirname(picture), "zoom0_20260102_080000_01_look2c.jpg")
    cv2.imwrite(blank, np.full((270, 480, 3), 255, np.uint8))
    two = reader.read(path, 0, [picture, blank], [], roi, [], STAMP)
    assert two.uncertain[0] == "second look: overexposed picture in the box"
    assert abs(two.scale[0] - 1.234) / 1.6 * 100 < 1.0
    with pytest.raises(ReadError) as err:
        reader.read(path, 0, [picture, picture.replace("_01.jpg", "_missing.jpg")], [], roi, [], STAMP)
    assert "unreadable" in str(err.value)


def test_two_reads_in_one_second_keep_both_result_pictures(setup):
    reader, path, picture, roi, _scene = setup
    stamp = "20260102_090000"
    first = reader.read(path, 0, [picture], [], roi, [], stamp).picture_path
    second = reader.read(path, 0, [picture], [], roi, [], stamp).picture_path
    assert len(set(first + second)) == len(first) + len(second)
    assert all(os.path.isfile(p) for p in first + second)
    assert second[0].endswith(stamp + "_read_00_2.jpg")


def test_foreign_object_present_and_absent(setup):
    reader, path, picture, roi, _scene = setup
    clean = reader.read(path, 1, [], [picture], [], [], STAMP)
    assert clean.foreign_scale == [0.0] and clean.scale == []
    dirty_image = cv2.imread(picture)
    # on the equipment (the plane the registration holds for), beside the targets
    cv2.ellipse(dirty_image, (360, 60), (40, 22), 0, 0, 360, (30, 60, 90), -1)
    dirty = picture.replace("_01.jpg", "_02.jpg")
    cv2.imwrite(dirty, dirty_image)
    both = reader.read(path, 2, [picture], [dirty], roi, [], STAMP)
    assert both.foreign_scale[0] >= 1 and both.foreign_possibility[0] > 50
    assert len(both.scale) == 3


@pytest.mark.parametrize("change,reason", [
    (dict(directory="/nonexistent/meter"), "outside the allowed roots"),
    (dict(directory="PRESETS/meter_1/19990101_000000"), "not found"),
    (dict(foreign_detect=3), "foreign_detect"),
    (dict(filename=[]), "filename has 0 entries"),
    (dict(filename=["PIC", "PIC"] * 2), "filename has 4 entries"),
    (dict(filename=["PIC"] * 5), "filename has 5 entries"),
    (dict(filename=["PICTURES/missing.jpg"]), "unreadable"),
    (dict(roi_vertex=[1, 2, 3]), "8 numbers per box"),
    (dict(roi_vertex="DROP8"), "roi_vertex has 2 box"),
    (dict(roi_vertex="SHIFT"), "outside the 480x270 picture"),
    (dict(roi_vertex="TWIST"), "not a convex"),
    (dict(roi_vertex_thermal=[0] * 8), "roi_vertex_thermal has 1 box"),
    (dict(foreign_detect=1, foreign_filename=[]), "foreign_filename is empty"),
])
def test_bad_requests_fail_with_a_reason(setup, change, reason):
    reader, path, picture, roi, _scene = setup
    args = dict(directory=path, foreign_detect=0, filename=[picture], foreign_filename=[], roi_vertex=roi,
                roi_vertex_thermal=[])
    args.update(change)
    if args["roi_vertex"] == "DROP8":
        args["roi_vertex"] = roi[:16]
    elif args["roi_vertex"] == "SHIFT":
        args["roi_vertex"] = [v + 400 for v in roi]
    elif args["roi_vertex"] == "TWIST":
        args["roi_vertex"] = roi[2:4] + roi[0:2] + roi[4:]
    presets = os.path.dirname(os.path.dirname(path))
    args["directory"] = args["directory"].replace("PRESETS", presets)
    args["filename"] = [f.replace("PICTURES", os.path.dirname(picture)).replace("PIC", picture)
                        if f != "PIC" else picture for f in args["filename"]]
    with pytest.raises(ReadError) as err:
        reader.read(args["directory"], args["foreign_detect"], args["filename"], args["foreign_filename"],
                    args["roi_vertex"], args["roi_vertex_thermal"], STAMP)
    assert reason in str(err.value)


def test_thermal_target(tmp_path):
    from inspection_robot.inspection.calibration import calibrate
    from inspection_robot.files import write_atomic
    from inspection_robot.inspection.preset import PresetDirWriter, PresetInfo
    with PresetDirWriter(str(tmp_path), "hot", "20260101_000000") as writer:
        cv2.imwrite(writer.file("zoom0.jpg"), np.zeros((90, 160, 3), np.uint8))
        info = PresetInfo("hot", "infrared", True, "20260101_000000", 0, 0, 1.0, 0x4000, (0, 0, 0), [1.0], 160, 90)
        write_atomic(writer.file("preset.ini"), info.to_ini())
        calibrate(writer.path, [{"kind": "thermal", "box": [10, 10, 50, 10, 50, 50, 10, 50],
                                 "thermal_box": [5, 5, 30, 5, 30, 30, 5, 30]}], S.linear_optics(160, 90))
        path = writer.commit()
    frame = np.full((60, 80), 20.0, np.float32)
    frame[12, 14] = 65.25
    np.save(str(tmp_path / "frame.npy"), frame)
    reader = ScaleReader([str(tmp_path)], [str(tmp_path)], str(tmp_path / "out"))
    out = reader.read(path, 0, [str(tmp_path / "frame.npy")], [], [10, 10, 50, 10, 50, 50, 10, 50],
                      [5, 5, 30, 5, 30, 30, 5, 30], STAMP)
    assert out.scale == [pytest.approx(65.25)]
    assert os.path.isfile(out.picture_path[0])


def test_a_box_that_is_not_the_gauge_fails_with_the_reason(setup, tmp_path):
    reader, path, picture, roi, _scene = setup
    other = os.path.join(os.path.dirname(picture), "zoom0_20260102_080000_07.jpg")
    rng = np.random.default_rng(21)
    cv2.imwrite(other, S.textured_background(480, 270, rng))
    with pytest.raises(ReadError) as err:
        reader.read(path, 0, [other], [], roi, [], STAMP)
    assert "box 0: the box does not show the calibrated gauge" in str(err.value)
    blank = os.path.join(os.path.dirname(picture), "zoom0_20260102_080000_08.jpg")
    cv2.imwrite(blank, np.full((270, 480, 3), 255, np.uint8))
    with pytest.raises(ReadError) as err:
        reader.read(path, 0, [blank], [], roi, [], STAMP)
    assert "box 0: overexposed picture in the box" in str(err.value)


def test_uncertain_readings_say_why_in_the_result():
    from inspection_robot.inspection.reading import ReadOutcome, result_text
    fine = ReadOutcome([1.0, 0.0], [90.0, 80.0], [], [], [], [], ["", ""])
    assert result_text(fine, "success") == "success"
    unsure = ReadOutcome([1.0, 0.0, 2.0], [30.0, 80.0, 20.0], [], [], [], [],
                         ["two pointers 40 deg apart", "", "glare"])
    assert result_text(unsure, "success") == "uncertain: box 0: two pointers 40 deg apart; box 2: glare"


@pytest.mark.parametrize("change,reason", [
    (dict(start_value=1.0, end_value=1.0), "must differ"),
    (dict(centre=(1.2, 0.5)), "centre"),
    (dict(radius=0.0), "radius"),
    (dict(pointer_colour="purple"), "pointer_colour"),
])
def test_bad_pointer_calibrations_are_refused(tmp_path, change, reason):
    from inspection_robot.inspection.calibration import calibrate
    from inspection_robot.files import write_atomic
    from inspection_robot.inspection.preset import PresetDirWriter, PresetError, PresetInfo
    spec = {"kind": "pointer", "box": [10, 10, 70, 10, 70, 70, 10, 70], "start_angle": 225, "end_angle": 135,
            "start_value": 0.0, "end_value": 1.6}
    spec.update(change)
    with PresetDirWriter(str(tmp_path), "m", "20260101_000000") as writer:
        cv2.imwrite(writer.file("zoom0.jpg"), np.zeros((90, 160, 3), np.uint8))
        info = PresetInfo("m", "visible", False, "20260101_000000", 0, 0, 1.0, 0x4000, (0, 0, 0), [1.0], 160, 90)
        write_atomic(writer.file("preset.ini"), info.to_ini())
        with pytest.raises(PresetError) as err:
            calibrate(writer.path, [spec], S.linear_optics(160, 90))
    assert reason in str(err.value)


def test_colour_hints_round_trip_and_old_calibrations_load(setup):
    from inspection_robot.inspection.preset import Target
    _reader, path, _picture, _roi, _scene = setup
    old = load_preset(path).targets[0]
    assert old.params["pointer_colour"] == "" and old.params["ignore_colour"] == ""
    assert "pointer_colour" not in old.section()
    hinted = Target("pointer", old.boxes, name="x", **dict(old.params, pointer_colour="dark", ignore_colour="red"))
    section = hinted.section()
    assert (section["pointer_colour"], section["ignore_colour"]) == ("dark", "red")
    again = Target.from_section(dict((k, str(v)) for k, v in section.items()), old.boxes)
    assert again.params["ignore_colour"] == "red"


def test_only_a_pointer_box_may_reach_out_of_the_picture():
    """A pointer's box partly outside the picture is read (the reader judges the dial inside it);
    a lamp's or switch's box, or a box wholly outside, is refused."""
    from inspection_robot.inspection.reading import _check_quad
    quad = np.array([[-20.0, 10.0], [100.0, 10.0], [100.0, 130.0], [-20.0, 130.0]])
    _check_quad(quad, (270, 480, 3), "box 0", partly_outside=True)
    with pytest.raises(ReadError) as err:
        _check_quad(quad, (270, 480, 3), "box 1")
    assert "box 1 lies outside the 480x270 picture" in str(err.value)
    with pytest.raises(ReadError):
        _check_quad(quad + 1000.0, (270, 480, 3), "box 0", partly_outside=True)


def test_the_finder_accepts_a_pointer_box_reaching_out_when_its_dial_is_inside():
    from types import SimpleNamespace
    from inspection_robot.inspection.finder import readable_in
    from inspection_robot.inspection.gauge import GaugeScale
    pointer = SimpleNamespace(kind="pointer", params={"centre": (0.5, 0.5), "radius": 0.45, "aspect": 1.0},
                              scale=GaugeScale(225, 135, 0.0, 1.6))
    lamp = SimpleNamespace(kind="lamp", params={}, scale=None)
    corner_out = np.array([[-10.0, -10.0], [160.0, -10.0], [160.0, 160.0], [-10.0, 160.0]])  # the dial inside
    arc_out = corner_out - [60.0, 0.0]                                                        # part of the arc out
    assert readable_in(pointer, corner_out, (270, 480, 3))
    assert not readable_in(lamp, corner_out, (270, 480, 3))
    assert not readable_in(pointer, arc_out, (270, 480, 3))
    assert readable_in(lamp, corner_out + 20.0, (270, 480, 3))


@pytest.mark.parametrize("kinds", [["pointer"], ["pointer", "switch"], ["switch", "pointer"], ["pointer", "thermal"],
                                   ["thermal", "pointer"], ["pointer", "lamp", "switch", "thermal"],
                                   ["pointer", "pointer", "thermal", "lamp"]])
def test_task_managers_filenames_give_every_target_its_own_pictures(kinds):
    """request_filenames as task_manager sends it, parsed as read_scale parses it: every target
    reads the found picture (a thermal one its frame) and only pointers the second look, whatever
    the count (a 2-target preset's [picture, second] once read the switch in the second picture,
    taken later with the robot still turning, at the box found in the first)."""
    from collections import namedtuple
    from inspection_robot.inspection.reading import _pictures_per_box, request_filenames
    Kind = namedtuple("Kind", "kind")
    targets = [Kind(k) for k in kinds]
    thermal_ids = [i for i, k in enumerate(kinds) if k == "thermal"]
    for second in ("look2.jpg", ""):
        files = request_filenames(kinds, "found.jpg", "frame.png" if thermal_ids else "", second)
        first, again = _pictures_per_box(files, targets, thermal_ids)
        assert first == ["frame.png" if k == "thermal" else "found.jpg" for k in kinds], files
        assert again == [second if k == "pointer" else "" for k in kinds], files
