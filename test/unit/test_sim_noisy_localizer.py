"""The simulated localizer: noise of the configured size, its latency, silence when truth stops."""
import math
import statistics

import pytest

from inspection_robot.nav.localization import LocalizationMonitor
from inspection_robot.sim.noisy_localizer import NoisyLocalizer


def test_noise_has_the_configured_spread_and_no_bias():
    loc = NoisyLocalizer(0.02, 0.0087, 0.0, seed=1)
    xs, yaws = [], []
    for i in range(4000):
        loc.add(i * 0.1, i, (5.0, 5.0, 3.1))
        _stamp, (x, _y, yaw) = loc.output(i * 0.1)
        xs.append(x)
        yaws.append(yaw)
    assert statistics.mean(xs) == pytest.approx(5.0, abs=0.002)
    assert statistics.pstdev(xs) == pytest.approx(0.02, rel=0.05)
    assert all(-math.pi <= v <= math.pi for v in yaws)   # wrapped across +-pi
    offsets = [math.remainder(v - 3.1, 2 * math.pi) for v in yaws]
    assert statistics.pstdev(offsets) == pytest.approx(0.0087, rel=0.05)


def test_a_pose_comes_out_latency_late_once_and_nothing_when_truth_stops():
    loc = NoisyLocalizer(0.0, 0.0, 0.05)
    loc.add(1.00, "s1", (1.0, 2.0, 0.5))
    assert loc.output(1.04) is None
    assert loc.output(1.05) == ("s1", (1.0, 2.0, 0.5))
    assert loc.output(1.15) is None            # not published twice
    loc.add(1.20, "s2", (1.1, 2.0, 0.5))
    loc.add(1.22, "s3", (1.2, 2.0, 0.5))
    assert loc.output(1.30) == ("s3", (1.2, 2.0, 0.5))   # the newest old enough
    loc.add(1.4, "bad", (float("nan"), 0.0, 0.0))
    assert loc.output(2.0) is None


def test_move_base_trusts_its_covariance_and_bad_settings_are_refused():
    loc = NoisyLocalizer(0.02, 0.0087, 0.05)
    mon = LocalizationMonitor(0.5, 0.2, 0.5)
    mon.update(0.0, 1.0, 1.0, 0.0, loc.covariance)
    assert mon.problem(0.0) is None and loc.covariance[0] == pytest.approx(0.0004)
    with pytest.raises(ValueError, match="~latency must be a number >= 0"):
        NoisyLocalizer(0.02, 0.01, -1)
