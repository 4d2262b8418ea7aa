"""Two looks at one pointer (inspection.looks): agreement within 1 % FS, disagreement, a failed look."""
import math

import pytest

from inspection_robot.inspection.looks import combine_looks
from inspection_robot.inspection.readers import Reading

FS = 16.0   # e.g. a 0..16 kV voltmeter


def look(value, confidence=90.0, reason=""):
    return Reading(value, confidence, {"reason": reason, "band": "inner"})


def test_one_look_is_returned_unchanged():
    first = look(10.46)
    assert combine_looks(first, None, FS) is first


def test_looks_within_one_percent_give_their_mean_and_the_lower_confidence():
    out = combine_looks(look(10.46, 92.0), look(10.31, 85.0), FS)   # 0.94 % FS apart
    assert out.value == pytest.approx(10.385)
    assert out.confidence == 85.0
    assert out.detail["reason"] == ""
    assert out.detail["looks"] == [10.46, 10.31]
    assert out.detail["band"] == "inner"


def test_looks_more_than_one_percent_apart_are_uncertain_with_both_values():
    out = combine_looks(look(10.46, 80.0), look(10.23, 95.0), FS)   # 1.44 % FS apart
    assert out.detail["reason"] == "two looks disagree: 10.46 and 10.23 (1.4 % FS)"
    assert out.value == 10.23          # the more confident look
    assert out.confidence == 80.0
    tie = combine_looks(look(10.46, 90.0), look(10.23, 90.0), FS)
    assert tie.value == 10.46          # the first look on a tie


def test_a_doubt_either_look_had_stays():
    agree = combine_looks(look(5.0, 90.0), look(5.05, 40.0, "glare over 12 % of the dial"), FS)
    assert agree.detail["reason"] == "glare over 12 % of the dial"
    apart = combine_looks(look(5.0, 40.0, "two pointers 37 deg apart"), look(9.0, 30.0), FS)
    assert apart.detail["reason"] == "two looks disagree: 5 and 9 (25.0 % FS); two pointers 37 deg apart"


def test_an_unreadable_look_leaves_the_other_value_uncertain():
    out = combine_looks(look(7.2, 90.0), look(float("nan"), 0.0, "needle not found"), FS)
    assert (out.value, out.confidence) == (7.2, 45.0)
    assert out.detail["reason"] == "second look: needle not found"
    assert out.detail["looks"] == [7.2, None]
    first_bad = combine_looks(look(float("nan"), 0.0, "needle not found"), look(7.1, 80.0), FS)
    assert (first_bad.value, first_bad.detail["reason"]) == (7.1, "first look: needle not found")
    neither = combine_looks(look(float("nan"), 0.0, "needle not found"), look(float("nan"), 0.0, "x"), FS)
    assert math.isnan(neither.value) and neither.detail["reason"] == "needle not found"


def test_the_tolerance_is_exactly_one_percent_of_full_scale():
    assert combine_looks(look(0.0), look(0.16), FS).detail["reason"] == ""
    assert combine_looks(look(0.0), look(0.1601), FS).detail["reason"].startswith("two looks disagree")
    with pytest.raises(ValueError):
        combine_looks(look(0.0), look(0.1), 0.0)
