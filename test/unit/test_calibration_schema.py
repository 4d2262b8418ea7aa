"""The calibration schema: every stored key survives its INI text; values are refused by name."""
import math

import numpy as np
import pytest

from inspection_robot.inspection import calibration_schema as schema

GOOD = {"name": "oil", "digits": 2, "normal": [0.2, 1.4], "start_angle": -135.0, "end_angle": 135.0, "start_value": 0.0,
        "end_value": 1.6, "unit": "MPa %", "centre": [0.5, 0.55], "radius": 0.42, "aspect": 1.25,
        "scale_table": [[0.0, -135.0], [0.8, 0.0], [1.6, 135.0]],
        "marks": [[0.0, 0.18, 0.82], [1.6, 0.82, 0.82]], "pointer_colour": "dark", "ignore_colour": "red",
        "colour": "green", "on_reference": "target_0_on.png", "off_reference": "target_0_off.png",
        "open_reference": "a.png", "closed_reference": "b.png", "needle_reference": "target_0_needle.png",
        "thermal_box": [5.0, 5.0, 30.5, 5.0, 30.5, 30.0, 5.0, 30.0], "phase": "B", "device": "T1 bay 3",
        "equipment_class": "breaker", "emissivity": 0.9, "distance": 12.5, "digit_count": 4, "polarity": "dark",
        "slant": -6.0, "fill": 0.75, "style": "drum", "font": "duplex_bold", "glyph": 0.55, "decimals": 1,
        "contrast": 77.5, "window": [-0.04, 0.0, 1.04, 0.96], "cell_shifts": [-0.1, 0.25, 0.0],
        "split": "face", "counter": True, "alarm_band": [0.0, 1.6]}


@pytest.mark.parametrize("key", sorted(k for k, f in schema.FIELDS.items() if f.stored))
def test_every_stored_key_round_trips_through_its_text(key):
    assert key in GOOD, "add an example of %s" % key
    assert schema.from_text(key, schema.to_text(key, GOOD[key])) == GOOD[key]


def test_a_whole_pointer_round_trips_with_defaults():
    params = schema.check_params("pointer", {"start_angle": 225, "end_angle": 135, "start_value": 0,
                                             "end_value": 10})
    assert params["centre"] == [0.5, 0.5] and params["radius"] == 0.45 and params["marks"] == []
    section = schema.params_to_section(params)
    assert "marks" not in section and "pointer_colour" not in section and section["scale_table"] == ""
    again = dict((k, schema.from_text(k, t)) for k, t in section.items())
    assert schema.check_params("pointer", dict((k, v) for k, v in again.items() if v is not None)) == params


@pytest.mark.parametrize("key,value,reason", [
    ("end_value", float("inf"), "end_value must be a finite number, got inf"),
    ("end_value", float("nan"), "end_value must be a finite number, got nan"),
    ("end_value", 10 ** 400, "end_value must be a finite number"),
    ("end_value", True, "end_value must be a finite number, got True"),
    ("end_value", "1.6", "end_value must be a finite number, got '1.6'"),
    ("end_value", np.float64(2e9), "end_value must be in [-1e+09, 1e+09]"),
    ("start_angle", -361, "start_angle must be in [-360, 360], got -361"),
    ("radius", 0.0, "radius must be in (0, 1.5], got 0"),
    ("centre", [0.5], "centre must be a list of 2 numbers"),
    ("centre", [0.5, 1.01], "centre must be in [0, 1], got 1.01"),
    ("scale_table", [[0, 1], [1]], "scale_table entries must be [value, angle]"),
    ("scale_table", [[0, 1], [0, 2]], "scale_table values must be strictly monotonic"),
    ("marks", [[0, -0.1, 0.5]], "marks u must be in [0, 1], got -0.1"),
    ("thermal_box", [0, 0, 1, 0, 1, 1, 0, math.inf], "thermal_box must be a finite number, got inf"),
    ("normal", [1, 0], "normal must be [low, high], low 1 is above high 0"),
    ("open_reference", "sub/a.png", "open_reference must be a file name in the preset directory"),
    ("open_reference", ".hidden.png", "open_reference must be a file name"),
    ("name", "x" * 201, "name must be at most 200 characters"),
    ("radus", 0.4, "unknown key 'radus'"),
    ("phase", "D", "phase must be one of A|B|C|ambient, got 'D'"),
    ("equipment_class", "clamp", "equipment_class must be one of connector|metal_joint|"),
    ("emissivity", 0.05, "emissivity must be in [0.1, 1], got 0.05"),
    ("emissivity", 1.2, "emissivity must be in [0.1, 1], got 1.2"),
    ("emissivity", float("nan"), "emissivity must be a finite number"),
    ("distance", 0.0, "distance must be in (0, 100], got 0.0"),
    ("window", [0.5, 0.0, 0.4, 1.0], "window must be [left, top, right, bottom] with left < right"),
    ("window", [0.0, 0.0, 2.0, 1.0], "window must be in [-0.5, 1.5], got 2.0"),
    ("cell_shifts", [0.0, 0.7], "cell_shifts must be in [-0.5, 0.5], got 0.7"),
    ("cell_shifts", [], "cell_shifts must be a list of 1 to 12 numbers"),
    ("split", "middle", "split must be one of gap|face"),
    ("distance", 150, "distance must be in (0, 100], got 150.0"),
    ("distance", "10 m", "distance must be a finite number"),
    ("counter", 1, "counter must be true or false, got 1"),
    ("counter", "yes", "counter must be true or false, got 'yes'"),
])
def test_values_are_refused_by_name(key, value, reason):
    with pytest.raises(schema.SchemaError) as err:
        schema.check_value(key, value)
    assert reason in str(err.value)


@pytest.mark.parametrize("key,text,reason", [
    ("end_value", "inf", "end_value must be a finite number, got inf"),
    ("end_value", "1.6x", "end_value: cannot read '1.6x'"),
    ("marks", "0:0.5", "marks: cannot read"),
    ("radus", "0.4", "unknown key 'radus'"),
    ("open_picture", "x.png", "unknown key 'open_picture'"),    # a spec key, never in the file
])
def test_file_text_is_refused_by_name(key, text, reason):
    with pytest.raises(schema.SchemaError) as err:
        schema.from_text(key, text)
    assert reason in str(err.value)


def test_keys_belong_to_their_kind():
    with pytest.raises(schema.SchemaError) as err:
        schema.check_params("thermal", {"thermal_box": GOOD["thermal_box"], "unit": "degC"})
    assert "key 'unit' does not apply to a thermal target (pointer|digital only)" in str(err.value)
    with pytest.raises(schema.SchemaError) as err:
        schema.check_params("switch", {"open_reference": "a.png"})
    assert "missing key(s) closed_reference" in str(err.value)
    assert schema.check_params("thermal", {"thermal_box": GOOD["thermal_box"]}, thermal_size=(32, 31))
    with pytest.raises(schema.SchemaError) as err:
        schema.check_params("thermal", {"thermal_box": GOOD["thermal_box"]}, thermal_size=(30, 40))
    assert "thermal_box lies outside the 30x40 thermal picture" in str(err.value)


def test_a_thermal_device_needs_a_phase():
    box = [5.0, 5.0, 30.5, 5.0, 30.5, 30.0, 5.0, 30.0]
    assert schema.check_params("thermal", {"thermal_box": box, "phase": "A", "device": "T1"})["device"] == "T1"
    with pytest.raises(schema.SchemaError) as err:
        schema.check_params("thermal", {"thermal_box": box, "device": "T1"})
    assert "device 'T1' needs a phase (A|B|C|ambient)" in str(err.value)
    with pytest.raises(schema.SchemaError) as err:
        schema.check_params("pointer", {"start_angle": 0, "end_angle": 90, "start_value": 0, "end_value": 1,
                                        "phase": "A"})
    assert "key 'phase' does not apply to a pointer target (thermal only)" in str(err.value)


@pytest.mark.parametrize("limits, reason", [
    ({"normal": [0, 10], "alarm_band": [1, 12]}, "alarm band [1, 12] must contain the normal band [0, 10]"),
    ({"alarm_band": [0, 12]}, "alarm_band needs a normal band inside it (normal [low, high])"),
    ({"normal": [0, 10], "alarm_band": [0, float("nan")]}, "alarm_band must be a finite number, got nan"),
    ({"normal": [0, 10], "alarm_band": [12, 0]}, "alarm_band must be [low, high], low 12 is above high 0"),
])
def test_an_alarm_band_contains_the_normal_band(limits, reason):
    box = [5.0, 5.0, 30.5, 5.0, 30.5, 30.0, 5.0, 30.0]
    with pytest.raises(schema.SchemaError) as err:
        schema.check_params("thermal", dict(limits, thermal_box=box))
    assert reason in str(err.value)
    good = schema.check_params("thermal", {"thermal_box": box, "normal": [0, 70], "alarm_band": [-20, 90]})
    assert (good["normal"], good["alarm_band"]) == ([0.0, 70.0], [-20.0, 90.0])
