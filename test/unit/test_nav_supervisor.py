"""Goal supervision on a fake clock: pause in other modes, obstacle wait, replanning, off-track, result codes."""
from collections import namedtuple

import pytest

from inspection_robot.interface import (MODE_JOY, MODE_SERVER, MODE_TASK, MOVE_RESULT_BLOCKED, MOVE_RESULT_CANCELLED,
                                        MOVE_RESULT_LOCALIZATION_LOST, NAV_LOCALIZATION_LOST, NAV_OBSTACLE_3D,
                                        NAV_OFF_TRACK)
from inspection_robot.nav.supervisor import (BLOCKED_TURNS, FOLLOW, OBSTACLE_REASON, OFF_TRACK_REASON, PAUSE, REPLAN,
                                             STOP, GoalAborted, GoalSupervisor)

ALL = NAV_OFF_TRACK | NAV_LOCALIZATION_LOST | NAV_OBSTACLE_3D
Progress = namedtuple("Progress", "lateral_error")


def supervisor():
    sup = GoalSupervisor(mode_wait=60.0, obstacle_wait=10.0, replan_min_interval=2.0, off_track_m=0.5)
    sup.replanned(0.0)  # the first plan
    return sup


def test_follows_when_nothing_happens():
    sup = supervisor()
    assert sup.check(0.05, MODE_TASK, False, ALL) == (FOLLOW, None)


def test_pause_in_joystick_mode_reports_once_then_replans_on_return():
    sup = supervisor()
    action, alarm = sup.check(1.0, MODE_JOY, False, ALL)
    assert action == PAUSE and alarm == "robot_control in joy mode (%d): goal paused" % MODE_JOY
    assert sup.check(30.0, MODE_JOY, False, ALL) == (PAUSE, None)
    assert sup.check(31.0, MODE_TASK, False, ALL) == (REPLAN, None)
    sup.replanned(31.0)
    assert sup.check(31.05, MODE_TASK, False, ALL) == (FOLLOW, None)


def test_pause_longer_than_mode_wait_gives_the_goal_up():
    sup = supervisor()
    sup.check(1.0, MODE_SERVER, False, ALL)
    assert sup.check(61.0, MODE_SERVER, False, ALL)[0] == PAUSE
    with pytest.raises(GoalAborted) as err:
        sup.check(61.1, MODE_SERVER, False, ALL)
    assert err.value.ret_code == MOVE_RESULT_CANCELLED
    assert str(err.value) == "robot_control in server mode (%d) for 60.0 s: goal given up" % MODE_SERVER


def test_obstacle_stops_then_replans_when_cleared():
    sup = supervisor()
    assert not sup.obstacle_met
    assert sup.check(5.0, MODE_TASK, True, ALL) == (STOP, OBSTACLE_REASON)
    assert sup.obstacle_met                   # from now on plans without departure curves
    assert sup.check(9.0, MODE_TASK, True, ALL) == (STOP, None)
    assert sup.check(9.5, MODE_TASK, False, ALL) == (REPLAN, None)
    assert sup.obstacle_met


def test_turning_away_only_while_robot_control_stops_and_in_the_first_three_obstacle_stops():
    sup = supervisor()
    assert not sup.may_turn_away(True)             # no obstacle met
    for n in range(1, BLOCKED_TURNS + 2):
        assert sup.check(10.0 * n, MODE_TASK, True, ALL)[0] == STOP
        assert sup.may_turn_away(True) == (n <= BLOCKED_TURNS)
        assert not sup.may_turn_away(False)       # robot_control's switch off: a spin would move the robot
        assert sup.check(10.0 * n + 1.0, MODE_TASK, False, ALL)[0] == REPLAN
        sup.replanned(10.0 * n + 1.0)
    assert sup.obstacle_stops == BLOCKED_TURNS + 1


def test_a_failed_plan_without_departure_curve_is_tried_again_only_after_the_replan_interval():
    sup = supervisor()
    assert sup.check(1.0, MODE_TASK, True, ALL)[0] == STOP
    assert sup.may_plan_plain(1.0)                 # right after the stop, though the last plan was 1 s ago
    sup.plain_plan_failed(1.0)
    assert not sup.may_plan_plain(1.05)            # not on the next tick
    assert not sup.may_plan_plain(2.9)
    assert sup.may_plan_plain(3.0)


def test_obstacle_longer_than_obstacle_wait_ends_blocked():
    sup = supervisor()
    sup.check(5.0, MODE_TASK, True, ALL)
    sup.check(15.0, MODE_TASK, True, ALL)
    with pytest.raises(GoalAborted) as err:
        sup.check(15.01, MODE_TASK, True, ALL)
    assert err.value.ret_code == MOVE_RESULT_BLOCKED and str(err.value) == "blocked by an obstacle for 10.0 s"


def test_obstacle_ignored_when_its_enable_bit_is_off():
    sup = supervisor()
    assert sup.check(5.0, MODE_TASK, True, ALL & ~NAV_OBSTACLE_3D) == (FOLLOW, None)


def test_off_track_replans_at_most_every_interval():
    sup = supervisor()
    sup.followed(Progress(0.8))
    assert sup.off_track
    assert sup.check(1.0, MODE_TASK, False, ALL) == (FOLLOW, None)  # 1 s after the last plan
    assert sup.check(2.5, MODE_TASK, False, ALL) == (REPLAN, OFF_TRACK_REASON)
    sup.replanned(2.5)
    assert sup.check(3.0, MODE_TASK, False, ALL) == (FOLLOW, None)
    sup.followed(Progress(0.1))
    assert sup.check(10.0, MODE_TASK, False, ALL) == (FOLLOW, None)
    sup.followed(Progress(0.8))
    assert sup.check(10.0, MODE_TASK, False, ALL & ~NAV_OFF_TRACK) == (FOLLOW, None)


def test_costmap_change_requests_a_replan():
    sup = supervisor()
    sup.request_replan()
    assert sup.check(0.5, MODE_TASK, False, ALL) == (REPLAN, None)
    sup.replanned(0.5)
    assert sup.check(0.55, MODE_TASK, False, ALL) == (FOLLOW, None)


def test_localization_lost_ends_the_goal_only_when_enabled():
    sup = supervisor()
    sup.check_localization(None, ALL)
    sup.check_localization("no pose for 0.6 s", ALL & ~NAV_LOCALIZATION_LOST)
    with pytest.raises(GoalAborted) as err:
        sup.check_localization("no pose for 0.6 s", ALL)
    assert err.value.ret_code == MOVE_RESULT_LOCALIZATION_LOST
    assert str(err.value) == "localization lost: no pose for 0.6 s"
