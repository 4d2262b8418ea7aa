"""Drum counters (inspection.drum): learned from a picture and the typed value, read at rest and
between digits, doubted where a wheel cannot be told, refused when nothing shows; and the simulated
yard's arrester counter calibrated from the world and read at every count."""
import cv2
import numpy as np
import pytest

from inspection_robot.inspection import calibration_schema as schema
from inspection_robot.inspection.calibration import calibrate
from inspection_robot.inspection.drum import ROLLED, drum_model, learn_drum, own_digits, read_drum, render_drum
from inspection_robot.inspection.preset import PresetError, load_preset
from inspection_robot.inspection.readers import ReadFailed
from inspection_robot.inspection.reading import ScaleReader
from inspection_robot.sim.inspection_sim import world_specs
from inspection_robot.sim.world import World
from inspection_robot_testing.world_views import recorded_preset
from inspection_robot_testing.yard_patrol import config_file

QUAD = [[100, 70], [300, 70], [300, 130], [100, 130]]


def picture(positions, **style):
    """A 5-wheel counter at ``positions`` in a grey 400 x 200 picture, in QUAD."""
    image = np.full((200, 400, 3), 128, np.uint8)
    image[70:130, 100:300] = render_drum(positions, 200, 60, **style)
    return image


def odometer(value, wheels=5):
    """Each wheel's position for a count ``value`` (fractional: the last wheel turning, the ones
    above it turning only while those below pass 9 -> 0)."""
    positions = [0.0] * wheels
    positions[-1] = value % 10.0
    for k in range(wheels - 2, -1, -1):
        positions[k] = int(value // 10 ** (wheels - 1 - k)) % 10 + max(0.0, positions[k + 1] - 9.0)
    return positions


def shown(positions):
    """What the counter's convention reads: a wheel between two digits is the lower one, three
    quarters of the way the next."""
    return float("".join(str(int(np.floor(p + ROLLED)) % 10) for p in positions))


@pytest.mark.parametrize("font,pitch,polarity", [("duplex", 1.5, "lit"), ("complex", 1.3, "dark"),
                                                 ("triplex", 1.8, "lit")])
def test_a_turning_counter_is_read_right_or_doubted(font, pitch, polarity):
    style = dict(font=font, pitch=pitch, polarity=polarity)
    model = learn_drum(picture([0, 3, 4, 7, 2], **style), QUAD, list("03472"), 0)
    assert model.polarity == polarity
    rng = np.random.RandomState(7)
    confident = 0
    for value in list(rng.uniform(0, 99999, 40)) + [0.0, 99999.0, 1299.5, 8888.0, 6565.0]:
        positions = odometer(value)
        reading = read_drum(picture(positions, **style), QUAD, model)
        if reading.detail.get("reason"):
            assert reading.confidence <= 40.0
            continue
        confident += 1
        assert reading.value == shown(positions), (value, positions, reading.detail)
    assert confident >= 30   # the last wheel is random: a fifth of the time near where the next digit is read


def test_a_wheel_half_way_reads_the_lower_digit_and_says_so():
    model = learn_drum(picture([0, 1, 2, 9, 0]), QUAD, list("01290"), 0)
    reading = read_drum(picture([0, 1, 2, 9, 3.5]), QUAD, model)
    assert reading.value == 1293.0 and not reading.detail.get("reason")
    assert reading.detail["rolled"] == "wheel 5 between 3 and 4, read 3"
    carry = read_drum(picture(odometer(1299.5)), QUAD, model)   # 1299 -> 1300: three wheels turning together
    assert carry.value == 1299.0 and not carry.detail.get("reason"), carry.detail
    assert "wheel 3 between 2 and 3" in carry.detail["rolled"]


def test_a_wheel_half_way_above_one_at_rest_is_doubted():
    model = learn_drum(picture([0, 1, 2, 9, 0]), QUAD, list("01290"), 0)
    reading = read_drum(picture([0, 1, 2.5, 4, 0]), QUAD, model)
    assert "wheel 3 half-way while wheel 4 shows 4" in reading.detail["reason"]
    assert reading.confidence <= 40.0


def test_decimals_come_from_the_calibration():
    model = learn_drum(picture([0, 0, 4, 1, 7]), QUAD, list("00417"), 1)
    assert read_drum(picture([0, 0, 5, 2, 3]), QUAD, model).value == pytest.approx(52.3)


def test_nothing_to_read_and_what_cannot_be_learned_are_refused():
    model = learn_drum(picture([0, 3, 4, 7, 2]), QUAD, list("03472"), 0)
    blank = np.full((200, 400, 3), 128, np.uint8)
    with pytest.raises(ReadFailed) as err:
        read_drum(blank, QUAD, model)
    assert "no drum wheel shows a digit" in str(err.value)
    with pytest.raises(ReadFailed) as err:
        learn_drum(picture([0, 3, 4, 7, 2]), QUAD, list(" 3472"), 0)
    assert "type them all" in str(err.value)
    with pytest.raises(ReadFailed) as err:
        learn_drum(picture([0, 3, 4, 7, 2]), QUAD, list("58190"), 0)   # not what it shows
    assert "does not show '58190' on drum wheels" in str(err.value)
    with pytest.raises(ReadFailed) as err:   # the last wheel near where its next digit is read: no calibration
        learn_drum(picture([0, 3, 4, 7, 0.8]), QUAD, list("03471"), 0)
    assert "the learned counter reads '03471' on the calibration picture only in doubt (wheel 5 at" in str(err.value)


def printed(text, four, blur=0.0):
    """A 5-wheel counter showing ``text`` (at rest) in QUAD, its 4 printed open-topped like a water
    meter's (``four``: the diagonal's top x, the stem's x, the stem's top y in a 40 x 60 window) and
    its other digits in OpenCV's simplex font; ``blur``: the lens's Gaussian sigma in px."""
    image = np.full((200, 400, 3), 128, np.uint8)
    for k, char in enumerate(text):
        cell = np.full((60, 40), 30, np.uint8)
        if char == "4":
            top, stem, stem_top = four
            cv2.polylines(cell, [np.array([[top, 12], [8, 36], [32, 36]])], False, 230, 3, cv2.LINE_AA)
            cv2.line(cell, (stem, stem_top), (stem, 48), 230, 3, cv2.LINE_AA)
        else:
            (w, h), _ = cv2.getTextSize(char, cv2.FONT_HERSHEY_SIMPLEX, 1.2, 2)
            cv2.putText(cell, char, ((40 - w) // 2, (60 + h) // 2), cv2.FONT_HERSHEY_SIMPLEX, 1.2, 230, 2,
                        cv2.LINE_AA)
        image[70:130, 100 + 40 * k:140 + 40 * k] = cell[..., None]
    return cv2.GaussianBlur(image, (0, 0), blur) if blur else image


def test_a_digit_printed_unlike_the_fonts_is_read_by_its_own_print_or_doubted():
    """The stroke fonts misread a meter's own 4 once the lens softens it; the 4 shown at calibration
    reads it (its print near-identical, the font's digit's print clearly less like it), or doubts
    it when the font's digit was never seen printed (two digits of one print can be 0.9 alike)."""
    for four, font_reads, own_reads, reason in [
            ((16, 26, 12), 817, 817, "wheel 3: 8|4 (like the 4 printed at calibration, match 0.9"),
            ((20, 28, 12), 17, 417, None)]:
        model = learn_drum(printed("00401", four), QUAD, list("00401"), 0)
        own = own_digits(printed("00401", four), QUAD, model)
        assert sorted(own) == ["0", "1", "4"]
        live = printed("00417", four, blur=1.5)
        font_alone, with_own = read_drum(live, QUAD, model), read_drum(live, QUAD, model, own)
        assert font_alone.value == font_reads   # the font alone is wrong: confidently for the first 4
        assert (with_own.value, with_own.detail.get("reason", "")[:len(reason or "")] or None) == (own_reads, reason)
        if reason:
            assert with_own.detail["digits"][2]["candidates"] == ["8", "4"] and with_own.confidence <= 40.0
        else:
            assert "wheel 3 read 4, as printed at calibration (match 0.9" in with_own.detail["own"]
            assert with_own.detail["digits"][2]["candidates"] == ["4", "0"] and with_own.confidence > 40.0


def test_the_own_print_is_not_used_when_the_calibration_picture_reads_otherwise():
    model = learn_drum(picture([0, 3, 4, 7, 2]), QUAD, list("03472"), 0)
    assert sorted(own_digits(picture([0, 3, 4, 7, 2]), QUAD, model)) == ["0", "2", "3", "4", "7"]
    assert sorted(own_digits(picture([0, 3, 4, 7, 2.5]), QUAD, model)) == ["0", "3", "4", "7"]   # no half 2
    assert own_digits(picture([0, 3, 4.5, 7, 2]), QUAD, model) is None   # half-way above a wheel at rest: doubt
    assert own_digits(np.full((200, 400, 3), 128, np.uint8), QUAD, model) is None   # nothing shown


def test_the_schema_keeps_a_drums_model_apart_from_a_displays():
    drum = {"digit_count": 3, "polarity": "lit", "decimals": 0, "contrast": 150.0, "style": "drum",
            "font": "duplex", "glyph": 0.55}
    assert schema.check_params("digital", drum)["font"] == "duplex"
    for bad, words in [(dict(drum, slant=0.0), "slant does not apply to a drum display"),
                       (dict(drum, window=[0, 0, 1, 1]), "window does not apply to a drum display"),
                       (dict(drum, font="gothic"), "font must be one of"),
                       (dict((k, v) for k, v in drum.items() if k != "glyph"),
                        "missing key(s) glyph (a digital (drum)"),
                       (dict(drum, style="segments"), "missing key(s) slant, fill (a digital target needs")]:
        with pytest.raises(schema.SchemaError) as err:
            schema.check_params("digital", bad)
        assert words in str(err.value)


def test_the_yards_arrester_counter_is_read_at_every_count(tmp_path):
    world = World.load(config_file("sim_world.yaml"))
    path, head, optics, _pose = recorded_preset(world, str(tmp_path), "b2", "breaker_2", 3.5, 1.45, 2.0, 1280, 720)
    (spec,) = [s for s in world_specs(world, head) if s["name"] == "breaker_2/arrester_counter"]
    assert spec["style"] == "drum" and spec["shown"] == "007" and spec["counter"]
    calibrate(path, [spec], optics)   # as an upload: the model learned from zoom0.jpg and "shown", then stored
    (target,) = load_preset(path).targets
    assert sorted(target.params) == ["contrast", "counter", "decimals", "digit_count", "font", "glyph", "polarity",
                                     "style", "unit"]
    box = np.reshape(spec["box"], (4, 2))
    preset = load_preset(path)
    assert own_digits(cv2.imread(preset.picture(0)), target.boxes[0], drum_model(target.params))   # its 0 and 7
    reader = ScaleReader(str(tmp_path), [str(tmp_path)], [str(tmp_path)], str(tmp_path))
    for count in list(range(0, 1000, 53)) + [8, 386, 654, 888, 666, 555, 999]:
        world.set_value("breaker_2/arrester_counter", count)
        reading = reader.read_target(preset, target, head.capture(None), box)   # as read_scale: with its own print
        assert (reading.value, reading.detail.get("reason"), reading.detail.get("own")) == (count, None, None), \
            (count, reading.detail)


def test_a_drum_calibration_that_cannot_hold_is_refused(tmp_path):
    world = World.load(config_file("sim_world.yaml"))
    path, head, optics, _pose = recorded_preset(world, str(tmp_path), "b2", "breaker_2", 3.5, 1.45, 2.0, 1280, 720)
    (spec,) = [s for s in world_specs(world, head) if s["name"] == "breaker_2/arrester_counter"]
    for shown, words in [("0071", "does not show '0071' on drum wheels"), (" 07", "type them all"),
                         ("2x7", "is not what a seven-segment display shows")]:
        with pytest.raises(PresetError) as err:
            calibrate(path, [dict(spec, shown=shown)], optics)
        assert "target 0 (digital): " in str(err.value) and words in str(err.value)
