#!/usr/bin/env python3
"""Benchmark of the backend link: the project's bridge against a plain websocket echo server.

Starts its own roscore and rosbridge_websocket (port 0), plus an in-process tornado echo server
that answers each publish / call_service frame with the same frame / an empty service_response.
The same clients (a raw tornado websocket client and roslibpy) measure, against both:
publish->subscribe round trip (p50/p99), one-way throughput client->ROS and ROS->client (msgs/s),
call_service latency to a ROS ControlService and to /rosapi/get_time. One JSON line per figure;
``ratio`` = bridge / echo (latency) or bridge / echo (throughput).

Burst mode (``bridge_burst``): one client subscribes to a topic and publishes N sequence-numbered
32-byte strings on it through the same connection as fast as it can (no window), then counts what
comes back: delivered, lost, out of order, and the delivered rate (messages / time from the first
send to the last arrival). Any loss or reordering makes the bench exit non-zero.
Image line (``bridge_image``): a 1080p rgb8 sensor_msgs/Image published at 10 Hz by a ROS node in a
process of its own (header.seq numbered) to three client processes (JSON, CBOR, PNG compression): per
client frames published, received, lost, received per second, and the latency from the publish
(header.stamp) to the frame's arrival at the client.
Video line (``bridge_video``, ``--only video``): what the console's live view does. A 1280x720 JPEG
(the simulated camera's rendered view of the yard, encoded as camera_node encodes it) published as
sensor_msgs/CompressedImage at ``--video-rate`` Hz by a ROS publisher process, to three client
processes that subscribe as the console does (``compression: cbor``, ``queue_length: 1``), decode
the CBOR message and the JPEG (OpenCV) and count what arrives: per client frames published,
received, latency p50/p99 from the publish (header.stamp) to the decoded picture, and the bridge's
CPU (% of one core, ms per published frame). The same clients run against every bridge in one run,
``--video-rounds`` times in alternating order (the ratio line compares the medians of the rounds):
ours, rosbridge_server 0.11.17 started from its source tree (``--rosbridge-src DIR``: a checkout of
RobotWebTools/rosbridge_suite at tag 0.11.17; it needs pymongo's bson on ``--rosbridge-deps DIR``,
e.g. ``pip install --target DIR pymongo``; rosbridge_msgs is generated with genpy and rosauth, unused
without ``~authenticate``, is stubbed, both into a temporary folder) and any ``--url ws://...``
(no CPU figure). A ``bridge_video_ratio`` line compares ours with rosbridge. ``--slow-ms`` adds a
fourth client that takes that long over each frame and reads its socket only between frames: with
queue_length 1 it should get fresh frames (few of them), not a growing backlog.
Side by side (``--only compare``): the raw client's echo round trip (p50/p99 of ``N_RTT``) and a
10,000-message burst (delivered rate, lost, out of order, bridge CPU per message) against ours and
every other bridge (``--rosbridge-src``, ``--url``), ``--compare-rounds`` times in alternating order;
a ``bridge_compare_ratio`` line per other bridge gives ours / theirs for the burst rate and theirs /
ours for the echo percentiles (medians of the rounds). Only ours' losses fail the bench.
``--only burst,image,classic,video,compare`` runs a subset; ``--bursts 10000,100000`` sets the burst sizes;
``--image-seconds`` the image and video lines' length.
"""
import argparse
import asyncio
import concurrent.futures
import json
import os
import queue
import re
import shutil
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time

from benchlib import percentile, report, start_roscore

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
N_RTT = 1000
N_THROUGHPUT = 5000
N_CALLS = 300
WINDOW = 200


def start_echo_server():
    """A plain websocket server doing the least a rosbridge peer must: echo publish, answer calls."""
    import tornado.ioloop
    import tornado.web
    import tornado.websocket

    class Echo(tornado.websocket.WebSocketHandler):
        def check_origin(self, origin):
            return True

        def open(self):
            self.set_nodelay(True)

        def on_message(self, message):
            msg = json.loads(message)
            if msg.get("op") == "publish":
                self.write_message(message)
            elif msg.get("op") == "call_service":
                self.write_message(json.dumps({"op": "service_response", "service": msg["service"], "values": {},
                                               "result": True, "id": msg.get("id")}))

    ready = concurrent.futures.Future()

    def run():
        asyncio.set_event_loop(asyncio.new_event_loop())
        app = tornado.web.Application([(r"/.*", Echo)])
        server = app.listen(0, "127.0.0.1")
        ready.set_result(next(iter(server._sockets.values())).getsockname()[1])
        tornado.ioloop.IOLoop.current().start()
    thread = threading.Thread(target=run)
    thread.daemon = True
    thread.start()
    return ready.result(5)


def loopback_ready(client, topic):
    """Subscribe and advertise ``topic`` through the bridge; return once a publish comes back."""
    client.send({"op": "subscribe", "topic": topic, "type": "std_msgs/String"})
    client.send({"op": "advertise", "topic": topic, "type": "std_msgs/String"})
    deadline = time.monotonic() + 10
    while True:  # until the ROS loopback connection is up
        client.send({"op": "publish", "topic": topic, "msg": {"data": "warmup"}})
        try:
            client.recv_message(lambda m: m.get("op") == "publish", timeout=0.2)
            break
        except queue.Empty:
            if time.monotonic() > deadline:
                raise
    drain(client)


def raw_rtt(client, topic, n):
    loopback_ready(client, topic)
    samples = []
    for i in range(n):
        t0 = time.perf_counter()
        client.send('{"op":"publish","topic":"%s","msg":{"data":"%d"}}' % (topic, i))
        client.recv_message(lambda m: m.get("op") == "publish" and m["msg"]["data"] == str(i), timeout=5)
        samples.append((time.perf_counter() - t0) * 1000.0)
    return samples


def drain(client):
    try:
        while True:
            client.recv(0.2)
    except queue.Empty:
        pass


def raw_throughput_loopback(client, topic, n):
    """Publish n messages with at most WINDOW in flight; msgs/s until the last came back."""
    t0 = time.perf_counter()
    sent = received = 0
    while received < n:
        while sent < n and sent - received < WINDOW:
            client.send('{"op":"publish","topic":"%s","msg":{"data":"%d"}}' % (topic, sent))
            sent += 1
        frame = client.recv(5)
        if isinstance(frame, str) and frame.startswith('{"op":"publish"'):
            received += 1
    return n / (time.perf_counter() - t0)


def raw_calls(client, service, args, n):
    samples = []
    for i in range(n):
        t0 = time.perf_counter()
        client.send({"op": "call_service", "id": "c%d" % i, "service": service, "args": args})
        reply = client.recv_message(lambda m: m.get("op") == "service_response" and m.get("id") == "c%d" % i, 5)
        if not reply["result"]:
            raise RuntimeError("call failed: %s" % reply)
        samples.append((time.perf_counter() - t0) * 1000.0)
    return samples


def roslibpy_rtt(port, topic, n):
    import roslibpy
    ros = roslibpy.Ros("127.0.0.1", port)
    ros.run(timeout=10)
    got = queue.Queue()
    listener = roslibpy.Topic(ros, topic, "std_msgs/String")
    listener.subscribe(lambda m: got.put(m["data"]))
    talker = roslibpy.Topic(ros, topic, "std_msgs/String")
    deadline = time.monotonic() + 10
    while True:
        talker.publish(roslibpy.Message({"data": "warmup"}))
        try:
            got.get(timeout=0.2)
            break
        except queue.Empty:
            if time.monotonic() > deadline:
                raise
    while not got.empty():
        got.get()
    samples = []
    for i in range(n):
        t0 = time.perf_counter()
        talker.publish(roslibpy.Message({"data": str(i)}))
        while got.get(timeout=5) != str(i):
            pass
        samples.append((time.perf_counter() - t0) * 1000.0)
    ros.close()
    return samples


def cpu_seconds(pid):
    """User + system CPU time of a process so far (Linux /proc), in seconds."""
    with open("/proc/%d/stat" % pid) as stat:
        fields = stat.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / float(os.sysconf("SC_CLK_TCK"))


def burst(url, topic, n, bridge_pid=None, timeout=120.0):
    """Unpaced publish of n sequence numbers and subscribe on one connection.

    Returns (delivered/s, lost, out of order, delivered, status texts, bridge CPU µs per message).
    The CPU figure does not depend on how loaded the machine is, the rate does.
    """
    from inspection_robot_testing.bridge_client import RawClient
    client = RawClient(url)
    loopback_ready(client, topic)
    pad = "x" * 24
    cpu0 = cpu_seconds(bridge_pid) if bridge_pid else None
    t0 = time.perf_counter()
    # 32-byte payloads: 8 digits of sequence number + padding
    client.send_many('{"op":"publish","topic":"%s","msg":{"data":"%08d%s"}}' % (topic, i, pad) for i in range(n))
    seqs, statuses, t_last = [], [], t0
    end = time.monotonic() + timeout
    while len(seqs) < n and time.monotonic() < end:
        try:
            frame = client.recv(10.0)
        except queue.Empty:
            break  # nothing for 10 s: the rest is lost
        if not isinstance(frame, str):
            break
        if frame.startswith('{"op":"publish"'):
            seqs.append(int(json.loads(frame)["msg"]["data"][:8]))
            t_last = time.perf_counter()
        elif '"op":"status"' in frame.replace(" ", ""):
            statuses.append(json.loads(frame)["msg"])
    cpu_us = (cpu_seconds(bridge_pid) - cpu0) * 1e6 / max(1, len(seqs)) if bridge_pid else None
    client.close()
    disordered = sum(1 for a, b in zip(seqs, seqs[1:]) if b <= a)
    lost = n - len(set(seqs))
    return len(seqs) / max(t_last - t0, 1e-9), lost, disordered, len(seqs), statuses, cpu_us


HEADER = re.compile(r'"header":\{"seq":(\d+),"stamp":\{"secs":(\d+),"nsecs":(\d+)\}')
IMAGE_TOPIC = "/bench/image"


def paced_publish(pub, msg, seconds, rate_hz, subscribers):
    """Wait for ``subscribers`` connections, then publish ``msg`` every 1/rate_hz s for ``seconds``
    (header.seq 0, 1, ...; header.stamp = wall-clock time of the publish) and print one JSON line:
    frames published, the wall-clock time of the first, and how late the latest publish started
    (rospy's queue is large enough that none of these frames can be dropped). Then stays alive
    (rospy still writes queued frames) until its stdin is closed."""
    import rospy
    deadline = time.monotonic() + 20
    while pub.get_num_connections() < subscribers and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.5)  # the bridge's subscriber connection is up; let its clients' subscriptions settle
    published, late_ms, t0 = 0, [], time.time()
    while published < int(seconds * rate_hz):
        due = t0 + published / rate_hz
        time.sleep(max(0.0, due - time.time()))
        now = time.time()
        late_ms.append((now - due) * 1000.0)
        msg.header.seq = published
        msg.header.stamp = rospy.Time.from_sec(now)
        pub.publish(msg)
        published += 1
    print(json.dumps({"published": published, "t0": t0, "late_p99_ms": round(percentile(late_ms, 0.99), 1)}),
          flush=True)
    sys.stdin.read()  # rospy's connection thread may still be writing queued frames: live until told


def publish_images(seconds, rate_hz, subscribers):
    """The image line's publisher (a process of its own so nothing of the bench delays it): 1080p rgb8."""
    import rospy
    from sensor_msgs.msg import Image
    rospy.init_node("bench_image_publisher", disable_signals=True)
    pub = rospy.Publisher(IMAGE_TOPIC, Image, queue_size=int(seconds * rate_hz) + 10)
    pixels = bytes(bytearray(i % 251 for i in range(1920 * 3))) * 1080
    paced_publish(pub, Image(height=1080, width=1920, encoding="rgb8", step=1920 * 3, data=pixels), seconds,
                  rate_hz, subscribers)


def camera_jpeg(width=1280, height=720, quality=80):
    """The simulated camera's rendered view of the yard as camera_node's JPEG (camera.jpeg, ~80 kB at 720p)."""
    from inspection_robot.camera.jpeg import encode_jpeg
    from inspection_robot.sim.render import PinholeCamera, Renderer
    from inspection_robot.sim.world import World
    world = World.load(os.path.join(ROOT, "config", "sim_world.yaml"))
    camera = PinholeCamera.from_pose((0.0, 0.0, 0.3), 0.0, 0.0, world.sensor_height, 0.9 * width, width, height)
    return encode_jpeg(Renderer(world, 0, 2.0, 0.6, 0.08).render(camera), quality)


def publish_video(topic, seconds, rate_hz, subscribers):
    """The video line's publisher (a process of its own): a 720p JPEG CompressedImage on ``topic``."""
    import rospy
    from sensor_msgs.msg import CompressedImage
    jpeg = camera_jpeg()
    rospy.init_node("bench_video_publisher", anonymous=True, disable_signals=True)
    pub = rospy.Publisher(topic, CompressedImage, queue_size=int(seconds * rate_hz) + 10)
    paced_publish(pub, CompressedImage(format="jpeg", data=jpeg), seconds, rate_hz, subscribers)


def timed_client(url):
    """A RawClient that notes the wall-clock arrival time of every frame (in ``arrivals``)."""
    from inspection_robot_testing.bridge_client import RawClient

    class TimedClient(RawClient):
        def __init__(self, url):
            self.arrivals = queue.Queue()
            RawClient.__init__(self, url)

        def _on_message(self, message):
            if message is not None:
                self.arrivals.put(time.time())
            RawClient._on_message(self, message)
    return TimedClient(url)


def receive_frames(client, record, quiet_s, limit_s):
    """The image and video clients' loop: each frame the bridge sends, with its arrival time, to
    ``record(frame, arrived)`` (returns a (seq, latency ms, time) row, or raises on a frame it cannot
    read: reported, not fatal) until no frame came for ``quiet_s`` after the first; statuses apart.
    Prints one JSON line {"frames", "status", "error"}."""
    from inspection_robot_testing.bridge_client import CLOSED
    frames, statuses, error = [], [], None
    end = time.monotonic() + limit_s
    while time.monotonic() < end:
        try:
            frame = client.recv(quiet_s if frames else limit_s)
        except queue.Empty:
            break
        if frame is CLOSED:
            error = "closed by the bridge: %s %s" % (client.close_code, client.close_reason)
            break
        arrived = client.arrivals.get()
        if isinstance(frame, str) and '"status"' in frame[:20]:  # {"op": "status", ...}
            statuses.append(json.loads(frame).get("msg"))
            continue
        try:
            frames.append(record(frame, arrived))
        except (ValueError, KeyError, AttributeError, TypeError) as exc:  # a bug: reported, not fatal
            error = error or repr(exc)[:200] + " in " + repr(frame[:100])
    client.close()
    print(json.dumps({"frames": frames, "status": statuses[:3], "error": error}), flush=True)


def image_client(url, kind, quiet_s=10.0, limit_s=150.0):
    """One image line client, run in a process of its own (the clients must not share one GIL).

    Subscribes with compression ``kind``, prints "ready", then records (header.seq, latency ms from
    header.stamp to the frame's arrival on the websocket thread, before decoding) until no frame
    came for ``quiet_s`` after the first; prints them as one JSON line.
    """
    from inspection_robot.bridge import cbor
    from inspection_robot.bridge.compression import png_decode

    def header_of(frame):
        if kind == "cbor":
            header = cbor.loads(frame)["msg"]["header"]
            return header["seq"], header["stamp"]["secs"] + header["stamp"]["nsecs"] * 1e-9
        text = frame if kind == "none" else png_decode(json.loads(frame)["data"])
        seq, secs, nsecs = HEADER.search(text[:300]).groups()
        return int(seq), int(secs) + int(nsecs) * 1e-9

    def record(frame, arrived):
        seq, stamp = header_of(frame)
        return seq, round((arrived - stamp) * 1000.0, 2), arrived

    client = timed_client(url)
    client.send({"op": "subscribe", "topic": IMAGE_TOPIC, "type": "sensor_msgs/Image", "compression": kind})
    print("ready", flush=True)
    receive_frames(client, record, quiet_s, limit_s)


def image_line(url, bridge_pid, seconds=10.0, rate_hz=10.0):
    """A 1080p rgb8 image at rate_hz from a ROS publisher process to three client processes
    (JSON, CBOR, PNG compression).

    Per client: frames published, received, lost (sequence numbers that never arrived), delivered
    per second (received / time from the first publish to the last arrival), latency p50/p99 from
    the publish (header.stamp) to the frame's arrival at the client (before it is decoded, so a
    slow decoder does not count), and the bridge's CPU time per frame it sent (all three
    encodings; does not depend on the machine's load).
    """
    kinds = ("none", "cbor", "png")
    clients = {}
    for kind in kinds:
        clients[kind] = subprocess.Popen([sys.executable, os.path.abspath(__file__), "--image-client", kind, url],
                                         stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, universal_newlines=True)
    try:
        for proc in clients.values():
            if proc.stdout.readline().strip() != "ready":
                raise RuntimeError("an image client did not start")
        cpu0 = cpu_seconds(bridge_pid)
        publisher = clients["publisher"] = subprocess.Popen(
            [sys.executable, os.path.abspath(__file__), "--publish-images", "%g,%g" % (seconds, rate_hz)],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, universal_newlines=True)
        published = json.loads(publisher.stdout.readline())
        results = {kind: json.loads(clients[kind].communicate(timeout=180)[0].strip().splitlines()[-1])
                   for kind in kinds}
        cpu_ms = (cpu_seconds(bridge_pid) - cpu0) * 1000.0
        publisher.stdin.close()
    finally:
        for proc in clients.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait(10)
    handled = max(len(results[kind]["frames"]) for kind in kinds)  # frames the bridge encoded and sent
    for kind in kinds:
        frames = results[kind]["frames"]
        seqs = set(seq for seq, _, _ in frames)
        latencies = [ms for _, ms, _ in frames]
        span = max([arrived for _, _, arrived in frames] + [published["t0"] + seconds]) - published["t0"]
        report(bench="bridge_image", compression=kind, published=published["published"], received=len(seqs),
               lost=published["published"] - len(seqs), rate_hz=rate_hz,
               delivered_frames_s=round(len(seqs) / span, 1),  # from the first publish to the last arrival
               p50_ms=round(percentile(latencies, 0.5), 1) if latencies else None,
               p99_ms=round(percentile(latencies, 0.99), 1) if latencies else None,
               publisher_late_p99_ms=published["late_p99_ms"],
               bridge_cpu_ms_per_frame=round(cpu_ms / max(1, handled), 1), status=results[kind]["status"],
               error=results[kind]["error"], load_avg_1min=round(os.getloadavg()[0], 1),
               path="ROS publisher process->bridge->3 client processes, 1920x1080 rgb8 sensor_msgs/Image")


VIDEO_SUBSCRIPTION = {"compression": "cbor", "queue_length": 1}  # the console's (web/console/images.js VIDEO)


def video_client(url, topic, quiet_s=10.0, limit_s=150.0):
    """One video line client, a process of its own: subscribes to ``topic`` as the console does,
    prints "ready", then decodes every frame (CBOR, then the JPEG) and records (header.seq, latency
    ms from header.stamp to the decoded picture, decode time) until no frame came for ``quiet_s``
    after the first; prints them as one JSON line."""
    import cv2
    import numpy as np
    from inspection_robot.bridge import cbor

    def record(frame, _arrived):
        msg = cbor.loads(frame)["msg"]
        picture = cv2.imdecode(np.frombuffer(msg["data"], np.uint8), cv2.IMREAD_COLOR)
        if picture is None or picture.shape[:2] != (720, 1280):
            raise ValueError("not a 720p JPEG")
        stamp = msg["header"]["stamp"]
        decoded = time.time()
        return msg["header"]["seq"], round((decoded - stamp["secs"] - stamp["nsecs"] * 1e-9) * 1000.0, 2), decoded

    client = timed_client(url)
    client.send(dict(VIDEO_SUBSCRIPTION, op="subscribe", topic=topic, type="sensor_msgs/CompressedImage"))
    print("ready", flush=True)
    receive_frames(client, record, quiet_s, limit_s)


def slow_video_client(url, topic, slow_ms, quiet_s=10.0, limit_s=150.0):
    """A client that takes ``slow_ms`` over each frame (a slow browser or link), reading its socket
    only between frames (a small receive buffer, as a slow link has): what is stale when it reads
    again is up to the bridge. Records (header.seq, latency ms from header.stamp to the frame read);
    prints "ready" and then one JSON line, as video_client."""
    from inspection_robot.bridge import cbor
    from inspection_robot_testing.bridge_client import SocketClient
    client = SocketClient(int(url.rsplit(":", 1)[1].rstrip("/")), rcvbuf=16384)
    client.send(dict(VIDEO_SUBSCRIPTION, op="subscribe", topic=topic, type="sensor_msgs/CompressedImage"))
    print("ready", flush=True)
    frames, error = [], None
    client.sock.settimeout(limit_s)
    end = time.monotonic() + limit_s
    try:
        for opcode, payload in client.frames():
            if opcode == 0x8 or time.monotonic() > end:
                break
            if opcode == 0x9:  # ping: answer (a masked pong), or the bridge's keep-alive drops the client
                mask = os.urandom(4)
                client.sock.sendall(struct.pack("!BB", 0x8A, 0x80 | len(payload)) + mask
                                    + bytes(b ^ mask[i % 4] for i, b in enumerate(payload)))
                continue
            if opcode != 0x2:
                continue
            msg = cbor.loads(payload)["msg"]
            read = time.time()
            stamp = msg["header"]["stamp"]
            frames.append((msg["header"]["seq"], round((read - stamp["secs"] - stamp["nsecs"] * 1e-9) * 1000.0, 2),
                           read))
            client.sock.settimeout(quiet_s)
            time.sleep(slow_ms / 1000.0)
    except (OSError, EOFError) as exc:  # the quiet timeout ends the run; anything else is reported
        if not isinstance(exc, socket.timeout):
            error = repr(exc)[:200]
    client.sock.close()
    print(json.dumps({"frames": frames, "status": [], "error": error}), flush=True)


def video_line(name, url, bridge_pid, seconds, rate_hz, round_no=0, clients=3, slow_ms=0):
    """The video line against one bridge; reports one line per client and returns the bridge's summary.
    ``slow_ms`` > 0 adds a fourth client that takes that long over each frame (reported apart)."""
    topic = "/bench/video_%s_%d/compressed" % (re.sub(r"[^a-z0-9]", "_", name.lower()), round_no)
    argv = [[sys.executable, os.path.abspath(__file__), "--video-client", topic, url]] * clients
    if slow_ms > 0:
        argv.append([sys.executable, os.path.abspath(__file__), "--slow-video-client", topic, url, str(slow_ms)])
    procs = [subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, universal_newlines=True)
             for args in argv]
    try:
        for proc in procs:
            if proc.stdout.readline().strip() != "ready":
                raise RuntimeError("a video client did not start")
        cpu0, wall0 = (cpu_seconds(bridge_pid) if bridge_pid else None), time.monotonic()
        publisher = subprocess.Popen(
            [sys.executable, os.path.abspath(__file__), "--publish-video", "%s,%g,%g" % (topic, seconds, rate_hz)],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, universal_newlines=True)
        procs.append(publisher)
        published = json.loads(publisher.stdout.readline())   # printed once the last frame went out
        results = [json.loads(proc.communicate(timeout=seconds + 180)[0].strip().splitlines()[-1])
                   for proc in procs[:len(argv)]]
        # the clients end quiet_s after their last frame: the bridge's CPU up to then, idle time included
        cpu_s = cpu_seconds(bridge_pid) - cpu0 if bridge_pid else None
        wall_s = time.monotonic() - wall0
        publisher.stdin.close()
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
                proc.wait(10)
    load = round(os.getloadavg()[0], 1)
    every = []
    for i, result in enumerate(results):
        latencies = [ms for _, ms, _ in result["frames"]]
        slow = i >= clients
        if not slow:
            every.extend(latencies)
        report(bench="bridge_video", bridge=name, round=round_no,
               client="slow: %g ms per frame" % slow_ms if slow else i, published=published["published"],
               received=len(set(seq for seq, _, _ in result["frames"])), rate_hz=rate_hz,
               p50_ms=round(percentile(latencies, 0.5), 1) if latencies else None,
               p99_ms=round(percentile(latencies, 0.99), 1) if latencies else None,
               publisher_late_p99_ms=published["late_p99_ms"], status=result["status"], error=result["error"],
               load_avg_1min=load)
    summary = dict(bridge=name, round=round_no, published=published["published"], clients=clients,
                   received_min=min(len(r["frames"]) for r in results[:clients]),
                   p50_ms=round(percentile(every, 0.5), 1) if every else None,
                   p99_ms=round(percentile(every, 0.99), 1) if every else None,
                   load_avg_1min=load, jpeg_bytes=len(camera_jpeg()))
    if slow_ms > 0:
        latencies = [ms for _, ms, _ in results[clients]["frames"]]
        summary.update(slow_client_received=len(latencies), slow_client_p50_ms=percentile(latencies, 0.5),
                       slow_client_max_ms=max(latencies) if latencies else None)
    if cpu_s is not None:
        # everything the bridge spent from before the first publish until every client went quiet
        summary["bridge_cpu_ms_per_frame"] = round(cpu_s * 1000.0 / max(1, published["published"]), 2)
        summary["bridge_cpu_pct_while_streaming"] = round(100.0 * cpu_s / max(1e-9, min(wall_s, seconds + 1.0)), 1)
    report(bench="bridge_video_summary", path="ROS publisher process->bridge->%d client processes, 1280x720 "
           "JPEG sensor_msgs/CompressedImage, subscribe %s" % (clients, json.dumps(VIDEO_SUBSCRIPTION)), **summary)
    return summary


def rosbridge_0_11(src, deps, workdir, env):
    """argv and environment that run rosbridge_server 0.11.17's rosbridge_websocket from its source tree
    ``src`` (twisted/autobahn, as that release is), with pymongo's bson from ``deps``; rosbridge_msgs is
    generated with genpy into ``workdir`` and rosauth (imported at start, used only with
    ``~authenticate``) stubbed there."""
    shim = os.path.join(workdir, "rosbridge_shim")
    msg_dir = os.path.join(shim, "rosbridge_msgs", "msg")
    os.makedirs(msg_dir, exist_ok=True)
    open(os.path.join(shim, "rosbridge_msgs", "__init__.py"), "w").close()
    std_msgs = subprocess.check_output(["rospack", "find", "std_msgs"], env=env, universal_newlines=True).strip()
    generator = "/usr/lib/genpy/genmsg_py.py"
    for name in ("ConnectedClient", "ConnectedClients"):
        subprocess.check_call([sys.executable, generator, "-p", "rosbridge_msgs",
                               "-Irosbridge_msgs:%s/rosbridge_msgs/msg" % src, "-Istd_msgs:%s/msg" % std_msgs,
                               "-o", msg_dir, "%s/rosbridge_msgs/msg/%s.msg" % (src, name)], env=env)
    subprocess.check_call([sys.executable, generator, "--initpy", "-o", msg_dir, "-p", "rosbridge_msgs"], env=env)
    os.makedirs(os.path.join(shim, "rosauth"), exist_ok=True)
    open(os.path.join(shim, "rosauth", "__init__.py"), "w").close()
    with open(os.path.join(shim, "rosauth", "srv.py"), "w") as stub:
        stub.write("class Authentication(object):\n    pass  # stand-in: ~authenticate stays false\n")
    paths = [shim, deps, os.path.join(src, "rosbridge_library", "src"), os.path.join(src, "rosbridge_server", "src")]
    run_env = dict(env, PYTHONPATH=os.pathsep.join(paths + [env.get("PYTHONPATH", "")]))
    return [sys.executable, os.path.join(src, "rosbridge_server", "scripts", "rosbridge_websocket.py"),
            "__name:=bench_rosbridge", "_port:=0", "_address:=127.0.0.1"], run_env


def wait_port(name, deadline_s=30):
    import rospy
    deadline = time.monotonic() + deadline_s
    while not rospy.has_param("/%s/actual_port" % name):
        if time.monotonic() > deadline:
            raise RuntimeError("%s did not start" % name)
        time.sleep(0.1)
    return "ws://127.0.0.1:%d" % rospy.get_param("/%s/actual_port" % name)


def latency_line(name, bridge, echo, **extra):
    report(bench=name, p50_ms=round(percentile(bridge, 0.5), 3), p99_ms=round(percentile(bridge, 0.99), 3),
           n=len(bridge), echo_p50_ms=round(percentile(echo, 0.5), 3), echo_p99_ms=round(percentile(echo, 0.99), 3),
           ratio_p50=round(percentile(bridge, 0.5) / percentile(echo, 0.5), 2), **extra)


def classic(bridge_url, counter):
    import rospy
    from std_msgs.msg import String

    from inspection_robot_testing.bridge_client import RawClient
    echo_port = start_echo_server()
    echo_url = "ws://127.0.0.1:%d" % echo_port

    bridge, echo = RawClient(bridge_url), RawClient(echo_url)
    latency_line("bridge_rtt", raw_rtt(bridge, "/bench/echo", N_RTT), raw_rtt(echo, "/bench/echo", N_RTT),
                 client="raw_tornado", path="client->bridge->ROS->bridge->client")
    drain(bridge)
    bridge_loop = raw_throughput_loopback(bridge, "/bench/echo", N_THROUGHPUT)
    echo_loop = raw_throughput_loopback(echo, "/bench/echo", N_THROUGHPUT)
    report(bench="bridge_throughput_loopback", msgs_s=round(bridge_loop), n=N_THROUGHPUT,
           echo_msgs_s=round(echo_loop), ratio=round(bridge_loop / echo_loop, 2), window=WINDOW,
           path="client->bridge->ROS->bridge->client")
    bridge.send({"op": "unsubscribe", "topic": "/bench/echo"})
    drain(bridge)

    # one way, client -> ROS (counted by a ROS subscriber)
    bridge.send({"op": "advertise", "topic": "/bench/to_ros", "type": "std_msgs/String"})
    deadline = time.monotonic() + 10
    while counter["n"] == 0 and time.monotonic() < deadline:
        bridge.send({"op": "publish", "topic": "/bench/to_ros", "msg": {"data": "warmup"}})
        time.sleep(0.05)
    start_count = counter["n"]
    t0 = time.perf_counter()
    for i in range(N_THROUGHPUT):
        bridge.send('{"op":"publish","topic":"/bench/to_ros","msg":{"data":"%d"}}' % i)
        if i % WINDOW == WINDOW - 1:
            while counter["n"] - start_count < i - WINDOW and time.perf_counter() - t0 < 30:
                time.sleep(0.0005)
    while counter["n"] - start_count < N_THROUGHPUT and time.perf_counter() - t0 < 30:
        time.sleep(0.0005)
    to_ros = (counter["n"] - start_count) / (time.perf_counter() - t0)
    report(bench="bridge_throughput_to_ros", msgs_s=round(to_ros), n=N_THROUGHPUT,
           received=counter["n"] - start_count, echo_msgs_s=round(echo_loop), ratio=round(to_ros / echo_loop, 2),
           path="client->bridge->ROS subscriber")

    # one way, ROS -> client
    pub = rospy.Publisher("/bench/from_ros", String, queue_size=10000)
    bridge.send({"op": "subscribe", "topic": "/bench/from_ros", "type": "std_msgs/String"})
    deadline = time.monotonic() + 10
    while True:  # until a warm-up message made it through
        pub.publish(String(data="warmup"))
        try:
            bridge.recv(0.1)
            break
        except queue.Empty:
            if time.monotonic() > deadline:
                raise
    drain(bridge)
    received = 0
    t0 = time.perf_counter()
    for i in range(N_THROUGHPUT):
        pub.publish(String(data=str(i)))
        if i % 50 == 49:  # rospy's publisher must not outrun the bridge's ROS queue
            while received < i - WINDOW:
                bridge.recv(5)
                received += 1
    try:
        while received < N_THROUGHPUT:
            bridge.recv(1.0)
            received += 1
    except queue.Empty:
        pass
    from_ros = received / (time.perf_counter() - t0)
    report(bench="bridge_throughput_from_ros", msgs_s=round(from_ros), n=N_THROUGHPUT, received=received,
           echo_msgs_s=round(echo_loop), ratio=round(from_ros / echo_loop, 2), path="ROS publisher->bridge->client")
    bridge.send({"op": "unsubscribe", "topic": "/bench/from_ros"})
    drain(bridge)

    args = {"sender": "bench", "trans_id": 1, "cmd": "noop", "data": "x"}
    echo_calls = raw_calls(echo, "/bench_control", args, N_CALLS)
    latency_line("bridge_call_service", raw_calls(bridge, "/bench_control", args, N_CALLS), echo_calls,
                 service="/bench_control (inspection_robot/ControlService, rospy server)")
    latency_line("bridge_call_service", raw_calls(bridge, "/rosapi/get_time", {}, N_CALLS), echo_calls,
                 service="/rosapi/get_time (in-process)")
    bridge.close()
    echo.close()

    latency_line("bridge_rtt", roslibpy_rtt(int(bridge_url.rsplit(":", 1)[1]), "/bench/roslibpy", 300),
                 roslibpy_rtt(echo_port, "/bench/roslibpy", 300), client="roslibpy")


def compare(bridges, rounds, n=10000):
    """Echo round trip and an unpaced burst against every bridge, rounds in alternating order."""
    from inspection_robot_testing.bridge_client import RawClient
    runs, failed = {}, False
    for round_no in range(rounds):
        for name, url, pid in (bridges if round_no % 2 == 0 else bridges[::-1]):
            client = RawClient(url)
            rtt = raw_rtt(client, "/bench/compare_echo%d" % round_no, N_RTT)
            client.close()
            rate, lost, disordered, delivered, _statuses, cpu_us = burst(url, "/bench/compare%d" % round_no, n, pid)
            figures = {"echo_p50_ms": percentile(rtt, 0.5), "echo_p99_ms": percentile(rtt, 0.99),
                       "burst_msgs_s": rate}
            runs.setdefault(name, []).append(figures)
            report(bench="bridge_compare", bridge=name, round=round_no, echo_n=len(rtt),
                   echo_p50_ms=round(figures["echo_p50_ms"], 3), echo_p99_ms=round(figures["echo_p99_ms"], 3),
                   burst_n=n, delivered=delivered, lost=lost, out_of_order=disordered, burst_msgs_s=round(rate),
                   bridge_cpu_us_per_msg=None if cpu_us is None else round(cpu_us, 1),
                   load_avg_1min=round(os.getloadavg()[0], 1))
            failed = failed or (name == "ours" and (lost > 0 or disordered > 0))
    ours = runs["ours"]

    def median(rows, key):
        return percentile([r[key] for r in rows], 0.5)
    for name, theirs in runs.items():
        if name != "ours":
            report(bench="bridge_compare_ratio", other=name, rounds=rounds,
                   burst_ours_over_theirs=round(median(ours, "burst_msgs_s") / median(theirs, "burst_msgs_s"), 2),
                   echo_p50_theirs_over_ours=round(median(theirs, "echo_p50_ms") / median(ours, "echo_p50_ms"), 2),
                   echo_p99_theirs_over_ours=round(median(theirs, "echo_p99_ms") / median(ours, "echo_p99_ms"), 2))
    return failed


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--only", default="classic,burst,image",
                        help="comma-separated: classic, burst, image, video, compare")
    parser.add_argument("--bursts", default="10000,100000", help="comma-separated burst sizes")
    parser.add_argument("--bridge-log", help="file for the bridge's output (default: discarded)")
    parser.add_argument("--image-seconds", type=float, default=10.0, help="length of the image line (s)")
    parser.add_argument("--publish-images", help=argparse.SUPPRESS)  # "seconds,rate": the image publisher process
    parser.add_argument("--image-client", nargs=2, help=argparse.SUPPRESS)  # compression url: one image client
    parser.add_argument("--video-rate", type=float, default=15.0, help="Hz of the video line (10-25)")
    parser.add_argument("--slow-ms", type=float, default=0.0,
                        help="video line: a fourth client taking this long (ms) over each frame")
    parser.add_argument("--slow-video-client", nargs=3, help=argparse.SUPPRESS)  # topic url ms: the slow client
    parser.add_argument("--video-rounds", type=int, default=3, help="video line rounds, bridges in alternating order")
    parser.add_argument("--url", action="append", default=[],
                        help="another rosbridge to run the video and compare lines against")
    parser.add_argument("--rosbridge-src",
                        help="rosbridge_suite 0.11.17 source tree: the video and compare lines run on it too")
    parser.add_argument("--compare-rounds", type=int, default=3, help="compare line rounds, alternating order")
    parser.add_argument("--rosbridge-deps", default="", help="folder with pymongo's bson for --rosbridge-src")
    parser.add_argument("--publish-video", help=argparse.SUPPRESS)  # "topic,seconds,rate": the video publisher
    parser.add_argument("--video-client", nargs=2, help=argparse.SUPPRESS)  # topic url: one video client
    args = parser.parse_args()
    if args.video_client:
        video_client(args.video_client[1], args.video_client[0])
        return
    if args.slow_video_client:
        slow_video_client(args.slow_video_client[1], args.slow_video_client[0], float(args.slow_video_client[2]))
        return
    if args.publish_video:
        topic, seconds, rate_hz = args.publish_video.split(",")
        publish_video(topic, float(seconds), float(rate_hz), 1)
        return
    if args.image_client:
        image_client(args.image_client[1], args.image_client[0])
        return
    if args.publish_images:
        seconds, rate_hz = (float(x) for x in args.publish_images.split(","))
        publish_images(seconds, rate_hz, 1)
        return
    only = set(args.only.split(","))
    workdir = tempfile.mkdtemp(prefix="bench_bridge_")
    failed = False
    bridge_log = open(args.bridge_log, "w") if args.bridge_log else subprocess.DEVNULL
    procs = [start_roscore()]
    env = dict(os.environ)
    try:
        import rospy
        from std_msgs.msg import String

        from inspection_robot.srv import ControlService, ControlServiceResponse

        procs.append(subprocess.Popen(
            [sys.executable, "-c", "from inspection_robot.nodes.rosbridge_websocket import main; main()",
             "__name:=bench_bridge", "_port:=0", "_address:=127.0.0.1"],
            stdout=bridge_log, stderr=subprocess.STDOUT, env=env))
        rospy.init_node("bench_bridge_client", disable_signals=True)
        rospy.Service("/bench_control", ControlService,
                      lambda req: ControlServiceResponse(trans_id=req.trans_id, ack="success", data=req.data))
        counter = {"n": 0}
        rospy.Subscriber("/bench/to_ros", String, lambda m: counter.__setitem__("n", counter["n"] + 1),
                         queue_size=10000)
        bridge_url = wait_port("bench_bridge")
        ours_pid = procs[-1].pid
        if "classic" in only:
            classic(bridge_url, counter)
        if "burst" in only:
            for n in [int(x) for x in args.bursts.split(",") if x]:
                rate, lost, disordered, delivered, statuses, cpu_us = burst(bridge_url, "/bench/burst%d" % n, n,
                                                                            ours_pid)
                report(bench="bridge_burst", n=n, delivered=delivered, lost=lost, out_of_order=disordered,
                       delivered_msgs_s=round(rate), bridge_cpu_us_per_msg=round(cpu_us, 1),
                       cpu_bound_msgs_s=round(1e6 / cpu_us), status=statuses[:3], client="raw_tornado",
                       path="client->bridge->ROS->bridge->client, unpaced",
                       load_avg_1min=round(os.getloadavg()[0], 1))
                failed = failed or lost > 0 or disordered > 0
        if "image" in only:
            image_line(bridge_url, ours_pid, args.image_seconds)
        bridges = [("ours", bridge_url, ours_pid)]   # every bridge the video and compare lines run against
        if args.rosbridge_src and only & {"video", "compare"}:
            argv, rb_env = rosbridge_0_11(os.path.abspath(args.rosbridge_src), os.path.abspath(args.rosbridge_deps),
                                          workdir, env)
            procs.append(subprocess.Popen(argv, stdout=bridge_log, stderr=subprocess.STDOUT, env=rb_env))
            bridges.append(("rosbridge 0.11.17", wait_port("bench_rosbridge"), procs[-1].pid))
        bridges.extend((url, url, None) for url in args.url)
        if "compare" in only:
            failed = compare(bridges, args.compare_rounds) or failed
        if "video" in only:
            report(bench="bridge_video_machine", uptime=subprocess.check_output(["uptime"], universal_newlines=True)
                   .strip(), cores=os.cpu_count())
            runs = {}  # bridge -> its summaries; rounds alternate the order (the machine's load drifts)
            for round_no in range(args.video_rounds):
                for name, url, pid in (bridges if round_no % 2 == 0 else bridges[::-1]):
                    runs.setdefault(name, []).append(video_line(name, url, pid, args.image_seconds, args.video_rate,
                                                                round_no, slow_ms=args.slow_ms))
            ours = runs["ours"]
            for other_name, other in runs.items():
                if other_name == "ours":
                    continue
                ratio = {}
                for key in ("p50_ms", "p99_ms", "bridge_cpu_ms_per_frame"):
                    mine, theirs = [r.get(key) for r in ours], [r.get(key) for r in other]
                    if all(mine) and all(theirs):
                        ratio[key] = round(percentile(theirs, 0.5) / percentile(mine, 0.5), 2)
                report(bench="bridge_video_ratio", other=other_name, other_over_ours_median_of_rounds=ratio,
                       p99_ms={"ours": [r["p99_ms"] for r in ours], other_name: [r["p99_ms"] for r in other]},
                       received_min={"ours": [r["received_min"] for r in ours],
                                     other_name: [r["received_min"] for r in other]},
                       published=ours[0]["published"], load_avg_1min=round(os.getloadavg()[0], 1))
    finally:
        shutil.rmtree(workdir, ignore_errors=True)
        for proc in reversed(procs):
            proc.terminate()
        for proc in reversed(procs):
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
    os._exit(1 if failed else 0)  # roslibpy's twisted reactor thread cannot be restarted or joined cleanly


if __name__ == "__main__":
    main()
