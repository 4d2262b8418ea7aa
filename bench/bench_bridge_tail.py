#!/usr/bin/env python3
"""Echo tail latency of two bridges side by side (A/B/A/B), inside a running robot or on a bare roscore.

Uses the running master (ROS_MASTER_URI, e.g. sim.launch) or starts a roscore when none answers.
Starts two rosbridge_websocket processes on it, each in a session of its own as roslaunch starts
nodes (so that a ``~nice`` reaches the session's autogroup, ros/node.renice_session): A from a git
ref of this repository (``--base``,
default HEAD: the unchanged bridge), B from the working tree, each with its own extra environment
(``--env-a`` / ``--env-b`` NAME=VALUE,...; e.g. INSPECTION_BRIDGE_TRACE for bridge/trace.py; a
PYTHONPATH given there goes in front of the bridge's own, e.g. for a sitecustomize.py that changes
one thing in an experiment).
Then ``--rounds`` times, alternately against A and B, bench_bridge's raw client measures ``--n``
echo round trips (publish on a topic the client subscribes, through rospy's TCP loopback, and back;
one topic per bridge). One JSON line per round and one per bridge with the pooled p50 / p99 / max,
and the load average at each round (on a shared machine compare the ratio, not the figures).
"""
import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time

from benchlib import percentile, report, start_roscore
from bench_bridge import raw_rtt

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# An exported tree's package must still find the workspace's generated messages (devel space).
INIT = '''"""Exported copy of inspection_robot (bench_bridge_tail)."""
import os as _os
import sys as _sys
for _entry in _sys.path:
    _candidate = _os.path.join(_entry, "inspection_robot")
    if _os.path.isdir(_os.path.join(_candidate, "msg")) and _candidate not in __path__:
        __path__.append(_candidate)
'''


EXPORTS = []  # temporary directories, removed at exit


def export(ref):
    """The ``src`` folder of ``ref`` in a temporary directory (its path)."""
    where = tempfile.mkdtemp(prefix="bridge_tail_")
    EXPORTS.append(where)
    archive = subprocess.run(["git", "-C", ROOT, "archive", ref, "src"], stdout=subprocess.PIPE, check=True)
    subprocess.run(["tar", "-x", "-C", where], input=archive.stdout, check=True)
    with open(os.path.join(where, "src", "inspection_robot", "__init__.py"), "w") as out:
        out.write(INIT)
    return os.path.join(where, "src")


def parse_env(text):
    pairs = [item.split("=", 1) for item in text.split(",") if item]
    if any(len(pair) != 2 for pair in pairs):
        raise SystemExit("--env-a/--env-b take NAME=VALUE,...; got %r" % text)
    return dict(pairs)


def stop_all(procs):
    """SIGINT the bench's processes, newest first (rospy shuts down and runs its hooks: the trace dump),
    kill any that do not end within 15 s, and remove the exported code trees."""
    for proc in reversed(procs):
        proc.send_signal(2)
    for proc in reversed(procs):
        try:
            proc.wait(15)
        except subprocess.TimeoutExpired:
            proc.kill()
    for where in EXPORTS:
        shutil.rmtree(where, ignore_errors=True)


def start_bridge(name, python_path, extra_env, log, params=()):
    """A bridge from ``python_path`` (a checkout's src; None: this one) on a free port. Its surface is
    ``open``: benches use their own /bench topics, which no backend role may touch."""
    env = dict(os.environ)
    extra_env = dict(extra_env)
    python_path = os.pathsep.join(p for p in (extra_env.pop("PYTHONPATH", None), python_path) if p)
    env.update(extra_env)
    if python_path:
        env["PYTHONPATH"] = python_path + os.pathsep + env.get("PYTHONPATH", "")
    return subprocess.Popen([sys.executable, "-c",
                             "from inspection_robot.nodes.rosbridge_websocket import main; main()",
                             "__name:=%s" % name, "_port:=0", "_address:=127.0.0.1", "_console:=false",
                             "_surface:=open"] + list(params),
                            stdout=log, stderr=subprocess.STDOUT, env=env, start_new_session=True)


def side_client(url, topics):
    """A second client subscribed to ``topics``, its frames read and dropped by a thread; (client, [count])."""
    import queue
    import threading

    from inspection_robot_testing.bridge_client import CLOSED, RawClient
    client = RawClient(url)
    for topic in topics.split(","):
        client.send({"op": "subscribe", "topic": topic})
    count = [0]

    def drain():
        while True:
            try:
                frame = client.recv(1.0)
            except queue.Empty:
                continue
            if frame is CLOSED:
                return
            count[0] += 1
    threading.Thread(target=drain, daemon=True).start()
    return client, count


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--base", default="HEAD", help="git ref of bridge A (default HEAD)")
    parser.add_argument("--base-b", help="git ref of bridge B (default: the working tree)")
    parser.add_argument("--env-a", default="", help="NAME=VALUE,... for bridge A")
    parser.add_argument("--env-b", default="", help="NAME=VALUE,... for bridge B")
    parser.add_argument("--params-a", default="", help="private params of bridge A, e.g. _nice:=-10 (space-separated)")
    parser.add_argument("--params-b", default="", help="private params of bridge B, e.g. _nice:=-5 (space-separated)")
    parser.add_argument("--side-topics", default="",
                        help="comma-separated topics a second client of each bridge subscribes (the fan-out a "
                             "console causes, e.g. robot_status,camera/image_raw); counted, then dropped")
    parser.add_argument("--rounds", type=int, default=6, help="rounds per bridge, alternating")
    parser.add_argument("--n", type=int, default=1000, help="echoes per round")
    parser.add_argument("--log", default=os.devnull, help="file for both bridges' output")
    args = parser.parse_args()
    import rosgraph
    procs = [] if rosgraph.is_master_online() else [start_roscore()]
    try:
        import rospy

        from inspection_robot_testing.bridge_client import RawClient
        log = open(args.log, "a")
        tag = "%d" % os.getpid()
        names = {"A": "tail_a_" + tag, "B": "tail_b_" + tag}
        procs.append(start_bridge(names["A"], export(args.base), parse_env(args.env_a), log, args.params_a.split()))
        procs.append(start_bridge(names["B"], export(args.base_b) if args.base_b else None, parse_env(args.env_b), log,
                                  args.params_b.split()))
        rospy.init_node("bench_bridge_tail_" + tag, disable_signals=True)
        clients = {}
        for arm, name in sorted(names.items()):
            deadline = time.monotonic() + 30
            while not rospy.has_param("/%s/actual_port" % name):
                if time.monotonic() > deadline:
                    raise RuntimeError("bridge %s did not start" % arm)
                time.sleep(0.1)
            clients[arm] = RawClient("ws://127.0.0.1:%d" % rospy.get_param("/%s/actual_port" % name))
        side = {arm: side_client(clients[arm].url, args.side_topics) for arm in clients if args.side_topics}
        pooled = {"A": [], "B": []}
        for round_ in range(args.rounds):
            for arm in ("A", "B") if round_ % 2 == 0 else ("B", "A"):
                samples = raw_rtt(clients[arm], "/bench/tail_%s" % arm.lower(), args.n)
                pooled[arm].extend(samples)
                report(bench="bridge_tail_round", bridge=arm, round=round_, n=len(samples),
                       p50_ms=round(percentile(samples, 0.5), 3), p99_ms=round(percentile(samples, 0.99), 3),
                       max_ms=round(max(samples), 3), load_avg_1min=round(os.getloadavg()[0], 1))
        for arm in ("A", "B"):
            samples = pooled[arm]
            report(bench="bridge_tail", bridge=arm, n=len(samples), p50_ms=round(percentile(samples, 0.5), 3),
                   p99_ms=round(percentile(samples, 0.99), 3), p999_ms=round(percentile(samples, 0.999), 3),
                   max_ms=round(max(samples), 3), over_1ms=sum(1 for s in samples if s > 1.0))
        ratio = {q: round(percentile(pooled["B"], q) / percentile(pooled["A"], q), 2) for q in (0.5, 0.99)}
        report(bench="bridge_tail_ratio", p50_b_over_a=ratio[0.5],
               p99_b_over_a=ratio[0.99], max_b_over_a=round(max(pooled["B"]) / max(pooled["A"]), 2),
               load_avg=[round(x, 1) for x in os.getloadavg()])
        for arm, (client, count) in sorted(side.items()):
            report(bench="bridge_tail_side", bridge=arm, topics=args.side_topics, frames_received=count[0])
            client.close()
        for client in clients.values():
            client.close()
    finally:
        stop_all(procs)
    os._exit(0)


if __name__ == "__main__":
    main()
