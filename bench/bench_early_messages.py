#!/usr/bin/env python3
"""How long after ``advertise`` a client's first message reaches a ROS subscriber, under CPU load
(issue #44 item 3), and how many of the messages published at once are lost.

Starts a roscore and one rosbridge_websocket (``--ref`` runs a git ref's code, e.g. ``--ref main``
for the figures before a change) and ``--hogs`` busy-looping processes (default 3 on 2 cores).
Each round a rospy subscriber (this process) subscribes to a new topic; once the master lists it,
a websocket client (a new connection each round: disconnect, connect, as a backend that
reconnects) advertises the topic and publishes ``--messages`` (20) messages at once. Figures, one
JSON line each: ``first_message_after_advertise`` (ms from the advertise sent to the first message
received, p50/p99/max), ``early_messages_lost`` (of rounds x messages, and rounds losing any).
"""
import argparse
import os
import shutil
import signal
import subprocess
import sys
import threading
import time

from benchlib import latency_figures, report, start_roscore, wait_for
from bench_bridge_tail import EXPORTS, export, start_bridge


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rounds", type=int, default=40)
    parser.add_argument("--messages", type=int, default=20)
    parser.add_argument("--hogs", type=int, default=3, help="busy-looping processes beside the bridge")
    parser.add_argument("--ref", help="run the bridge with this git ref's code")
    parser.add_argument("--settle", type=float, default=15.0, help="s to wait for a round's last message")
    args = parser.parse_args()

    import rosgraph
    import rospy
    from std_msgs.msg import String

    from inspection_robot_testing.bridge_client import RawClient
    core = start_roscore()
    log = open(os.devnull, "w")
    bridge = start_bridge("rosbridge_websocket", export(args.ref) if args.ref else None, {}, log)
    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.hogs)]
    try:
        rospy.init_node("bench_early_messages", disable_signals=True)
        master = rosgraph.Master("/bench_early_messages")
        port = wait_for(lambda: rospy.get_param("/rosbridge_websocket/actual_port", None), 60.0, "the bridge's port")
        delays, lost, rounds_losing = [], 0, 0
        for k in range(args.rounds):
            topic = "/early_%d" % k
            got, first = [], []
            lock = threading.Lock()

            def received(msg, got=got, first=first, lock=lock):
                with lock:
                    if not first:
                        first.append(time.monotonic())
                    got.append(msg.data)
            subscriber = rospy.Subscriber(topic, String, received, queue_size=None)
            wait_for(lambda: any(t == topic for t, _ in master.getSystemState()[1]), 30.0, "the subscriber listed")
            client = RawClient("ws://127.0.0.1:%d" % port, timeout=30.0)
            sent = time.monotonic()
            client.send_many([{"op": "advertise", "topic": topic, "type": "std_msgs/String"}]
                             + [{"op": "publish", "topic": topic, "msg": {"data": str(i)}}
                                for i in range(args.messages)])
            try:
                wait_for(lambda: len(got) >= args.messages, args.settle, "the messages", 0.005)
            except RuntimeError:
                pass
            with lock:
                missing = args.messages - len(set(got))
                if first:
                    delays.append(first[0] - sent)
            lost += missing
            rounds_losing += missing > 0
            delay = "%.0f" % ((first[0] - sent) * 1000) if first else "-"
            print("round %d: first after %s ms, %d lost" % (k, delay, missing), file=sys.stderr, flush=True)
            client.close()
            subscriber.unregister()
        report(figure="first_message_after_advertise", hogs=args.hogs, ref=args.ref or "working tree",
               **latency_figures(delays))
        report(figure="early_messages_lost", hogs=args.hogs, ref=args.ref or "working tree", rounds=args.rounds,
               messages=args.rounds * args.messages, lost=lost, rounds_losing=rounds_losing)
    finally:
        for hog in hogs:
            hog.kill()
        os.killpg(bridge.pid, signal.SIGINT)
        try:
            bridge.wait(20.0)
        except subprocess.TimeoutExpired:
            os.killpg(bridge.pid, signal.SIGKILL)
        core.terminate()
        core.wait(30.0)
        log.close()
        for where in EXPORTS:
            shutil.rmtree(where, ignore_errors=True)


if __name__ == "__main__":
    main()
