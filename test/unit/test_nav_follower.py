"""Path follower geometry against an ideal kinematic robot (unicycle, 20 Hz)."""
import math
import random

import numpy as np
import pytest

from inspection_robot.interface import WHEEL_STEER, WHEEL_STRAIGHT
from inspection_robot.nav.follower import DONE, Approach, Arrival, FollowerParams, PathFollower
from inspection_robot.nav.obstacle import FORWARD, CorridorDetector, direction_from_command
from inspection_robot.nav.goal import MoveGoal
from inspection_robot.angles import wrap_angle

DT = 0.05


def drive(path, goal, start, params=None, max_steps=4000):
    """Run the follower in closed loop; return (final pose, commands)."""
    follower = PathFollower(path, goal, params or FollowerParams())
    x, y, yaw = start
    commands = []
    for _ in range(max_steps):
        progress = follower.step(x, y, yaw)
        cmd = progress.command
        commands.append((progress.phase, cmd))
        if progress.phase == DONE:
            break
        v = cmd.velocity_x if cmd.wheel_control == WHEEL_STRAIGHT else 0.0
        assert abs(cmd.velocity_x) <= goal.velocity_x + 1e-9
        assert abs(cmd.velocity_yaw) <= goal.velocity_yaw + 1e-9
        yaw += cmd.velocity_yaw * DT
        x += v * math.cos(yaw) * DT
        y += v * math.sin(yaw) * DT
    return (x, y, wrap_angle(yaw)), commands


def goal(x, y, yaw=0.0, with_direction=False, precision=False, backward=False, v=1.0, w=1.0):
    return MoveGoal(x, y, yaw, with_direction, precision, backward, v, w)


def test_straight_goal_reached_within_tolerance():
    (x, y, _), cmds = drive([[0, 0], [10, 0]], goal(10, 0), (0, 0, 0))
    assert cmds[-1][0] == DONE
    assert math.hypot(x - 10, y) < 0.05
    assert max(c.velocity_x for _p, c in cmds) == pytest.approx(1.0)


def test_spins_in_place_first_when_facing_away():
    (x, y, _), cmds = drive([[0, 0], [0, 5]], goal(0, 5), (0, 0, -math.pi / 2))
    assert cmds[0][1].wheel_control == WHEEL_STEER and cmds[0][1].velocity_x == 0.0
    assert math.hypot(x, y - 5) < 0.05


def test_l_shaped_path_and_lateral_error_stays_small():
    path = np.array([[0, 0], [5, 0], [5, 5]], dtype=float)
    follower_goal = goal(5, 5)
    (x, y, _), _cmds = drive(path, follower_goal, (0, 0, 0))
    assert math.hypot(x - 5, y - 5) < 0.05


def test_with_direction_reaches_goal_heading():
    (x, y, yaw), cmds = drive([[0, 0], [4, 3]], goal(4, 3, yaw=2.5, with_direction=True), (0, 0, 0.6))
    assert math.hypot(x - 4, y - 3) < 0.05
    assert abs(wrap_angle(yaw - 2.5)) < math.radians(3)
    assert cmds[-2][0] == "spin" and cmds[-2][1].wheel_control == WHEEL_STEER


def test_precision_goal_tight_tolerance():
    (x, y, yaw), _ = drive([[0, 0], [3, 1]], goal(3, 1, yaw=0.3, precision=True, with_direction=True), (0, 0, 0.3))
    assert math.hypot(x - 3, y - 1) < 0.02
    assert abs(wrap_angle(yaw - 0.3)) < math.radians(1)


def test_backward_drives_with_negative_speed():
    (x, y, yaw), cmds = drive([[0, 0], [-6, 0]], goal(-6, 0, backward=True), (0, 0, 0))
    assert math.hypot(x + 6, y) < 0.05
    moving = [c for p, c in cmds if p == "track"]
    assert moving and all(c.velocity_x < 0 for c in moving)
    assert abs(yaw) < 0.1  # never turned around


def test_velocity_limits_respected():
    slow = goal(5, 5, v=0.3, w=0.2)
    (x, y, _), cmds = drive([[0, 0], [5, 0], [5, 5]], slow, (0, 0, 0))
    assert math.hypot(x - 5, y - 5) < 0.05
    assert max(abs(c.velocity_x) for _p, c in cmds) <= 0.3 + 1e-9


def test_progress_reports_remaining_and_lateral_error():
    follower = PathFollower([[0, 0], [10, 0]], goal(10, 0), FollowerParams())
    progress = follower.step(3.0, 0.4, 0.0)
    assert progress.remaining == pytest.approx(7.0, abs=1e-6)
    assert progress.lateral_error == pytest.approx(0.4, abs=1e-6)


def test_speed_regulated_near_obstacles_read_from_the_costmap():
    # a wall (cell centres at y = 4.275) beside the second half of a straight 20 m path at y = 4.825:
    # the robot's edge (radius 0.45 m) passes 0.1 m from it
    from inspection_robot.nav.costmap import Costmap
    from inspection_robot.nav.gridmap import GridMap
    occ = np.zeros((200, 400), dtype=np.int8)
    occ[85, 200:] = 100  # from x = 10 m on
    costmap = Costmap(GridMap(occ, 0.05, (0.0, 0.0, 0.0)), robot_radius=0.45, safety_margin=0.3)
    assert costmap.clearance(5.0, 5.0) == float("inf")
    assert costmap.clearance(15.0, 4.825) == pytest.approx(0.1, abs=0.03)
    assert costmap.clearance(15.0, 4.5) == 0.0
    path = [[0.0, 4.825], [19.5, 4.825]]
    g = MoveGoal(19.5, 4.825, 0.0, False, False, False, 1.0, 1.0)
    speeds = {}
    for name, clearance in (("free", None), ("regulated", costmap.clearance)):
        follower = PathFollower(path, g, FollowerParams(), clearance)
        x, yaw, out = 0.0, 0.0, []
        while x < 18.0:
            cmd = follower.step(x, 4.825, yaw).command
            out.append((x, cmd.velocity_x))
            x += cmd.velocity_x * DT
        speeds[name] = max(v for px, v in out if 12.0 < px < 16.0)
    assert speeds["free"] == pytest.approx(1.0)
    # clearance ~0.1 m of the 0.2 m proximity distance: about half speed
    assert 0.4 < speeds["regulated"] <= 0.6


def test_arrival_ignores_poses_from_before_the_stop_and_waits_for_rest():
    params = FollowerParams()
    arrival = Arrival(params, stopped_at=10.0)
    assert arrival.update(10.0, 9.99, (1.0, 0.0, 0.0)) is None       # arrived before the stop
    assert arrival.update(10.1, 10.05, (1.02, 0.0, 0.0)) is None     # one pose: nothing to compare
    assert arrival.update(10.4, 10.35, (1.05, 0.0, 0.0)) is None     # still rolling 3 cm
    assert arrival.update(10.5, 10.5, (1.052, 0.0, 0.0)) is None     # 2 mm since 10.35, but only 0.15 s
    assert arrival.update(10.6, 10.6, (1.052, 0.0, 0.01)) is None    # 0.6 deg turned since 10.35
    # at rest from 10.6 to 10.9: the mean of those two poses
    assert arrival.update(10.9, 10.9, (1.054, 0.0, 0.012)) == pytest.approx((1.053, 0.0, 0.011))


def test_arrival_judges_a_noisy_localizer_on_its_mean_pose_after_the_timeout():
    params = FollowerParams(rest_timeout_s=2.0)
    arrival = Arrival(params, stopped_at=0.0)   # an ordinary goal: rest_timeout
    i, t, verdict = 0, 0.0, None
    while verdict is None and t < 5.0:
        i += 1
        t = 0.05 * i
        verdict = arrival.update(t, t, (0.01 * (-1) ** i, 0.0, 0.0))  # 2 cm jitter
    assert verdict is not None and 2.0 <= t < 2.1
    assert verdict == pytest.approx((0.0, 0.0, 0.0), abs=0.001)   # one pose would be 1 cm off


def test_arrival_mean_of_a_gaussian_localizer_is_within_the_precise_tolerance():
    """sim_localizer's noise (2 cm, 0.5 deg sigma at 10 Hz): single poses miss the precise tolerance
    (1 cm, 0.015 rad) most of the time, the mean at rest almost never; braking poses are left out."""
    rng = random.Random(7)
    params = FollowerParams()
    misses = {"mean": 0, "single": 0}
    for trial in range(200):
        arrival = Arrival(params, stopped_at=0.0, precise=True)
        verdict, t, single = None, 0.0, None
        arrival.update(0.1, 0.1, (0.3, 0.0, 0.2))   # still braking 0.1 s after the stop: not averaged
        while verdict is None:
            t += 0.1
            single = (rng.gauss(0.0, 0.02), rng.gauss(0.0, 0.02), math.pi + rng.gauss(0.0, 0.0087))
            verdict = arrival.update(t + 0.1, t + 0.1, single)
        for name, pose in (("mean", verdict), ("single", single)):
            heading = abs(math.atan2(math.sin(pose[2] - math.pi), math.cos(pose[2] - math.pi)))
            misses[name] += math.hypot(pose[0], pose[1]) > params.xy_tolerance_precise or \
                heading > params.yaw_tolerance_precise
    assert misses["single"] > 100 and misses["mean"] < 40, misses


def test_arrival_waits_while_no_pose_comes():
    arrival = Arrival(FollowerParams(), stopped_at=0.0)
    assert arrival.update(5.0, None, None) is None


def test_blocked_by_what_it_faces_the_robot_spins_away_when_its_footprint_is_clear():
    """A robot stopped facing equipment 1.2 m ahead (obstacle_detector's corridor) while its path
    leaves behind it: move_base's command while blocked is the follower's spin, the detector then
    checks the footprint's disc, finds it clear and releases the robot. A path through the
    equipment keeps a stop, and the detector keeps seeing it."""
    equipment = np.array([[1.2, dy, dz] for dy in (-0.2, 0.0, 0.2) for dz in (0.5, 1.0)])
    detector = CorridorDetector(0.45, 0.45, 0.45, 1.2, 0.08, 1.8, 0.8, min_points=5, clear_count=3)
    assert detector.update(equipment, FORWARD)                     # stopped for it, last command forward
    behind = Approach(PathFollower([(0.0, 0.0), (-10.0, 0.0)], goal(-10.0, 0.0), FollowerParams()))
    command = behind.blocked_command((0.0, 0.0, 0.0))
    assert command.wheel_control == WHEEL_STEER and command.velocity_yaw != 0.0 and command.velocity_x == 0.0
    direction = direction_from_command(command.velocity_x, command.velocity_yaw, command.wheel_control, FORWARD)
    assert [detector.update(equipment, direction) for _ in range(3)] == [True, True, False]
    through = Approach(PathFollower([(0.0, 0.0), (10.0, 0.0)], goal(10.0, 0.0), FollowerParams()))
    command = through.blocked_command((0.0, 0.0, 0.0))
    assert (command.velocity_x, command.velocity_yaw) == (0.0, 0.0)
    detector = CorridorDetector(0.45, 0.45, 0.45, 1.2, 0.08, 1.8, 0.8, min_points=5, clear_count=3)
    direction = direction_from_command(command.velocity_x, command.velocity_yaw, command.wheel_control, FORWARD)
    assert all(detector.update(equipment, direction) for _ in range(5))
    assert behind.blocked_command(None) == through.blocked_command(None)   # no pose: a stop
