"""The localization contract move_base holds a localizer to (docs/interface.md "Localization contract"),
one rule per test, on a fake clock."""
import math

import pytest

from inspection_robot.interface import MOVE_RESULT_LOCALIZATION_LOST, NAV_LOCALIZATION_LOST
from inspection_robot.nav.localization import LocalizationMonitor
from inspection_robot.nav.supervisor import GoalAborted, GoalSupervisor

SOURCE = "/amcl_pose (setting move_base/pose_topic)"


def monitor():
    return LocalizationMonitor(max_xy_std_m=0.5, max_yaw_std_rad=0.2, stale_timeout_s=0.5, source=SOURCE)


def covariance(sigma_x, sigma_y, sigma_yaw):
    cov = [0.0] * 36
    cov[0], cov[7], cov[35] = sigma_x ** 2, sigma_y ** 2, sigma_yaw ** 2
    return cov


def test_a_topic_that_never_publishes_is_named_with_its_setting_and_no_goal_runs():
    mon = monitor()
    assert mon.problem(100.0) == "no pose received yet from " + SOURCE
    with pytest.raises(GoalAborted) as end:
        GoalSupervisor(60, 10, 2, 0.5).check_localization(mon.problem(100.0), NAV_LOCALIZATION_LOST)
    assert end.value.ret_code == MOVE_RESULT_LOCALIZATION_LOST and "move_base/pose_topic" in str(end.value)


def test_a_pose_is_trusted_for_pose_timeout_then_lost_until_the_next_one():
    mon = monitor()
    mon.update(10.0, 1.0, 2.0, 0.0, covariance(0.02, 0.02, 0.01))
    assert mon.problem(10.5) is None
    assert mon.problem(10.51) == "pose from %s is stale (0.5 s old)" % SOURCE
    mon.update(11.0, 1.1, 2.0, 0.0, covariance(0.02, 0.02, 0.01))
    assert not mon.lost(11.0) and mon.pose == (1.1, 2.0, 0.0)


def test_a_pose_outside_the_map_frame_is_never_used():
    mon = monitor()
    mon.update(1.0, 1.0, 2.0, 0.0, None, frame="odom")
    assert mon.problem(1.0) == "pose from %s is in frame 'odom', not 'map'" % SOURCE
    assert mon.pose is None
    mon.update(1.1, 1.0, 2.0, 0.0, None, frame="")
    assert "in frame ''" in mon.problem(1.1)
    mon.update(1.2, 1.0, 2.0, 0.0, None, frame="/map")
    assert mon.problem(1.2) is None and mon.pose == (1.0, 2.0, 0.0)


@pytest.mark.parametrize("sigmas, lost", [
    ((0.0, 0.0, 0.0), None),                                    # all zero: unknown, trusted (ground truth)
    ((0.3, 0.3, 0.1), None),                                    # sqrt(0.09 + 0.09) = 0.42 m
    ((0.4, 0.4, 0.1), "position uncertainty 0.57 m > 0.50 m"),  # x and y add up
    ((0.05, 0.05, 0.25), "heading uncertainty 0.250 rad > 0.200 rad"),
    ((float("nan"), 0.0, 0.0), "covariance is not finite"),
])
def test_covariance_decides_localization_lost(sigmas, lost):
    mon = monitor()
    mon.update(1.0, 0.0, 0.0, 0.0, covariance(*sigmas))
    assert mon.problem(1.0) == lost


def test_a_large_covariance_is_lost_while_it_lasts_and_the_pose_is_kept_for_status():
    mon = monitor()
    mon.update(1.0, 3.0, 4.0, 0.5, covariance(1.0, 1.0, 0.1))
    assert mon.lost(1.0) and mon.pose == (3.0, 4.0, 0.5)
    mon.update(1.1, 3.0, 4.0, 0.5, covariance(0.05, 0.05, 0.02))
    assert not mon.lost(1.1)


def test_a_non_finite_pose_is_lost_and_does_not_replace_the_last_good_one():
    mon = monitor()
    mon.update(1.0, 3.0, 4.0, 0.5, None)
    mon.update(1.1, float("inf"), 4.0, 0.5, None)
    assert mon.problem(1.1) == "pose is not finite" and mon.pose == (3.0, 4.0, 0.5)
    assert math.isfinite(mon.pose[0])
