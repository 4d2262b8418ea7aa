"""Navigation benchmarks: planning on a 200 m x 200 m yard at 5 cm, follower CPU at 20 Hz, detector per 50k points.

Prints one JSON line per figure.
"""
import json
import math
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "src"))

from inspection_robot.nav.costmap import Costmap  # noqa: E402
from inspection_robot.nav.follower import DONE, FollowerParams, PathFollower  # noqa: E402
from inspection_robot.nav.goal import MoveGoal  # noqa: E402
from inspection_robot.nav.gridmap import GridMap  # noqa: E402
from inspection_robot.nav.obstacle import FORWARD, CorridorDetector, cloud_bytes, xyz_from_cloud  # noqa: E402
from inspection_robot.nav.planner import Planner  # noqa: E402

RES = 0.05
SIZE_M = 200.0


def percentiles(samples_s):
    ms = np.array(samples_s) * 1000.0
    return round(float(np.percentile(ms, 50)), 2), round(float(np.percentile(ms, 99)), 2)


def yard(rng):
    """200 m x 200 m fenced yard with rows of equipment bays and a few internal fences."""
    n = int(SIZE_M / RES)
    occ = np.zeros((n, n), dtype=np.int8)
    occ[:4, :] = occ[-4:, :] = occ[:, :4] = occ[:, -4:] = 100
    for _ in range(400):
        r, c = rng.integers(40, n - 120, 2)
        h, w = rng.integers(20, 100, 2)
        occ[r:r + h, c:c + w] = 100
    for _ in range(12):  # long internal fences with gates
        r = rng.integers(200, n - 200)
        occ[r:r + 3, 100:n - 100] = 100
        gate = rng.integers(200, n - 300)
        occ[r:r + 3, gate:gate + 60] = 0
    return GridMap(occ, RES, (0.0, 0.0, 0.0))


def bench_planner(rng, pairs=30):
    grid = yard(rng)
    started = time.perf_counter()
    costmap = Costmap(grid, robot_radius=0.45, safety_margin=0.3)
    build_s = time.perf_counter() - started
    started = time.perf_counter()
    planner = Planner(costmap)
    coarse_s = time.perf_counter() - started
    print(json.dumps({"bench": "nav_costmap_rebuild_200m_5cm", "ms": round((build_s + coarse_s) * 1000.0, 1),
                      "cells": grid.width * grid.height}))
    times, lengths = [], []
    while len(times) < pairs:
        a, b = rng.uniform(1.0, SIZE_M - 1.0, (2, 2))
        ca, cb = grid.world_to_cell(*a), grid.world_to_cell(*b)
        if not costmap.connected(ca, cb) or math.hypot(*(a - b)) < 20.0:
            continue
        started = time.perf_counter()
        plan = planner.plan(a, b)
        times.append(time.perf_counter() - started)
        lengths.append(plan.length)
    p50, p99 = percentiles(times)
    print(json.dumps({"bench": "nav_plan_200m_5cm", "p50_ms": p50, "p99_ms": p99, "n": pairs,
                      "mean_path_m": round(float(np.mean(lengths)), 1)}))


def bench_follower():
    t = np.linspace(0, 3 * math.pi, 400)
    path = np.stack([50 + 40 * np.cos(t / 2), 50 + 30 * np.sin(t)], axis=1)
    goal = MoveGoal(path[-1, 0], path[-1, 1], 0.0, True, False, False, 1.0, 1.0)
    follower = PathFollower(path, goal, FollowerParams())
    x, y, yaw = path[0, 0], path[0, 1], math.atan2(path[1, 1] - path[0, 1], path[1, 0] - path[0, 0])
    steps, dt = 0, 0.05
    cpu = time.process_time()
    while steps < 4000:
        progress = follower.step(x, y, yaw)
        if progress.phase == DONE:
            break
        cmd = progress.command
        yaw += cmd.velocity_yaw * dt
        v = cmd.velocity_x if cmd.wheel_control == 0 else 0.0
        x += v * math.cos(yaw) * dt
        y += v * math.sin(yaw) * dt
        steps += 1
    per_step = (time.process_time() - cpu) / steps
    print(json.dumps({"bench": "nav_follower_cpu_20hz", "cpu_percent": round(per_step * 20 * 100, 3),
                      "step_us": round(per_step * 1e6, 1), "n": steps}))


def bench_detector(rng, clouds=100):
    det = CorridorDetector(0.45, 0.45, 0.45, 1.2, 0.08, 1.8, 0.8)
    pts = rng.uniform([-10, -10, -0.2], [10, 10, 3], (50000, 3)).astype(np.float32)
    data = cloud_bytes(pts)
    times = []
    for _ in range(clouds):
        started = time.perf_counter()
        det.update(xyz_from_cloud(data, 12, (0, 4, 8), len(pts)), FORWARD)
        times.append(time.perf_counter() - started)
    p50, p99 = percentiles(times)
    print(json.dumps({"bench": "nav_detector_50k_points", "p50_ms": p50, "p99_ms": p99, "n": clouds}))


def main():
    rng = np.random.default_rng(7)
    bench_follower()
    bench_detector(rng)
    bench_planner(rng)


if __name__ == "__main__":
    main()
