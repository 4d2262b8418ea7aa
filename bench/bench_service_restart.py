#!/usr/bin/env python3
"""The first service call after a node restarts (issue #44 item 1): calls over the websocket while
file_server is killed and respawned.

Starts a roscore of its own and, under roslaunch (respawn, as sim.launch), rosbridge_websocket and
file_server. A websocket client calls ``file_control stat {"path": "tasks"}`` until it answers
(the bridge then holds an idle persistent connection to file_server), then file_server is killed,
in turn with SIGKILL of its pid and with ``rosnode kill`` (its slave API's shutdown, as SIGTERM).
Once the master lists file_control at a new URI (the respawned node registered) the client makes
one call: does it fail? ``--kills`` rounds (default 100). Then ``--stream-kills`` (20) more while a
second client calls continuously (one call after another). ``--ref main`` runs main's code (the
figures before a change). One JSON line per figure:

- ``first_call_after_respawn``: failures of the first call after the new registration, of N kills;
- ``calls_during_kills``: the stream's calls, failed ones, failed ones made after the node was back
  (should be 0), and the texts of the failures (counted);
- ``lookup_service_ms``: the cost of one master lookupService (what a URI check per call would add).
"""
import argparse
import collections
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import xmlrpc.client

from benchlib import latency_figures, report, start_roscore, wait_for
from bench_bridge_tail import EXPORTS, export

SERVICE = "/file_control"
NODE = "/file_server"
LAUNCH = """<launch>
  <param name="data_root" value="%(root)s"/>
  <node pkg="inspection_robot" type="rosbridge_websocket" name="rosbridge_websocket" output="log" respawn="true">
    <rosparam command="load" file="$(find inspection_robot)/config/rosbridge_websocket.yaml"/>
    <param name="port" value="0"/>
    <param name="address" value="127.0.0.1"/>
    <param name="surface" value="open"/>
    <param name="console" value="false"/>
  </node>
  <node pkg="inspection_robot" type="file_server" name="file_server" output="log" respawn="true">
    <rosparam command="load" file="$(find inspection_robot)/config/file_server.yaml"/>
    <rosparam command="load" file="$(find inspection_robot)/config/camera_optics.yaml"/>
  </node>
</launch>
"""


class Caller(object):
    """A websocket client calling file_control stat; ``call()`` -> (ok, text)."""

    def __init__(self, url):
        from inspection_robot_testing.bridge_client import RawClient
        self._client = RawClient(url)
        self._n = 0

    def call(self, timeout_s=30.0):
        self._n += 1
        call_id = "c%d" % self._n
        self._client.send({"op": "call_service", "id": call_id, "service": SERVICE,
                           "type": "inspection_robot/ControlService",
                           "args": {"cmd": "stat", "data": json.dumps({"path": "tasks"})}})
        reply = self._client.recv_message(lambda m: m.get("op") == "service_response" and m.get("id") == call_id,
                                          timeout=timeout_s)
        if not reply.get("result"):
            return False, str(reply.get("values"))
        return reply["values"].get("ack") == "success", json.dumps(reply["values"])[:200]

    def close(self):
        self._client.close()


def service_uri(master):
    try:
        return master.lookupService(SERVICE)
    except Exception:  # boundary: not registered (rosgraph.MasterError) or the master busy
        return None


def kill(master, how):
    """Kill file_server ``how`` ("sigkill" or "rosnode"); returns its URI before."""
    node_uri = master.lookupNode(NODE)
    if how == "sigkill":
        pid = xmlrpc.client.ServerProxy(node_uri).getPid("/bench")[2]
        os.kill(pid, signal.SIGKILL)
    else:
        subprocess.run(["rosnode", "kill", NODE], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--kills", type=int, default=100, help="kills with one call after each respawn")
    parser.add_argument("--ref", help="run the nodes with this git ref's code (e.g. main, for the figures before)")
    parser.add_argument("--stream-kills", type=int, default=20, help="kills under a continuous stream of calls")
    args = parser.parse_args()

    import rosgraph
    if args.ref:
        os.environ["PYTHONPATH"] = export(args.ref) + os.pathsep + os.environ.get("PYTHONPATH", "")
    root = tempfile.mkdtemp(prefix="bench_service_restart_")
    os.makedirs(os.path.join(root, "tasks"))
    core = start_roscore()
    launch_file = os.path.join(root, "bench.launch")
    with open(launch_file, "w") as f:
        f.write(LAUNCH % {"root": root})
    log = open(os.path.join(root, "roslaunch.log"), "w")
    launch = subprocess.Popen(["roslaunch", "--wait", launch_file], stdout=log, stderr=subprocess.STDOUT,
                              start_new_session=True)
    stop = threading.Event()
    try:
        master = rosgraph.Master("/bench")
        port = wait_for(lambda: _param(master, "/rosbridge_websocket/actual_port"), 60.0, "the bridge's port")
        wait_for(lambda: service_uri(master), 60.0, "file_control")
        url = "ws://127.0.0.1:%d" % port
        first, stream = Caller(url), Caller(url)
        wait_for(lambda: first.call()[0], 30.0, "a first answer")

        lookups = []
        first_failures, texts = 0, collections.Counter()
        for k in range(args.kills):   # nothing else calls: the idle connection is the one the first call finds
            wait_for(lambda: first.call()[0], 30.0, "file_control answering before kill %d" % k)
            before = service_uri(master)
            kill(master, "sigkill" if k % 2 == 0 else "rosnode")
            wait_for(lambda: service_uri(master) not in (None, before), 60.0, "file_server's new registration", 0.005)
            ok, text = first.call()
            if not ok:
                first_failures += 1
                texts[text[:120]] += 1
            start = time.monotonic()
            service_uri(master)
            lookups.append(time.monotonic() - start)
            print("kill %d/%d: first call %s" % (k + 1, args.kills, "ok" if ok else "FAILED: " + text[:100]),
                  file=sys.stderr, flush=True)
        report(figure="first_call_after_respawn", kills=args.kills, failed=first_failures, texts=dict(texts))
        report(figure="lookup_service_ms", **latency_figures(lookups))

        absent = [False]        # between a kill and the new registration
        stream_calls = collections.Counter()
        failures = collections.Counter()

        def call_continuously():
            while not stop.is_set():
                was_absent = absent[0]
                ok, text = stream.call()
                stream_calls["calls"] += 1
                if not ok:
                    stream_calls["failed"] += 1
                    if not was_absent and not absent[0]:
                        stream_calls["failed_while_present"] += 1
                    failures[text.split(" (")[0][:120]] += 1
        streamer = threading.Thread(target=call_continuously, daemon=True)
        streamer.start()
        for k in range(args.stream_kills):
            wait_for(lambda: first.call()[0], 30.0, "file_control answering before kill %d" % k)
            before = service_uri(master)
            absent[0] = True
            kill(master, "sigkill" if k % 2 == 0 else "rosnode")
            wait_for(lambda: service_uri(master) not in (None, before), 60.0, "file_server's new registration", 0.005)
            absent[0] = False
        stop.set()
        streamer.join(30.0)
        report(figure="calls_during_kills", kills=args.stream_kills, calls=stream_calls["calls"],
               failed=stream_calls["failed"], failed_while_present=stream_calls["failed_while_present"],
               texts=dict(failures))
        first.close()
        stream.close()
    finally:
        stop.set()
        try:
            os.killpg(launch.pid, signal.SIGINT)
            launch.wait(30.0)
        except (OSError, subprocess.TimeoutExpired):
            os.killpg(launch.pid, signal.SIGKILL)
        core.terminate()
        core.wait(30.0)
        log.close()
        shutil.rmtree(root, ignore_errors=True)
        for where in EXPORTS:
            shutil.rmtree(where, ignore_errors=True)


def _param(master, name):
    try:
        return master.getParam(name)
    except Exception:  # boundary: not set yet
        return None


if __name__ == "__main__":
    main()
