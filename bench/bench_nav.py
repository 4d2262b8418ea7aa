"""Navigation benchmarks: planning on 200 m x 200 m yards at 5 cm, follower CPU at 20 Hz, detector per 50k points.

Prints one JSON line per figure.
"""
import argparse
import json
import math
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "src"))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from inspection_robot.nav.costmap import Costmap  # noqa: E402
from inspection_robot.nav.follower import DONE, FollowerParams, PathFollower  # noqa: E402
from inspection_robot.nav.goal import MoveGoal  # noqa: E402
from inspection_robot.nav.obstacle import FORWARD, CorridorDetector, cloud_bytes, xyz_from_cloud  # noqa: E402
from inspection_robot.nav.planner import Planner  # noqa: E402
from nav_reference import path_cost, reference_path  # noqa: E402
from nav_yards import STYLES, make_yard, pairs  # noqa: E402


def percentiles(samples_s):
    ms = np.array(samples_s) * 1000.0
    return round(float(np.percentile(ms, 50)), 2), round(float(np.percentile(ms, 99)), 2)


def bench_planner(styles, seeds, pairs_per_yard, reference_per_yard):
    """Per yard: costmap build, plan p50/p99 over pairs >= 40 m apart, length and cost vs the optimum."""
    all_times, ratios, cost_ratios, builds, edits = [], [], [], [], []
    for style in styles:
        for seed in seeds:
            grid = make_yard(style, seed)
            started = time.perf_counter()
            costmap = Costmap(grid, robot_radius=0.45, safety_margin=0.3)
            planner = Planner(costmap)
            build_ms = (time.perf_counter() - started) * 1000.0
            builds.append(build_ms)
            rng = np.random.default_rng(seed)
            times = []
            samples = pairs(costmap, rng, pairs_per_yard)
            yard_ratios, yard_cost_ratios = [], []
            for i, (a, b) in enumerate(samples):
                started = time.perf_counter()
                plan = planner.plan(a, b)
                times.append(time.perf_counter() - started)
                if i < reference_per_yard:
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
                              "n": len(times), "virtual_edit_max_ms": round(max(edit_ms), 1),
                              "length_ratio_max": round(max(yard_ratios), 4) if yard_ratios else None,
                              "cost_ratio_max": round(max(yard_cost_ratios), 4) if yard_cost_ratios else None,
                              "n_reference": len(yard_ratios)}))
    p50, p99 = percentiles(all_times)
    print(json.dumps({"bench": "nav_plan_200m_5cm", "p50_ms": p50, "p99_ms": p99, "n": len(all_times),
                      "yards": len(styles) * len(seeds)}))
    print(json.dumps({"bench": "nav_costmap_build_200m_5cm", "max_ms": round(max(builds), 1),
                      "mean_ms": round(float(np.mean(builds)), 1)}))
    e50, e99 = percentiles(np.array(edits) / 1000.0)
    print(json.dumps({"bench": "nav_virtual_obstacle_edit_200m_5cm", "p50_ms": e50, "max_ms": round(max(edits), 1),
                      "n": len(edits)}))
    if ratios:
        print(json.dumps({"bench": "nav_plan_vs_optimum", "length_ratio_mean": round(float(np.mean(ratios)), 4),
                          "length_ratio_max": round(max(ratios), 4),
                          "cost_ratio_mean": round(float(np.mean(cost_ratios)), 4),
                          "cost_ratio_max": round(max(cost_ratios), 4), "n": len(ratios)}))


def bench_virtual_edit(costmap, planner, near_xy):
    """ms until the next plan can start after adding, moving and deleting one 4 m virtual wall."""
    x, y = near_xy
    wall = ([[x + 2.0, y - 2.0], [x + 2.0, y + 2.0]], False)
    moved = ([[x + 3.0, y - 2.0], [x + 3.0, y + 2.0]], False)
    out = []
    for layer in ([wall], [moved], []):
        started = time.perf_counter()
        costmap.set_virtual(layer)
        planner.refresh()
        out.append((time.perf_counter() - started) * 1000.0)
    return out


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
    parser.add_argument("--only", default="", help="planner|follower|detector (default: all)")
    args = parser.parse_args()
    rng = np.random.default_rng(7)
    if args.only in ("", "follower"):
        bench_follower()
    if args.only in ("", "detector"):
        bench_detector(rng)
    if args.only in ("", "planner"):
        bench_planner(args.styles.split(","), [int(s) for s in args.seeds.split(",")], args.pairs, args.reference)


if __name__ == "__main__":
    main()
