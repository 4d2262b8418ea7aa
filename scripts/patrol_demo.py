#!/usr/bin/env python3
"""`make patrol`'s backend: over the websocket only, record and calibrate a preset for every meter
of the simulated yard, submit one patrol of the whole yard to task_manager, show its progress and
print the report's path. Started by scripts/patrol next to sim.launch."""
import argparse
import json
import sys
import time

import roslibpy

from inspection_robot.sim.world import World
from inspection_robot_testing.yard_patrol import (YARD_STOPS, PatrolClient, build_task, default_world_file,
                                                  preset_count, progress_bar)


def connect(port, timeout):
    deadline = time.monotonic() + timeout
    while True:
        ros = roslibpy.Ros("127.0.0.1", port)
        try:
            ros.run(timeout=5)
            return ros
        except Exception:  # roslibpy raises a bare Exception while the bridge is not up yet
            ros.close()
            if time.monotonic() > deadline:
                raise
            time.sleep(1.0)


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--port", type=int, default=9090, help="websocket port of the robot")
    parser.add_argument("--world", default=default_world_file(), help="world YAML (truth for calibration)")
    parser.add_argument("--timeout", type=float, default=1800.0, help="s the patrol may take")
    args = parser.parse_args()
    world = World.load(args.world)
    ros = connect(args.port, 180.0)
    client = PatrolClient(ros, roslibpy, log=print)
    client.wait(lambda: client.status, 120.0, "task_status from task_manager")
    if client.status["state"] in ("running", "paused"):
        # a previous `make patrol` was stopped mid-patrol: task_manager resumed its task at start-up
        print("patrol: cancelling task %s left unfinished by a previous run" % client.status["task_id"])
        client.task_cmd("cancel", "")
    print("patrol: recording %d presets at %d stops (simulated operator, calibrated from the world)"
          % (preset_count(), len(YARD_STOPS)))
    dirs, targets = client.record_yard(args.world, progress=lambda p, t: print("  %-20s %s" % (p, ", ".join(t))))
    client.teleport(world.start_pose)
    task = build_task("patrol_%s" % time.strftime("%Y%m%d_%H%M%S"), dirs, targets, world, order="shortest")
    client.submit(task)
    print("patrol: task %s submitted" % task["id"])

    def show(status):
        if status["task_id"] == task["id"] and status["state"] in ("running", "paused"):
            sys.stdout.write("\r" + progress_bar(status) + "   ")
            sys.stdout.flush()
    end = client.wait_task_end(task["id"], args.timeout, show)
    rows = client.results(task["id"])
    print("\r" + progress_bar(dict(end, done=preset_count(), total=preset_count(), stop=len(YARD_STOPS),
                                   stops=len(YARD_STOPS), stop_name="", eta_s=0.0)))
    print("patrol: %s, %d readings, %d alarm(s), %d failed" % (
        end["state"], len(rows), sum(1 for r in rows if r["alarm"] == "alarm"),
        sum(1 for r in rows if r["status"] == "failed")))
    for row in rows:
        if row["alarm"] in ("alarm", "failed"):
            print("  %-8s %-28s %s %s %s"
                  % (row["alarm"], row["target_name"], row["value"], row["unit"], row["reason"]))
    paths = json.loads(client.must("task_control", "report", task["id"]))
    print("patrol: report %s" % paths["report.html"])
    ros.close()
    return 0 if end["state"] == "done" else 1


if __name__ == "__main__":
    sys.exit(main())
