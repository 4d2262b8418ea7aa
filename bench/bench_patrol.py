"""Patrol benchmarks: task_manager's own cost per step, and where a real patrol's time goes.

- ``patrol_manager_step``: the state machine and the SQLite store (fsync'd commit per preset,
  status) on a synthetic 50-stop x 3-preset task whose steps take no time: task_manager's own
  time per step, p50/p99 ms.
- ``patrol_report``: writing CSV + JSON + HTML for that task.
- ``patrol_stop_split`` (when a real patrol's store exists: ``--store`` or
  ``$ROS_HOME/inspection_robot/tasks/results.sqlite``, e.g. after ``make patrol``): for its newest
  finished task, seconds per stop in drive / find / read / overhead (the rest of the stop's wall
  time: task_manager, ROS round trips, the ack wait), and ``patrol_manager_share``: task_manager's
  own time (steps x the p50 above) over the patrol's duration, goal < 2 %; and
  ``patrol_time_bound``: its wall time (first step to last) over its lower bound, the planned route
  (``planned_length_m``, less the leg from the last stop to the home pose that closes the tour
  but is not driven) at task_manager's ``velocity_x`` plus the measured inspection time of every
  preset, goal <= 1.25.
- ``patrol_drive_sim``: the same yard's drives in simulated time (bench/patrol_drive.py: follower,
  motion controller and chassis simulator, no ROS, so the machine's load does not distort it),
  per localizer (``truth``, ``noisy``): drive seconds against the planned length at velocity_x,
  seconds per phase and seconds lost per cause.

Prints one JSON line per figure. Timings on the shared 2-core machine are noisy.
"""
import argparse
import json
import os
import shutil
import sys
import tempfile
import time

import numpy as np
import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "src"))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from inspection_robot.task.patrol import (OUTCOME_OK, STEP_INSPECT, Inspection, Patrol,  # noqa: E402
                                          PatrolConfig)
from inspection_robot.task.report import write_reports  # noqa: E402
from inspection_robot.task.spec import ResolvedPreset, parse_task  # noqa: E402
from inspection_robot.task.store import ResultStore  # noqa: E402
from patrol_drive import drive_patrol, home_pose, summary, yard_planner  # noqa: E402

TARGETS = [{"name": "t%d" % k, "kind": "pointer", "unit": "MPa"} for k in range(4)]


def synthetic(folder, stops=50, presets=3):
    store = ResultStore(os.path.join(folder, "bench.sqlite"))
    config = PatrolConfig(retry_delay_s=1.0, home_pose=(0.0, 0.0, 0.0), move_estimate_s=20.0, preset_estimate_s=10.0,
                          uncertain_retries=1)
    patrol = Patrol(store, config, time.time())
    patrol.set_mode(0)
    task = parse_task(json.dumps({"id": "bench", "stops": [
        {"pose": {"x": float(i), "y": 0.0, "yaw": 0.0}, "presets": ["p%d" % j for j in range(presets)]}
        for i in range(stops)]}), lambda name: ResolvedPreset("/presets/" + name, TARGETS, {"t0": [0.0, 1.0]}),
        lambda x, y: None, 1)
    patrol.submit(task, time.time())
    samples = []
    while True:
        tick = time.perf_counter()
        step = patrol.next_step(time.time())
        if step is None:
            break
        now = time.time()
        detail = Inspection([0.5] * 4, [90.0] * 4, ["/p.jpg"] * 4, (1.0, 2.0, 0.0)) \
            if step.kind == STEP_INSPECT else ""
        patrol.step_done(step, OUTCOME_OK, detail, now, now)
        patrol.status()
        samples.append(time.perf_counter() - tick)
    ms = np.array(samples) * 1000.0
    print(json.dumps({"bench": "patrol_manager_step", "p50_ms": round(float(np.percentile(ms, 50)), 2),
                      "p99_ms": round(float(np.percentile(ms, 99)), 2), "steps": len(samples)}))
    tick = time.perf_counter()
    write_reports(os.path.join(folder, "report"), store.task("bench"), store.readings(task_id="bench", limit=10 ** 6),
                  store.steps("bench"), folder, "bench")
    print(json.dumps({"bench": "patrol_report", "ms": round((time.perf_counter() - tick) * 1000.0, 1),
                      "readings": stops * presets * len(TARGETS)}))
    return float(np.percentile(ms, 50)) / 1000.0


def real_patrol(path, step_s):
    store = ResultStore(path)
    tasks = [t for t in store.tasks() if t["state"] == "done" and t["ended"]]
    if not tasks:
        return
    task = tasks[0]
    steps = store.steps(task["task_id"])
    stops = {}
    for step in steps:
        entry = stops.setdefault(step["stop"], {"start": step["started"], "end": step["ended"], "move": 0.0,
                                                "find": 0.0, "read": 0.0, "inspect": 0.0})
        entry["start"], entry["end"] = min(entry["start"], step["started"]), max(entry["end"], step["ended"])
        if step["kind"] in entry:
            entry[step["kind"]] += step["ended"] - step["started"]
    order = sorted(s for s in stops if s >= 0)
    for n, stop in enumerate(order):   # a stop lasts until the next one starts (the gap is overhead)
        if n + 1 < len(order):
            stops[stop]["end"] = stops[order[n + 1]]["start"]
    total = task["ended"] - task["submitted"]
    for stop in order:
        e = stops[stop]
        wall = e["end"] - e["start"]
        print(json.dumps({"bench": "patrol_stop_split", "task": task["task_id"], "stop": stop + 1,
                          "drive_s": round(e["move"], 2), "find_s": round(e["find"], 2), "read_s": round(e["read"], 2),
                          "overhead_s": round(wall - e["move"] - e["find"] - e["read"], 2),
                          "wall_s": round(wall, 2)}))
    patrol_time_bound(task, steps)
    manager_steps = sum(1 for s in steps if s["kind"] in ("move", "inspect", "home"))  # find/read are parts
    share = manager_steps * step_s / total * 100.0 if total > 0 else 0.0
    print(json.dumps({"bench": "patrol_manager_share", "task": task["task_id"], "patrol_s": round(total, 1),
                      "steps": manager_steps, "percent": round(share, 3), "goal_percent": 2.0}))


def patrol_time_bound(task, steps):
    """The patrol's wall time against its lower bound: the planned route at task_manager's drive
    speed plus the measured time of every preset's inspection (head, zoom, find, read)."""
    planned = task["spec"].get("planned_length_m")
    if not planned or not steps:
        print(json.dumps({"bench": "patrol_time_bound", "skipped": "task %s has no planned length" % task["task_id"]}))
        return
    with open(os.path.join(ROOT, "config", "task_manager.yaml")) as f:
        speed = float(yaml.safe_load(f)["velocity_x"])
    inspect_s = sum(s["ended"] - s["started"] for s in steps if s["kind"] == "inspect")
    drive_s = sum(s["ended"] - s["started"] for s in steps if s["kind"] in ("move", "home"))
    wall = max(s["ended"] for s in steps) - min(s["started"] for s in steps)
    # planned_length_m runs on to the home pose that closes the tour, which a patrol does not drive:
    # that leg is left out of the bound (else the bound would count seconds nobody drove)
    home_m = 0.0
    stops = task["spec"].get("stops") or []
    if stops and not any(s["kind"] == "home" for s in steps):
        last = stops[-1]["pose"] if "pose" in stops[-1] else stops[-1]
        home_m = yard_planner().plan((last["x"], last["y"]), home_pose()[:2]).length
    driven = planned - home_m
    bound = driven / speed + inspect_s
    print(json.dumps({"bench": "patrol_time_bound", "task": task["task_id"], "order": task["spec"].get("order"),
                      "planned_m": planned, "home_leg_m": round(home_m, 2), "speed_m_s": speed,
                      "drive_bound_s": round(driven / speed, 1),
                      "drive_s": round(drive_s, 1), "inspect_s": round(inspect_s, 1), "wall_s": round(wall, 1),
                      "bound_s": round(bound, 1), "ratio": round(wall / bound, 3), "goal": 1.25}))


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    home = os.environ.get("ROS_HOME") or os.path.join(os.path.expanduser("~"), ".ros")
    parser.add_argument("--store", default=os.path.join(home, "inspection_robot", "tasks", "results.sqlite"))
    args = parser.parse_args()
    folder = tempfile.mkdtemp(prefix="bench_patrol_")
    try:
        step_s = synthetic(folder)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    for localizer in ("truth", "noisy"):
        print(json.dumps(dict({"bench": "patrol_drive_sim", "localizer": localizer}, **summary(
            *drive_patrol(localizer=localizer)))))
    if os.path.isfile(args.store):
        real_patrol(args.store, step_s)
    else:
        print(json.dumps({"bench": "patrol_stop_split", "skipped": "no patrol store at %s (run make patrol)"
                          % args.store}))


if __name__ == "__main__":
    main()
