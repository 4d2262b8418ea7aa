#!/usr/bin/env python3
"""Memory of rosbridge_websocket under a flood of unauthenticated, unfinished frames (issue #39 item 4).

Starts a roscore (unless one answers) and one rosbridge_websocket that requires a token, with the
shipped limits (config/rosbridge_websocket.yaml; ``--ref`` runs a git ref's code instead of the
working tree, e.g. ``--ref main`` for the figures before a change). Then ``--rounds`` times
``--connections`` raw connections (none authenticates) each do the websocket handshake and send
one binary frame whose header announces ``--frame-mb`` MB but whose last byte never comes, then
close. The bridge's resident memory (VmRSS) is read before, every 50 ms during (peak), after each
round and at the end, once the bridge holds no more sockets than before the flood. One JSON line
per figure: a line per round, then ``bridge_preauth`` with start / peak / end RSS and end/start.
"""
import argparse
import base64
import os
import socket
import struct
import sys
import threading
import time

from benchlib import report, start_roscore
from bench_bridge_tail import export, start_bridge, stop_all


def rss_mb(pid):
    with open("/proc/%d/status" % pid) as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    raise RuntimeError("no VmRSS for %d" % pid)


def sockets_held(pid):
    count = 0
    for fd in os.listdir("/proc/%d/fd" % pid):
        try:
            count += os.readlink("/proc/%d/fd/%s" % (pid, fd)).startswith("socket:")
        except OSError:
            pass
    return count


def unfinished_frame(port, frame_bytes, outcome):
    """Handshake, then a masked binary frame announcing ``frame_bytes`` with its last byte missing."""
    try:
        sock = socket.create_connection(("127.0.0.1", port), timeout=30.0)
    except OSError as exc:
        outcome.append("connect failed: %s" % exc.__class__.__name__)
        return
    try:
        key = base64.b64encode(os.urandom(16)).decode()
        sock.sendall(("GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                      "Sec-WebSocket-Key: %s\r\nSec-WebSocket-Version: 13\r\n\r\n" % key).encode())
        head = b""
        while b"\r\n\r\n" not in head:
            chunk = sock.recv(4096)
            if not chunk:
                outcome.append("closed in handshake")
                return
            head += chunk
        if b" 101 " not in head.split(b"\r\n")[0]:
            outcome.append("refused: %s" % head.split(b"\r\n")[0].decode(errors="replace"))
            return
        sock.sendall(struct.pack("!BBQ", 0x82, 0x80 | 127, frame_bytes) + os.urandom(4))
        block = b"\0" * (1 << 20)
        left = frame_bytes - 1
        while left > 0:
            sock.sendall(block[:min(left, len(block))])
            left -= min(left, len(block))
        outcome.append("sent")
    except OSError:
        outcome.append("closed by the bridge while sending")
    finally:
        sock.close()


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--ref", help="git ref of the bridge's code (default: the working tree)")
    parser.add_argument("--connections", type=int, default=40)
    parser.add_argument("--frame-mb", type=float, default=9.9)
    parser.add_argument("--rounds", type=int, default=9)
    parser.add_argument("--log", default=os.devnull, help="file for the bridge's output")
    args = parser.parse_args()
    import rosgraph
    procs = [] if rosgraph.is_master_online() else [start_roscore()]
    try:
        import rospy
        name = "preauth_%d" % os.getpid()
        log = open(args.log, "a")
        bridge = start_bridge(name, export(args.ref) if args.ref else None, {}, log,
                              ["_auth_token:=bench-token"])
        procs.append(bridge)
        rospy.init_node("bench_bridge_preauth_%d" % os.getpid(), disable_signals=True)
        deadline = time.monotonic() + 30
        while not rospy.has_param("/%s/actual_port" % name):
            if time.monotonic() > deadline or bridge.poll() is not None:
                raise RuntimeError("bridge did not start (see --log)")
            time.sleep(0.1)
        port = rospy.get_param("/%s/actual_port" % name)
        time.sleep(2.0)   # start-up done (gc.freeze follows the port): the baseline
        held0, start = sockets_held(bridge.pid), rss_mb(bridge.pid)
        peak = [start]
        stop = threading.Event()

        def sample():
            while not stop.wait(0.05):
                peak[0] = max(peak[0], rss_mb(bridge.pid))
        sampler = threading.Thread(target=sample, daemon=True)
        sampler.start()
        frame_bytes = int(args.frame_mb * 1e6)
        started = time.monotonic()
        for round_ in range(args.rounds):
            outcome = []
            threads = [threading.Thread(target=unfinished_frame, args=(port, frame_bytes, outcome))
                       for _ in range(args.connections)]
            for thread in threads:
                thread.start()
            for thread in threads:
                thread.join(120)
            kinds = {}
            for item in outcome:
                kinds[item] = kinds.get(item, 0) + 1
            report(bench="bridge_preauth_round", ref=args.ref or "worktree", round=round_ + 1,
                   rss_mb=round(rss_mb(bridge.pid), 1), peak_mb=round(peak[0], 1), outcomes=kinds)
        seconds = time.monotonic() - started
        deadline = time.monotonic() + 60
        while sockets_held(bridge.pid) > held0 and time.monotonic() < deadline:
            time.sleep(0.1)
        settled = sockets_held(bridge.pid) <= held0
        time.sleep(2.0)   # the bridge collects what departed clients left at most once a second
        stop.set()
        sampler.join()
        end = rss_mb(bridge.pid)
        report(bench="bridge_preauth", ref=args.ref or "worktree", connections=args.connections,
               frame_mb=args.frame_mb, rounds=args.rounds, flood_s=round(seconds, 1),
               rss_start_mb=round(start, 1), rss_peak_mb=round(peak[0], 1), rss_end_mb=round(end, 1),
               end_over_start=round(end / start, 3), sockets_back_to_start=settled,
               bridge_alive=bridge.poll() is None)
    finally:
        stop_all(procs)
    sys.stdout.flush()
    os._exit(0)


if __name__ == "__main__":
    main()
