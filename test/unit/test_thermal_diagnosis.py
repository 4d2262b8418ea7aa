"""thermal.diagnosis and task.rows: DL/T 664 grading of three-phase devices, on radiometric matrices
read as a patrol reads them (inspection.thermal_max), with a known answer at every grade boundary."""
import json

import numpy as np
import pytest

from inspection_robot.inspection.thermal_max import read_thermal_max
from inspection_robot.task.patrol import Inspection
from inspection_robot.task.rows import reading_rows, thermal_findings
from inspection_robot.task.states import ALARM_ALARM, ALARM_CHECK, ALARM_NONE, ALARM_NORMAL
from inspection_robot.thermal.diagnosis import (DEFAULT_RULES, GRADE_CRITICAL, GRADE_GENERAL, GRADE_NONE,
                                                GRADE_SERIOUS, DiagnosisError, check_rules, diagnose,
                                                object_temperature, thermal_groups, transmission)

CONNECTOR = DEFAULT_RULES["connector"]      # serious > 80 C or dt >= 80 %, critical > 110 C or dt >= 95 %
BOXES = {"A": [(10, 10), (40, 10), (40, 40), (10, 40)], "B": [(60, 10), (90, 10), (90, 40), (60, 40)],
         "C": [(110, 10), (140, 10), (140, 40), (110, 40)], "ambient": [(10, 70), (140, 70), (140, 95), (10, 95)]}


def frame(phases, ambient, background=None):
    """A 100 x 160 radiometric frame (degC): each phase box warm to its value at one hot pixel (its
    clamp), the ambient strip at ``ambient``, the rest ``background`` (ambient - 2 by default)."""
    image = np.full((100, 160), (ambient - 2.0) if background is None else background, np.float32)
    image[72:94, 12:138] = ambient
    for phase, hot in phases.items():
        (x0, y0), (x1, y1) = BOXES[phase][0], BOXES[phase][2]
        image[y0 + 2:y1 - 2, x0 + 2:x1 - 2] = ambient + 0.5 * (hot - ambient)
        image[(y0 + y1) // 2, (x0 + x1) // 2] = hot
    return image


def read_device(image, phases=("A", "B", "C")):
    """The box maxima a patrol stores: {phase: degC}, ambient."""
    values = dict((p, read_thermal_max(image, BOXES[p]).value) for p in phases)
    return values, read_thermal_max(image, BOXES["ambient"], "ambient").value


def test_an_ambient_box_partly_off_its_plate_reads_the_plate_not_the_warm_equipment_beside_it():
    # a 25 C plate on a 45 C transformer, its box a third off the plate (the robot stopped a little aside)
    image = np.full((100, 160), 45.0, np.float32)
    image[60:100, 0:100] = 25.0
    box = [(40, 70), (140, 70), (140, 95), (40, 95)]
    plate = read_thermal_max(image, box, "ambient")
    assert plate.value == pytest.approx(25.0) and plate.detail["statistic"] == "median"
    assert read_thermal_max(image, box, "A").value == pytest.approx(45.0)   # a phase box: its hottest pixel


def graded(phases, ambient, rule=CONNECTOR):
    values, t0 = read_device(frame(phases, ambient), tuple(phases))
    return diagnose(values, t0, rule, "connector")


# --- every grade boundary of the connector class, from frames --------------------------------------
@pytest.mark.parametrize("hot,expected", [
    # ambient 20, sisters 30: rise 10..: dt = (T1 - 30) / (T1 - 20)
    (35.0, GRADE_NONE),       # rise 15 (relative method applies), dt 33 %, 5 K over: nothing
    (35.4, GRADE_GENERAL),    # dt 35.06 % >= 35 %
    (44.9, GRADE_GENERAL),    # dt 59.8 %
    (70.0, GRADE_SERIOUS),    # dt 80.0 % >= 80 % exactly
    (69.9, GRADE_GENERAL),    # dt 79.96 %: just under
])
def test_relative_difference_boundaries(hot, expected):
    d = graded({"A": 30.0, "B": hot, "C": 30.0}, 20.0)
    assert d.grade == expected, d.rule
    assert d.hot_phase == "B" and d.t2 == pytest.approx(30.0) and d.t0 == pytest.approx(20.0)


def test_critical_by_dt_and_the_rule_names_it():
    # sisters 21, ambient 20, hot 41: dt = 20 / 21 = 95.2 % >= 95 %
    d = graded({"A": 21.0, "B": 21.0, "C": 41.0}, 20.0)
    assert d.grade == GRADE_CRITICAL and d.hot_phase == "C"
    assert d.rule == "critical defect (connector): dt 95 % >= 95 %"
    assert graded({"A": 21.2, "B": 21.2, "C": 41.0}, 20.0).grade == GRADE_SERIOUS    # dt 93.9 %


def test_hot_spot_temperature_grades_without_any_comparison():
    # one box, no sisters, no ambient: the absolute criteria still hold (> is strict)
    assert diagnose({"A": 80.0}, None, CONNECTOR).grade == GRADE_NONE
    assert diagnose({"A": 80.1}, None, CONNECTOR).grade == GRADE_SERIOUS
    assert diagnose({"A": 110.0}, None, CONNECTOR).grade == GRADE_SERIOUS
    d = diagnose({"A": 110.1}, None, CONNECTOR)
    assert d.grade == GRADE_CRITICAL and d.rule == "critical defect (connector): hot spot 110.1 C > 110 C"
    assert "no sister phase" in diagnose({"A": 50.0}, None, CONNECTOR).rule


def test_small_rises_do_not_use_the_ratio_but_a_15_k_difference_is_general():
    # ambient 30, sisters 31, hot 44: rise 14 K < 15 K: dt (93 %) not applied, 13 K difference: nothing
    d = graded({"A": 31.0, "B": 31.0, "C": 44.0}, 30.0)
    assert d.grade == GRADE_NONE and d.delta_t is None and "rise 14.0 K over ambient under 15 K" in d.rule
    # without an ambient box: dt unknown, but T1 - T2 over 15 K is a general defect
    d = diagnose({"A": 30.0, "B": 45.1, "C": 30.0}, None, CONNECTOR)
    assert d.grade == GRADE_GENERAL and d.rule == "general defect (connector): 15.1 K over the coolest phase > 15 K"
    assert diagnose({"A": 30.0, "B": 45.0, "C": 30.0}, None, CONNECTOR).grade == GRADE_NONE


def test_the_issue_case_a_connector_25_k_over_its_sisters_at_30_c():
    # its own band would call 55 C normal; compared with its sisters it is a serious defect
    d = graded({"A": 30.0, "B": 55.0, "C": 30.0}, 25.0)
    assert d.grade == GRADE_SERIOUS and d.delta_t == pytest.approx(83.3, abs=0.1)


def test_the_coolest_sister_is_the_reference_so_two_hot_phases_do_not_hide_each_other():
    d = graded({"A": 60.0, "B": 62.0, "C": 30.0}, 25.0)
    assert d.hot_phase == "B" and d.t2 == pytest.approx(30.0) and d.grade == GRADE_SERIOUS


def test_classes_differ_a_breaker_contact_is_critical_where_a_clamp_is_not():
    assert diagnose({"A": 81.0}, None, DEFAULT_RULES["breaker"]).grade == GRADE_CRITICAL   # > 80 C
    assert diagnose({"A": 81.0}, None, DEFAULT_RULES["connector"]).grade == GRADE_SERIOUS
    assert diagnose({"A": 81.0}, None, DEFAULT_RULES["metal_joint"]).grade == GRADE_NONE   # serious > 90 C


# --- rules a site overrides -----------------------------------------------------------------------
def test_overrides_apply_and_bad_ones_are_refused_by_name():
    rules = check_rules({"breaker": {"general_delta": 35}})
    assert rules["breaker"].general_delta == 35.0 and rules["connector"] == CONNECTOR
    for bad, words in [({"brekaer": {}}, "unknown equipment class 'brekaer'"),
                       ({"breaker": {"general_dlta": 1}}, "unknown field(s) general_dlta"),
                       ({"breaker": {"serious_hot": float("nan")}}, "breaker.serious_hot must be a finite number"),
                       ({"breaker": {"serious_hot": True}}, "must be a finite number"),
                       ({"breaker": {"general_delta": 90}}, "general <= serious <= critical"),
                       ({"breaker": {"critical_delta": 120}}, "in (0, 100]"),
                       ({"breaker": {"serious_hot": 100}}, "serious_hot 100 is above critical_hot 80"),
                       ({"breaker": 5}, "expected {field: number}")]:
        with pytest.raises(DiagnosisError) as err:
            check_rules(bad)
        assert words in str(err.value)


# --- emissivity -----------------------------------------------------------------------------------
def test_emissivity_correction_inverts_the_grey_body_radiance():
    k = 273.15
    true, reflected, e = 60.0, 20.0, 0.7
    apparent = (e * (true + k) ** 4 + (1 - e) * (reflected + k) ** 4) ** 0.25 - k
    assert apparent < true
    assert object_temperature(apparent, e, reflected) == pytest.approx(true, abs=1e-6)
    assert object_temperature(42.0, 1.0, 20.0) == 42.0
    with pytest.raises(DiagnosisError) as err:
        object_temperature(-60.0, 0.2, 40.0)
    assert "below what emissivity 0.20 reflects from 40.0 C" in str(err.value)


# --- distance -------------------------------------------------------------------------------------
def test_air_absorbs_more_over_a_longer_and_wetter_path():
    assert transmission(0.0, 20.0) == 1.0
    taus = [transmission(d, 20.0) for d in (1.0, 5.0, 10.0, 20.0, 50.0, 100.0)]
    assert taus == sorted(taus, reverse=True) and 0.9 < taus[-1] < taus[0] < 1.0
    assert transmission(10.0, 20.0, humidity=90.0) < transmission(10.0, 20.0, humidity=20.0)
    assert transmission(10.0, 35.0) < transmission(10.0, -10.0)   # warm air holds more water
    assert 0.96 < transmission(10.0, 20.0) < 0.99                # FLIR's model: ~0.97 at 10 m, 20 C, 50 %


def test_an_ambient_box_far_from_air_temperatures_is_refused_or_used_never_a_crash():
    # a hot plate taken for the ambient box: the vapour formula is held to the air's range
    assert transmission(30.0, 600.0) == transmission(30.0, 60.0) > 0.8
    for ambient in (300.0, 600.0, -200.0):
        try:
            value = object_temperature(90.0, 0.9, ambient, 30.0)
        except DiagnosisError as err:
            assert "below what emissivity 0.90 reflects" in str(err)
        else:
            assert value == value and abs(value) < 1e4


def test_distance_correction_inverts_the_path_through_the_air():
    k = 273.15
    true, air, e, d = 85.0, 25.0, 0.8, 30.0
    tau = transmission(d, air)
    seen = tau * (e * (true + k) ** 4 + (1 - e) * (air + k) ** 4) + (1 - tau) * (air + k) ** 4
    apparent = seen ** 0.25 - k
    assert apparent < true - 5.0
    assert object_temperature(apparent, e, air, d) == pytest.approx(true, abs=1e-6)
    # a blackbody across the yard reads a little cool, and the correction grows with the distance
    near, far = object_temperature(80.0, 1.0, 20.0, 5.0), object_temperature(80.0, 1.0, 20.0, 50.0)
    assert 80.0 < near < far < 85.0
    assert object_temperature(20.0, 1.0, 20.0, 50.0) == pytest.approx(20.0)   # air as warm as the box: no change


# --- groups ---------------------------------------------------------------------------------------
def test_groups_share_the_preset_ambient_unless_they_have_their_own():
    groups = thermal_groups([(0, "A", "t1"), (1, "B", "t1"), (2, "ambient", ""), (3, "A", "t2"),
                             (4, "ambient", "t2"), (5, "", "")])
    assert groups == {"t1": ({"A": 0, "B": 1}, 2), "t2": ({"A": 3}, 4)}
    for entries, words in [([(0, "A", "x"), (1, "A", "x")], "device 'x' has phase A twice (targets 0 and 1)"),
                           ([(0, "ambient", ""), (1, "ambient", "")], "device '' has two ambient boxes")]:
        with pytest.raises(DiagnosisError) as err:
            thermal_groups(entries)
        assert words in str(err.value)


# --- rows a patrol stores --------------------------------------------------------------------------
def preset(targets, alarms=None):
    return {"preset": "p", "directory": "/d/presets/p/1", "targets": targets, "alarms": alarms or {}, "foreign": False}


def phase_target(name, phase, **extra):
    target = {"name": name, "kind": "thermal", "unit": "C", "decimals": 1, "phase": phase}
    target.update(extra)
    return target


THREE_PHASE = [phase_target("clamp_a", "A", device="T1", equipment_class="connector"),
               phase_target("clamp_b", "B", device="T1"), phase_target("clamp_c", "C", device="T1"),
               phase_target("air", "ambient")]


def rows_for(values, targets=THREE_PHASE, alarms=None, reasons=None):
    inspection = Inspection(values, [95.0] * len(values), [""] * len(values), (1.0, 2.0, 0.0), None, reasons)
    return reading_rows("t1", 0, "bay 1", 0, preset(targets, alarms), inspection, "", 1000.0)


def test_the_hot_phase_row_is_an_alarm_with_its_grade_and_every_phase_carries_the_diagnosis():
    image = frame({"A": 30.0, "B": 55.0, "C": 30.2}, 25.0)
    values = [read_thermal_max(image, BOXES[p], p).value for p in ("A", "B", "C", "ambient")]
    rows = rows_for(values, alarms={"clamp_b": [-20.0, 90.0]})   # its own band calls 55 C normal
    a, b, c, air = rows
    assert b["grade"] == GRADE_SERIOUS and b["alarm"] == ALARM_ALARM
    assert b["reason"] == ("serious defect (connector): dt 83 % >= 80 % "
                           "(phase B 55.0 C, coolest sister 30.0 C, ambient 25.0 C)")
    assert a["grade"] == c["grade"] == GRADE_NONE and a["alarm"] == ALARM_NONE and c["alarm"] == ALARM_NONE
    d = json.loads(a["diagnosis"])
    assert d["device"] == "T1" and d["hot_phase"] == "B" and d["delta_t"] == pytest.approx(83.33, abs=0.01)
    assert d["phases"] == {"A": 30.0, "B": 55.0, "C": 30.2}
    assert air["diagnosis"] == "" and air["grade"] == ""


def test_a_healthy_device_keeps_its_band_alarm_and_an_uncertain_defect_is_a_check():
    rows = rows_for([30.0, 31.0, 30.5, 25.0], alarms={"clamp_b": [0.0, 40.0]})
    assert [r["grade"] for r in rows] == ["", "", "", ""] and rows[1]["alarm"] == ALARM_NORMAL
    assert json.loads(rows[1]["diagnosis"])["rule"] == ("no defect (connector); relative method not applied: "
                                                        "rise 6.0 K over ambient under 15 K")
    rows = rows_for([30.0, 55.0, 30.0, 25.0], reasons=["", "glare on the box", "", ""])
    assert rows[1]["alarm"] == ALARM_CHECK and rows[1]["reason"].endswith("; glare on the box")


def test_emissivity_raises_the_stored_value_and_keeps_the_apparent_one():
    targets = [phase_target("clamp_a", "A", device="T1", emissivity=0.6), phase_target("clamp_b", "B", device="T1"),
               phase_target("air", "ambient")]
    rows = rows_for([50.0, 40.0, 20.0], targets=targets)
    assert rows[0]["value"] > 60.0 and rows[1]["value"] == 40.0
    assert json.loads(rows[0]["diagnosis"])["apparent"] == {"A": 50.0, "B": 40.0}


def test_distance_raises_the_stored_value_and_without_ambient_is_named_not_applied():
    targets = [phase_target("clamp_a", "A", device="T1", distance=40.0), phase_target("clamp_b", "B", device="T1"),
               phase_target("air", "ambient")]
    rows = rows_for([80.0, 40.0, 20.0], targets=targets)
    assert 81.0 < rows[0]["value"] < 85.0 and rows[1]["value"] == 40.0
    findings = thermal_findings(targets[:2], [80.0, 40.0])
    assert findings[0]["value"] == 80.0
    assert findings[0]["diagnosis"]["notes"] == ["emissivity and distance of phase A not applied: no ambient reading"]


def test_a_phase_not_read_is_named_and_the_others_are_diagnosed():
    findings = thermal_findings(THREE_PHASE, [30.0, None, 58.0, 25.0])
    assert sorted(findings) == [0, 2] and findings[2]["grade"] == GRADE_SERIOUS
    assert findings[0]["diagnosis"]["notes"] == ["phase B not read"]


def test_targets_without_phases_are_left_as_they_were():
    rows = rows_for([70.0], targets=[{"name": "box", "kind": "thermal", "unit": "C", "decimals": 1}],
                    alarms={"box": [0.0, 60.0]})
    assert rows[0]["alarm"] == ALARM_ALARM and rows[0]["grade"] == "" and rows[0]["diagnosis"] == ""
