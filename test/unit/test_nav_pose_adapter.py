"""pose_adapter's pure part: parameters, covariance, TF pose, the error of a failing lookup."""
import math

import pytest

from inspection_robot.angles import quaternion_from_yaw
from inspection_robot.nav.localization import LocalizationMonitor
from inspection_robot.nav.pose_adapter import AdapterParams, LookupWatch, planar_covariance, pose_from_transform


def test_defaults_and_the_shipped_config_are_valid():
    import os
    import yaml
    root = os.path.join(os.path.dirname(__file__), "..", "..")
    with open(os.path.join(root, "config", "pose_adapter.yaml")) as f:
        cfg = yaml.safe_load(f)
    params = AdapterParams(**cfg)
    assert (params.mode, params.output_topic, params.rate) == ("none", "localization/pose", 10.0)   # site: on


@pytest.mark.parametrize("kwargs, message", [
    ({"mode": None}, r"~mode must be one of none\|topic\|tf, got None"),
    ({"mode": "amcl"}, "~mode must be one of"),
    ({"mode": "tf", "rate": 0}, "~rate must be a positive number, got 0"),
    ({"mode": "tf", "rate": "fast"}, "~rate must be a positive number"),
    ({"mode": "tf", "sigma_xy": -0.1}, "~sigma_xy must be a number >= 0"),
    ({"mode": "tf", "sigma_yaw": float("nan")}, "~sigma_yaw must be a number >= 0"),
    ({"mode": "tf", "base_frame": " "}, "~base_frame must be a non-empty name"),
    ({"mode": "topic", "input_topic": "p", "output_topic": "p"}, "would feed itself"),
])
def test_bad_parameters_are_refused_by_name(kwargs, message):
    with pytest.raises(ValueError, match=message):
        AdapterParams(**kwargs)


def test_the_configured_covariance_is_what_move_base_reads_and_trusts():
    cov = planar_covariance(0.05, 0.02)
    assert len(cov) == 36 and cov[0] == cov[7] == pytest.approx(0.0025) and cov[35] == pytest.approx(0.0004)
    assert sum(cov) == pytest.approx(0.0025 * 2 + 0.0004)
    mon = LocalizationMonitor(0.5, 0.2, 0.5)
    mon.update(0.0, 1.0, 2.0, 0.3, cov)
    assert mon.problem(0.0) is None
    mon.update(0.1, 1.0, 2.0, 0.3, planar_covariance(0.4, 0.02))
    assert "position uncertainty" in mon.problem(0.1)


def test_pose_from_transform_keeps_x_y_and_the_yaw():
    x, y, yaw = pose_from_transform((3.0, -4.0, 0.1), quaternion_from_yaw(2.5))
    assert (x, y) == (3.0, -4.0) and yaw == pytest.approx(2.5)
    assert pose_from_transform((0, 0, 0), quaternion_from_yaw(-3.0))[2] == pytest.approx(-3.0)


def test_a_failing_lookup_is_reported_with_its_frames_at_most_every_period():
    watch = LookupWatch("map", "base_link", 5.0)
    first = watch.failed(100.0, "frame map does not exist")
    assert first == ("cannot look up transform map -> base_link for 0.0 s (frame map does not exist): publishing "
                     "no pose, so move_base stops the robot on its pose timeout")
    assert watch.failed(102.0, "x") is None and watch.failed(104.9, "x") is None
    assert "for 5.5 s" in watch.failed(105.5, "x")
    assert watch.succeeded() is True and watch.succeeded() is False
    assert "for 0.0 s" in watch.failed(200.0, "x")
    assert math.isclose(watch.failing_since, 200.0)
