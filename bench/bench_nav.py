"""Navigation benchmarks: planning on 200 m x 200 m yards at 5 cm, follower CPU at 20 Hz, detector per 50k points.

Prints one JSON line per figure.
"""
import argparse
import json
import math
import os
import sys
import time

import cv2
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "src"))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from inspection_robot.nav.costmap import Costmap  # noqa: E402
from inspection_robot.angles import wrap_angle  # noqa: E402
from inspection_robot.interface import (MOVE_VELOCITY_X_UNIT_M_S, MOVE_VELOCITY_YAW_UNIT_RAD_S,  # noqa: E402
                                        SENDER_MOVE_BASE)
from inspection_robot.motion.controller import MotionController  # noqa: E402
from inspection_robot.motion.velocity import VelocityLimits  # noqa: E402
from inspection_robot.nav.follower import ALIGN, DONE, FollowerParams, PathFollower, stop_spin_go_params  # noqa: E402
from inspection_robot.nav.goal import MoveGoal  # noqa: E402
from inspection_robot.nav.obstacle import FORWARD, CorridorDetector, cloud_bytes, xyz_from_cloud  # noqa: E402
from inspection_robot.nav.planner import Planner  # noqa: E402
from inspection_robot.sim.chassis import SimChassis  # noqa: E402
from nav_reference import path_cost, reference_path  # noqa: E402
from nav_yards import STYLES, make_yard, pairs  # noqa: E402


def percentiles(samples_s):
    ms = np.array(samples_s) * 1000.0
    return round(float(np.percentile(ms, 50)), 2), round(float(np.percentile(ms, 99)), 2)


def bench_planner(styles, seeds, pairs_per_yard, reference_per_yard):
    """Per yard: costmap build, plan p50/p99 over pairs >= 40 m apart, length and cost vs the optimum."""
    all_times, cpu_times, ratios, cost_ratios, builds, edits = [], [], [], [], [], []
    for style in styles:
        for seed in seeds:
            grid = make_yard(style, seed)
            started, cpu = time.perf_counter(), time.process_time()
            costmap = Costmap(grid, robot_radius=0.45, safety_margin=0.3)
            planner = Planner(costmap)
            build_ms = (time.perf_counter() - started) * 1000.0
            builds.append((build_ms, (time.process_time() - cpu) * 1000.0))
            rng = np.random.default_rng(seed)
            times = []
            samples = pairs(costmap, rng, pairs_per_yard)
            yard_ratios, yard_cost_ratios = [], []
            for i, (a, b) in enumerate(samples):
                started, cpu = time.perf_counter(), time.process_time()
                plan = planner.plan(a, b)
                times.append(time.perf_counter() - started)
                cpu_times.append(time.process_time() - cpu)
                if len(yard_ratios) < reference_per_yard:
                    ref = reference_path(costmap, a, b)
                    if ref is None or ref[2]:
                        continue
                    cells, ref_cost, _touches = ref
                    ref_length = float(np.hypot(*np.diff(cells, axis=0).T).sum()) * grid.resolution
                    yard_ratios.append(plan.length / ref_length)
                    yard_cost_ratios.append(path_cost(costmap, plan.points) / ref_cost)
            edit_ms = bench_virtual_edit(costmap, planner, samples[0][0])
            edits.extend(edit_ms)
            all_times.extend(times)
            ratios.extend(yard_ratios)
            cost_ratios.extend(yard_cost_ratios)
            p50, p99 = percentiles(times)
            print(json.dumps({"bench": "nav_plan_yard", "style": style, "seed": seed, "build_ms": round(build_ms, 1),
                              "p50_ms": p50, "p99_ms": p99, "max_ms": round(max(times) * 1000.0, 1),
                              "n": len(times), "virtual_edit_max_ms": round(max(e[0] for e in edit_ms), 1),
                              "virtual_edit_cpu_max_ms": round(max(e[1] for e in edit_ms), 1),
                              "length_ratio_max": round(max(yard_ratios), 4) if yard_ratios else None,
                              "cost_ratio_max": round(max(yard_cost_ratios), 4) if yard_cost_ratios else None,
                              "n_reference": len(yard_ratios)}))
    p50, p99 = percentiles(all_times)
    c50, c99 = percentiles(cpu_times)
    print(json.dumps({"bench": "nav_plan_200m_5cm", "p50_ms": p50, "p99_ms": p99, "cpu_p50_ms": c50, "cpu_p99_ms": c99,
                      "n": len(all_times), "yards": len(styles) * len(seeds)}))
    print(json.dumps({"bench": "nav_costmap_build_200m_5cm", "max_ms": round(max(b[0] for b in builds), 1),
                      "cpu_max_ms": round(max(b[1] for b in builds), 1)}))
    e50, e99 = percentiles([e[0] / 1000.0 for e in edits])
    c50, c99 = percentiles([e[1] / 1000.0 for e in edits])
    print(json.dumps({"bench": "nav_virtual_obstacle_edit_200m_5cm", "p50_ms": e50,
                      "max_ms": round(max(e[0] for e in edits), 1), "cpu_p50_ms": c50,
                      "cpu_max_ms": round(max(e[1] for e in edits), 1), "n": len(edits)}))
    if ratios:
        print(json.dumps({"bench": "nav_plan_vs_optimum", "length_ratio_mean": round(float(np.mean(ratios)), 4),
                          "length_ratio_max": round(max(ratios), 4),
                          "cost_ratio_mean": round(float(np.mean(cost_ratios)), 4),
                          "cost_ratio_max": round(max(cost_ratios), 4), "n": len(ratios)}))


def bench_virtual_edit(costmap, planner, near_xy):
    """ms until the next plan can start after adding, moving and deleting one 4 m virtual wall."""
    x, y = near_xy
    side = 1.0 if x < 100.0 else -1.0  # towards the middle of the yard
    wall = ([[x + 2.0 * side, y - 2.0], [x + 2.0 * side, y + 2.0]], False)
    moved = ([[x + 3.0 * side, y - 2.0], [x + 3.0 * side, y + 2.0]], False)
    out = []
    for layer in ([wall], [moved], []):
        started, cpu = time.perf_counter(), time.process_time()
        costmap.set_virtual(layer)
        planner.refresh()
        out.append(((time.perf_counter() - started) * 1000.0, (time.process_time() - cpu) * 1000.0))
    return out


def staircase(costmap, corners=10, leg_m=8.0):
    """Patrol route of right-angle corners, placed at the first spot of the yard where all its points are free."""
    grid = costmap.grid
    for shift in range(400):
        x0, y0 = 20.0 + 2.0 * (shift % 20), 20.0 + 2.0 * (shift // 20)
        route = [(x0 + leg_m * ((i + 1) // 2), y0 + leg_m * (i // 2)) for i in range(corners + 2)]
        if all(costmap.free(*grid.world_to_cell(x, y)) for x, y in route):
            return route
    raise RuntimeError("no free spot for the route")


def drive_on_chassis(path, goal, params, clearance, costmap=None, timeout_s=900.0):
    """Follower at 20 Hz -> MotionController at 50 Hz -> SimChassis, on a fake clock.

    ``costmap``: regulate the speed near obstacles with its clearance (None: no regulation).

    Returns (seconds to DONE, final pose, minimum clearance (m) on the way, spins in place).
    """
    clock = [0.0]
    heading = math.atan2(path[1][1] - path[0][1], path[1][0] - path[0][0])
    chassis = SimChassis(lambda: clock[0], (path[0][0], path[0][1], heading))
    controller = MotionController(chassis, VelocityLimits(1.0, 1.0, 5.0, 5.0), 0.5, lambda: clock[0])
    follower = PathFollower(np.asarray(path, dtype=float), goal, params,
                            None if costmap is None else costmap.clearance)
    tick, step, spins, phase = 0.01, 0, 0, None
    min_clearance = float("inf")
    while clock[0] < timeout_s:
        (x, y, yaw), _velocity = chassis.true_pose()
        min_clearance = min(min_clearance, clearance(x, y))
        if step % 5 == 0:
            progress = follower.step(x, y, yaw)
            if progress.phase == ALIGN and phase != ALIGN:
                spins += 1
            phase = progress.phase
            if phase == DONE:
                return clock[0], (x, y, yaw), min_clearance, spins
            cmd = progress.command
            controller.on_move_cmd(SENDER_MOVE_BASE, cmd.velocity_x / MOVE_VELOCITY_X_UNIT_M_S,
                                   cmd.velocity_yaw / MOVE_VELOCITY_YAW_UNIT_RAD_S, cmd.wheel_control)
        if step % 2 == 0:
            controller.tick()
        clock[0] += tick
        step += 1
    raise RuntimeError("route not finished in %.0f s" % timeout_s)


def bench_route():
    """Standard patrol route with 10 corners: regulated pure pursuit against stop-spin-go."""
    grid = make_yard("posts", 1)
    costmap = Costmap(grid, robot_radius=0.45, safety_margin=0.3)
    planner = Planner(costmap)
    route = staircase(costmap)
    legs = [planner.plan(a, b).points for a, b in zip(route[:-1], route[1:])]
    path = np.vstack([legs[0]] + [leg[1:] for leg in legs[1:]])
    obstacles = costmap._static | costmap.virtual
    distance = cv2.distanceTransform((~obstacles).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)

    def clearance(x, y):
        row, col = grid.world_to_cell(x, y)
        return float(distance[row, col]) * grid.resolution

    goal = MoveGoal(route[-1][0], route[-1][1], math.pi, True, True, False, 1.0, 1.0)
    out = {}
    for name, params, regulated_by in (("stop_spin_go", stop_spin_go_params(), None),
                                       ("regulated", FollowerParams(), costmap)):
        seconds, (x, y, yaw), min_clearance, spins = drive_on_chassis(path, goal, params, clearance, regulated_by)
        out[name] = seconds
        print(json.dumps({"bench": "nav_route_10_corners_88m", "follower": name, "seconds": round(seconds, 1),
                          "min_clearance_m": round(min_clearance, 3), "spins": spins,
                          "goal_error_m": round(math.hypot(x - goal.x, y - goal.y), 4),
                          "yaw_error_deg": round(abs(math.degrees(wrap_angle(yaw - goal.yaw))), 2),
                          "path_m": round(float(np.hypot(*np.diff(path, axis=0).T).sum()), 1)}))
    print(json.dumps({"bench": "nav_route_time_saved", "percent": round(100.0 * (1.0 - out["regulated"]
                                                                                 / out["stop_spin_go"]), 1)}))


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
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--styles", default=",".join(STYLES), help="yard styles, comma-separated")
    parser.add_argument("--seeds", default="1,2", help="yard seeds, comma-separated")
    parser.add_argument("--pairs", type=int, default=40, help="start/goal pairs per yard")
    parser.add_argument("--reference", type=int, default=6, help="pairs per yard checked against the optimum")
    parser.add_argument("--only", default="", help="planner|route|follower|detector (default: all)")
    args = parser.parse_args()
    rng = np.random.default_rng(7)
    if args.only in ("", "follower"):
        bench_follower()
    if args.only in ("", "route"):
        bench_route()
    if args.only in ("", "detector"):
        bench_detector(rng)
    if args.only in ("", "planner"):
        bench_planner(args.styles.split(","), [int(s) for s in args.seeds.split(",")], args.pairs, args.reference)


if __name__ == "__main__":
    main()
