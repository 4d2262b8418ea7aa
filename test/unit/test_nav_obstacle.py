"""Corridor obstacle detection on synthetic point clouds, and the simulated yard's clouds."""
import math

import numpy as np

from inspection_robot.nav.obstacle import (BACKWARD, FORWARD, SPIN, CorridorDetector, cloud_bytes,
                                           direction_from_command, xyz_from_cloud)
from inspection_robot.sim.nav_yard import ObstacleCloud


def detector(**over):
    args = dict(half_width_m=0.5, front_offset_m=0.4, rear_offset_m=0.4, distance_m=1.5, ground_height_m=0.1,
                max_height_m=1.8, spin_radius_m=0.8, min_points=5, clear_count=2)
    args.update(over)
    return CorridorDetector(**args)


def blob(x, y, z=0.5, n=20):
    rng = np.random.default_rng(0)
    return np.array([x, y, z]) + rng.uniform(-0.05, 0.05, (n, 3))


def test_forward_corridor_ignores_ground_sides_and_rear():
    det = detector()
    ground = np.stack([np.linspace(0.5, 2, 100), np.zeros(100), np.full(100, 0.03)], axis=1)
    beside = blob(1.0, 1.2)
    behind = blob(-1.0, 0.0)
    overhead = blob(1.0, 0.0, z=2.5)
    assert det.count_in_corridor(np.vstack([ground, beside, behind, overhead]), FORWARD) == 0
    assert det.count_in_corridor(blob(1.0, 0.2), FORWARD) == 20
    assert det.count_in_corridor(blob(1.0, 0.2), BACKWARD) == 0
    assert det.count_in_corridor(behind, BACKWARD) == 20
    assert det.count_in_corridor(blob(0.0, 0.6), SPIN) == 20


def test_debounce_and_min_points():
    det = detector()
    assert det.update(blob(1.0, 0.0, n=3), FORWARD) is False
    assert det.update(blob(1.0, 0.0), FORWARD) is True
    assert det.update(np.zeros((0, 3)), FORWARD) is True     # one clear cloud is not enough
    assert det.update(np.zeros((0, 3)), FORWARD) is False


def test_sensor_mounting_transform():
    det = detector(sensor_pose=(0.3, 0.0, 1.0, math.pi))
    # sensor looks backwards, mounted 1 m high: a point 1 m "ahead" of the sensor is behind the robot
    pts = blob(1.0, 0.0, z=-0.5)
    assert det.count_in_corridor(pts, BACKWARD) == 20
    assert det.count_in_corridor(pts, FORWARD) == 0


def test_cloud_bytes_round_trip():
    pts = np.random.default_rng(1).normal(size=(50, 3)).astype(np.float32)
    assert np.array_equal(xyz_from_cloud(cloud_bytes(pts), 12, (0, 4, 8), 50), pts)
    padded = np.zeros((50, 16), dtype=np.uint8)
    padded[:, 4:16] = np.frombuffer(cloud_bytes(pts), dtype=np.uint8).reshape(50, 12)
    assert np.array_equal(xyz_from_cloud(padded.tobytes(), 16, (4, 8, 12), 50), pts)


def test_direction_from_command():
    assert direction_from_command(300.0, 0.0, 0, BACKWARD) == FORWARD
    assert direction_from_command(-300.0, 10.0, 0, FORWARD) == BACKWARD
    assert direction_from_command(0.0, 0.0, 0, BACKWARD) == BACKWARD
    assert direction_from_command(0.0, 200.0, 1, FORWARD) == SPIN


def test_sim_cloud_sees_dropped_box_in_corridor():
    world = {"size": [60, 40], "equipment": [{"id": "t", "position": [20, 10, 0], "yaw": 0.0,
                                              "footprint": [4, 3], "height": 3}]}
    cloud = ObstacleCloud(world, sensor_range_m=6.0)
    det = detector()
    assert det.count_in_corridor(cloud.points_in_robot_frame(5, 5, 0.0), FORWARD) == 0
    cloud.drop("rock", 6.2, 5.0, 0.4, 0.5)
    assert det.count_in_corridor(cloud.points_in_robot_frame(5, 5, 0.0), FORWARD) > 5
    assert det.count_in_corridor(cloud.points_in_robot_frame(5, 5, math.pi), FORWARD) == 0
    assert cloud.remove("rock") and not cloud.remove("rock")
    pts = cloud.points_in_robot_frame(17.0, 10.0, 0.0)   # transformer 1 m ahead of the front
    assert det.count_in_corridor(pts, FORWARD) > 5
