"""The real-photo set's labels (bench/data/real_gauges.json) obey the split rule and the protocol.

The split must not drift: a source whose recorded part differs from the rule, or a photo whose
source is not listed, would let a tuned-on photo into the test part."""
import copy
import json
import os
import sys

import pytest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "bench"))
import real_set  # noqa: E402


def test_labels_follow_the_split_rule_and_protocol():
    doc = real_set.load()
    roles = real_set.plan(doc)
    for source in doc["sources"]:
        assert source["part"] == real_set.split_part(source["repo"])
    for photo in doc["photos"]:
        calibration = real_set.calibration_photo(doc, photo) if not photo.get("excluded") else None
        if calibration is not None and roles[photo["id"]] == "cross":
            assert calibration["id"] != photo["id"] and real_set.dial_of(calibration) == real_set.dial_of(photo)
    summary = real_set.summary(doc)
    assert summary["tuning"]["readings"] > 0 and summary["test"]["readings"] > 0


def test_split_rule_is_fixed():
    # the rule's value for two sources, so that a change of the rule shows here
    assert real_set.split_part("AlexVT100/gauge-reader") == "test"
    assert real_set.split_part("TYKMASHIRO/Dashboard-Recognition-System") == "tuning"
    assert real_set.split_part("tykmashiro/dashboard-recognition-system") == "tuning"


def test_a_source_moved_to_the_other_part_is_refused():
    doc = real_set.load()
    bad = copy.deepcopy(doc)
    bad["sources"][0]["part"] = "tuning" if bad["sources"][0]["part"] == "test" else "test"
    with pytest.raises(real_set.LabelError, match="split rule"):
        real_set.check(bad)


def test_unlisted_source_and_bad_marks_are_refused():
    doc = real_set.load()
    bad = copy.deepcopy(doc)
    bad["photos"][0]["repo"] = "someone/else"
    with pytest.raises(real_set.LabelError, match="not in sources"):
        real_set.check(bad)
    bad = copy.deepcopy(doc)
    bad["photos"][0]["marks"] = [[0, 1, 1], [2, 2, 2], [1, 3, 3]]
    with pytest.raises(real_set.LabelError, match="monotonic"):
        real_set.check(bad)


def test_display_labels_follow_the_split_rule_and_are_well_formed(tmp_path):
    doc = real_set.load_displays()
    assert all(s["part"] == real_set.split_part(s["repo"]) for s in doc["sources"])
    roles = real_set.plan(doc, real_set.device_of)
    test_cross = [p for p in doc["photos"] if roles.get(p["id"]) == "cross" and real_set.part_of(doc, p) == "test"]
    assert len(test_cross) >= 100   # issue #42: at least 100 readings in the test part
    broken = copy.deepcopy(doc)
    broken["photos"][0]["shown"] = "2x"
    path = tmp_path / "labels.json"
    path.write_text(json.dumps(broken))
    with pytest.raises(real_set.LabelError, match="is not what a seven-segment display shows"):
        real_set.load_displays(str(path))
