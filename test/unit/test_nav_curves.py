"""Departure curves (nav/curves.py), the follower driving them on the chassis simulator, and the patrol's
choice of turning at stops (task.patrol.turns_to_yaw)."""
import math

import numpy as np

from inspection_robot.nav.curves import STEP_M, curved_path, departure, shape_path
from inspection_robot.nav.follower import ALIGN, FollowerParams
from inspection_robot.nav.goal import MoveGoal
from inspection_robot.task.patrol import STEP_HOME, STEP_MOVE, Step, turns_to_yaw
from test_nav_follower_chassis import drive

PARAMS = FollowerParams()
EAST = [[0.0, 0.0], [6.0, 0.0]]


def goal(x, y, yaw=0.0, with_direction=False, backward=False):
    return MoveGoal(x, y, yaw, with_direction, False, backward, 0.8, 0.8)


def curvature(points):
    seg = np.diff(points, axis=0)
    heading = np.unwrap(np.arctan2(seg[:, 1], seg[:, 0]))
    return np.abs(np.diff(heading)) / STEP_M


def test_departure_curve_leaves_along_the_heading_and_joins_the_path():
    shaped = departure(np.array(EAST), (0.0, 0.0, math.pi / 2), PARAMS)
    assert shaped is not None
    assert np.allclose(shaped[0], (0.0, 0.0))
    first = shaped[1] - shaped[0]
    assert abs(math.atan2(first[1], first[0]) - math.pi / 2) < 0.1     # tangent to the robot's heading
    assert np.allclose(shaped[-1], EAST[-1])
    bend = shaped[:int(4.0 / STEP_M)]
    assert curvature(bend).max() <= 1.0 / PARAMS.min_turn_radius + 1e-6  # drivable in straight mode
    assert np.abs(shaped[:, 1]).max() < 1.0                             # stays near the path


def test_no_curve_when_it_would_cross_an_obstacle_or_turn_too_far():
    wall_north = lambda x, y: 0.0 if y > 0.3 else float("inf")      # noqa: E731 (lethal north of the path)
    path = np.array(EAST)
    assert departure(path, (0.0, 0.0, math.pi / 2), PARAMS, wall_north) is None
    assert departure(path, (0.0, 0.0, math.pi), FollowerParams(curve_max_rad=2.5)) is None   # spin instead
    assert departure(path, (0.0, 0.0, math.pi), PARAMS, lambda x, y: 0.0 if abs(y) > 0.3 else 1.0) is None
    assert np.array_equal(shape_path(path, (0.0, 0.0, math.pi / 2), goal(6, 0), PARAMS, wall_north), path)
    assert np.array_equal(shape_path(path, (0.0, 0.0, math.pi / 2), goal(6, 0, backward=True), PARAMS), path)
    off = FollowerParams(curve_max_m=0.0)
    assert np.array_equal(shape_path(path, (0.0, 0.0, math.pi / 2), goal(6, 0), off), path)
    assert curved_path(path, (0.0, 0.0, math.pi / 2), goal(6, 0), off) is None
    assert curved_path(path, (0.0, 0.0, math.pi / 2), goal(6, 0), PARAMS) is not None


def test_no_curve_that_points_the_robot_at_equipment_within_the_obstacle_corridor():
    """patrol_sim: a charge cycle begun mid-turn 2.6 m in front of cabinet_1 (its inflated footprint 2.2 m
    ahead here), the dock behind the robot. The U-turn itself stays clear, but at its top the robot
    faces the cabinet within obstacle_detector's corridor, stops there and never leaves: spin instead."""
    cabinet = lambda x, y: 0.0 if y > 2.2 and abs(x) < 1.0 else float("inf")   # noqa: E731
    path = np.array([[0.0, 0.0], [-16.46, -16.82]])
    pose = (0.0, 0.0, 0.87)
    blind = departure(path, pose, FollowerParams(curve_sight_m=0.0), cabinet)
    assert blind is not None and blind[:, 1].max() > 0.5                # a U-turn towards the cabinet
    assert PARAMS.curve_sight >= 1.65                                   # obstacle_detector's front_offset + distance
    assert departure(path, pose, PARAMS, cabinet) is None
    assert departure(path, pose, PARAMS) is not None                   # with nothing there the curve stays


def test_robot_drives_off_sideways_without_spinning_and_is_faster():
    start = (0.0, 0.0, math.pi / 2)             # facing the equipment, next stop to the east
    shaped = shape_path(np.array(EAST), start, goal(6, 0), PARAMS)
    (x, y, _yaw), curved_s, phases = drive(shaped, goal(6, 0), start)
    assert ALIGN not in phases
    assert math.hypot(x - 6.0, y) <= PARAMS.xy_tolerance
    (_x, _y, _yaw), spun_s, phases = drive(np.array(EAST), goal(6, 0), start)
    assert ALIGN in phases
    assert curved_s < spun_s - 2.0              # the spin and its two wheel switches (1 s each) saved


def test_patrol_turns_only_where_the_head_cannot_take_the_heading_difference():
    stop = Step(STEP_MOVE, "t", 0, -1, 1.0, 2.0, 0.5, 0, None)
    assert not turns_to_yaw(stop, False)
    assert turns_to_yaw(stop, True)
    assert turns_to_yaw(stop._replace(precision=1), False)
    assert turns_to_yaw(stop._replace(kind=STEP_HOME), False)


def test_path_behind_is_taken_with_a_u_turn_where_there_is_room():
    start = (0.0, 0.0, math.pi)                 # came from the east, the next stop is back there
    shaped = shape_path(np.array(EAST), start, goal(6, 0), PARAMS)
    assert np.abs(shaped[:, 1]).max() <= 2.0 * PARAMS.min_turn_radius + 0.2
    (x, y, _yaw), _s, phases = drive(shaped, goal(6, 0), start)
    assert ALIGN not in phases and math.hypot(x - 6.0, y) <= PARAMS.xy_tolerance
