#!/usr/bin/env python3
"""A backend that reconnects keeps the control it acquires (issue #44 item 2): N tries of the reconnect.

Starts a roscore of its own and the three nodes the reconnect involves: rosbridge_websocket,
status_control and robot_control (simulated chassis), from the working tree or, with ``--ref``, a git
ref's code (``--ref main`` for the figures before the change). Each try (inspection_robot_testing.
backend_reconnect.reconnect_trial): backend A beats, acquires server mode and disconnects; backend B
connects a random 0 .. timeout + 0.2 s later (a restarted backend), beats and acquires at once, then
watches robot_status for timeout + 0.5 s: control kept = B's acquire granted and mode 1 online all
along. ``--sequence numbered`` is the documented sequence (heartbeat session number, wait for
robot_status to name it), ``legacy`` the one before it (wait for offline_warn 0). One JSON line per
figure: ``backend_reconnect`` with kept / tries and the first reasons of the losses.
"""
import argparse
import os
import random
import subprocess
import sys
import time

from benchlib import report, start_roscore
from bench_bridge_tail import EXPORTS, export, start_bridge


def start_node(module, name, python_path, log, params=()):
    env = dict(os.environ)
    if python_path:
        env["PYTHONPATH"] = python_path + os.pathsep + env.get("PYTHONPATH", "")
    return subprocess.Popen([sys.executable, "-c", "from inspection_robot.nodes.%s import main; main()" % module,
                             "__name:=%s" % name] + list(params), stdout=log, stderr=subprocess.STDOUT, env=env,
                            start_new_session=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--tries", type=int, default=100)
    parser.add_argument("--ref", help="git ref of the nodes' code (default: the working tree)")
    parser.add_argument("--sequence", choices=("numbered", "legacy"), default="numbered")
    parser.add_argument("--heartbeat-timeout", type=float, default=3.0, help="status_control's, s")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    import rospy
    from inspection_robot_testing.backend_reconnect import reconnect_trial

    core = start_roscore()
    code = export(args.ref) if args.ref else None
    log = open("/tmp/bench_backend_reconnect.log", "w")
    nodes = [start_bridge("rosbridge_websocket", code, {}, log),
             start_node("status_control", "status_control", code, log,
                        ["_heartbeat_timeout:=%g" % args.heartbeat_timeout]),
             start_node("robot_control", "robot_control", code, log, ["_driver:=sim"])]
    rng = random.Random(args.seed)
    try:
        rospy.init_node("bench_backend_reconnect", disable_signals=True)
        deadline = time.monotonic() + 60.0
        while rospy.get_param("/rosbridge_websocket/actual_port", None) is None:
            if time.monotonic() > deadline:
                raise SystemExit("bridge did not start: /tmp/bench_backend_reconnect.log")
            time.sleep(0.2)
        url = "ws://127.0.0.1:%d" % rospy.get_param("/rosbridge_websocket/actual_port")
        kept, why = 0, []
        for _ in range(args.tries):
            result = reconnect_trial(url, args.heartbeat_timeout + 0.5, rng.uniform(0.0, args.heartbeat_timeout + 0.2),
                                     numbered=args.sequence == "numbered", rng=rng)
            kept += result["kept"]
            if not result["kept"]:
                why.append(result["why"])
        report(bench="backend_reconnect", ref=args.ref or "worktree", sequence=args.sequence,
               heartbeat_timeout_s=args.heartbeat_timeout, tries=args.tries, control_kept=kept,
               losses=sorted(set(why))[:3])
    finally:
        for proc in nodes + [core]:
            proc.terminate()
        for proc in nodes + [core]:
            proc.wait(10)
        for where in EXPORTS:
            subprocess.run(["rm", "-rf", where])


if __name__ == "__main__":
    main()
