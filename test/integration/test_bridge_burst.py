#!/usr/bin/env python3
"""rostest: sequence-numbered bursts through the backend link lose nothing; a stuck client is bounded and told.

Clients publish unpaced bursts (10,000 and 100,000 messages) through the bridge to ROS and back;
every client that reads gets every message of every topic it subscribed to, in order. A client
that never reads holds at most its budget in the bridge, is told what was dropped (status
warning, diagnostics) and is disconnected with close code 1008 and a reason.
"""
import json
import queue
import struct
import threading
import time
import unittest

import roslibpy
import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray
from std_msgs.msg import String

from inspection_robot_testing.bridge_client import CLOSED, RawClient, SocketClient
from rostest_helpers import wait_for

PAD = "x" * 24
DIAGNOSTIC = "rosbridge_websocket: clients"


def connect_loopback(client, topic, seen):
    """Advertise and subscribe on ``topic``; publish until one message came back through ROS."""
    client.send({"op": "subscribe", "topic": topic, "type": "std_msgs/String"})
    client.send({"op": "advertise", "topic": topic, "type": "std_msgs/String"})
    warm_until(client, topic, heard_by(client, topic), "loopback on %s" % topic)
    drain(client, seen)


def heard_by(listener, topic):
    """A probe for warm_until: did ``listener`` get a message on ``topic`` within the timeout?"""
    def probe(timeout):
        try:
            listener.recv_message(lambda m: m.get("op") == "publish" and m.get("topic") == topic, timeout=timeout)
            return True
        except queue.Empty:
            return False
    return probe


def received_into(messages):
    """A probe for warm_until: did anything arrive in ``messages`` (filled by a callback) in time?"""
    def probe(timeout):
        deadline = time.monotonic() + timeout
        while not messages and time.monotonic() < deadline:
            time.sleep(0.01)
        return bool(messages)
    return probe


def warm_until(publisher, topic, probe, what):
    """Publish "warmup" on ``topic`` until ``probe(timeout)`` hears it.

    Frames of two connections are not ordered: a subscribe sent on one may be processed after a
    publish sent on another, so one warm-up message can pass before the listener is in place.
    """
    def round_trip():
        publisher.send({"op": "publish", "topic": topic, "msg": {"data": "warmup"}})
        return probe(0.3)
    wait_for(round_trip, 15.0, what, period=0.0)


def drain(client, seen):
    try:
        while True:
            frame = client.recv(0.3)
            seen.append(frame)
    except queue.Empty:
        pass


def publish_burst(client, topic, n):
    client.send_many('{"op":"publish","topic":"%s","msg":{"data":"%08d%s"}}' % (topic, i, PAD) for i in range(n))


def collect(client, counts, timeout=60.0):
    """Sequence numbers per topic until ``counts`` (topic -> n) are complete or nothing came for 5 s."""
    seqs = dict((topic, []) for topic in counts)
    while any(len(seqs[t]) < counts[t] for t in counts):
        try:
            frame = client.recv(5.0)
        except queue.Empty:
            break
        if frame is CLOSED:
            break
        message = json.loads(frame)
        if message["op"] == "publish" and message["msg"]["data"] != "warmup":
            seqs[message["topic"]].append(int(message["msg"]["data"][:8]))
    return seqs


class Diagnostics(object):
    """The bridge's latest diagnostic status values, by key."""

    def __init__(self):
        self.values = {}
        self._sub = rospy.Subscriber("/diagnostics", DiagnosticArray, self._on, queue_size=10)

    def _on(self, msg):
        for status in msg.status:
            if status.name.endswith(DIAGNOSTIC):
                self.values = dict((kv.key, kv.value) for kv in status.values)


class BridgeBurstTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_bridge_burst")
        cls.port = int(wait_for(lambda: rospy.get_param("/rosbridge_websocket/actual_port", None), 15.0, "port"))
        cls.url = "ws://127.0.0.1:%d" % cls.port
        cls.diagnostics = Diagnostics()

    def raw(self):
        client = RawClient(self.url)
        self.addCleanup(client.close)
        return client

    def test_10k_bursts_on_two_topics_reach_every_client_in_order(self):
        n = 10000
        publishers = {"/burst/a": self.raw(), "/burst/b": self.raw()}
        for topic, client in publishers.items():
            connect_loopback(client, topic, [])
        listener = self.raw()
        for topic in publishers:
            listener.send({"op": "subscribe", "topic": topic, "type": "std_msgs/String"})
        ros = roslibpy.Ros("127.0.0.1", self.port)  # an unmodified roslibpy client as a third reader
        ros.run(timeout=10)
        self.addCleanup(ros.terminate)
        via_roslibpy = []
        roslibpy.Topic(ros, "/burst/a", "std_msgs/String").subscribe(lambda m: via_roslibpy.append(m["data"]))
        for topic, client in publishers.items():  # every reader hears both topics before the bursts start
            warm_until(client, topic, heard_by(listener, topic), "listener on %s" % topic)
        warm_until(publishers["/burst/a"], "/burst/a", received_into(via_roslibpy), "roslibpy on /burst/a")
        drain(listener, [])
        for client in publishers.values():
            drain(client, [])
        for topic, client in publishers.items():  # both bursts at once
            publish_burst(client, topic, n)
        results = [collect(client, {topic: n}) for topic, client in publishers.items()]
        results.append(collect(listener, dict((topic, n) for topic in publishers)))
        for seqs in results:
            for topic, got in seqs.items():
                self.assertEqual(got, list(range(n)), "%s: %d of %d, first gap near %s" % (
                    topic, len(got), n, next((i for i, s in enumerate(got) if s != i), None)))
        wait_for(lambda: len([d for d in via_roslibpy if d != "warmup"]) >= n, 30.0, "roslibpy's messages")
        self.assertEqual([int(d[:8]) for d in via_roslibpy if d != "warmup"], list(range(n)))

    def test_publisher_leaving_mid_burst_leaves_an_in_order_prefix_and_the_bridge_serving(self):
        n, topic = 10000, "/burst/cut"
        publisher = RawClient(self.url)
        connect_loopback(publisher, topic, [])
        listener = self.raw()
        listener.send({"op": "subscribe", "topic": topic, "type": "std_msgs/String"})
        in_ros = []  # what reached ROS, seen by a plain rospy subscriber
        subscriber = rospy.Subscriber(topic, String, lambda m: in_ros.append(m.data), queue_size=None)
        self.addCleanup(subscriber.unregister)
        warm_until(publisher, topic, heard_by(listener, topic), "listener on %s" % topic)
        warm_until(publisher, topic, received_into(in_ros), "rospy on %s" % topic)
        drain(listener, [])
        publish_burst(publisher, topic, n)
        # gone mid-burst: once the listener has the burst's first message, while the rest is in flight
        first = listener.recv_message(lambda m: m.get("op") == "publish" and m["msg"]["data"] != "warmup",
                                      timeout=60.0)
        publisher.close()
        got = [int(first["msg"]["data"][:8])] + collect(listener, {topic: n - 1}, timeout=60.0)[topic]
        ros_seqs = [int(d[:8]) for d in in_ros if d != "warmup"]
        # whatever arrived (the first at least): from 0, in order, no gap, at both ends (each ROS
        # subscriber connection may lose a different tail when the publisher goes)
        self.assertEqual(got, list(range(len(got))))
        self.assertEqual(ros_seqs, list(range(len(ros_seqs))))
        listener.send({"op": "call_service", "id": "alive", "service": "/rosapi/get_time"})
        self.assertTrue(listener.recv_message(lambda m: m.get("id") == "alive", timeout=10.0)["result"])

    def test_100k_burst_while_a_client_never_reads(self):
        n, topic = 100000, "/burst/big"
        stuck = SocketClient(self.port, rcvbuf=4096)
        self.addCleanup(stuck.sock.close)
        stuck.send({"op": "subscribe", "topic": topic, "type": "std_msgs/String"})
        publisher, listener = self.raw(), self.raw()
        connect_loopback(publisher, topic, [])
        listener.send({"op": "subscribe", "topic": topic, "type": "std_msgs/String"})
        warm_until(publisher, topic, heard_by(listener, topic), "listener on %s" % topic)
        drain(publisher, [])
        drain(listener, [])
        closed = threading.Event()
        stuck_frames = []

        def read_stuck():
            # reads only once the bridge reports that it closed a client over budget
            wait_for(lambda: int(self.diagnostics.values.get("closed_over_budget", 0)) >= 1, 120.0,
                     "an over-budget disconnect")
            for opcode, payload in stuck.frames():
                stuck_frames.append((opcode, payload))
            closed.set()
        reader = threading.Thread(target=read_stuck)
        reader.daemon = True
        reader.start()
        publish_burst(publisher, topic, n)
        for client in (publisher, listener):
            got = collect(client, {topic: n}, timeout=200.0)[topic]
            self.assertEqual(len(got), n)
            self.assertEqual(got, list(range(n)))
        self.assertTrue(closed.wait(30.0), "the stuck client got no close frame")
        messages = [json.loads(payload.decode()) for opcode, payload in stuck_frames if opcode == 0x1]
        seqs = [int(m["msg"]["data"][:8]) for m in messages if m["op"] == "publish" and m["msg"]["data"] != "warmup"]
        warnings = [m["msg"] for m in messages if m["op"] == "status" and m["level"] == "warning"]
        code, reason = struct.unpack("!H", stuck_frames[-1][1][:2])[0], stuck_frames[-1][1][2:].decode()
        self.assertEqual(seqs, sorted(set(seqs)))  # in order, nothing twice
        self.assertLess(len(seqs), n)
        self.assertEqual(code, 1008)
        self.assertTrue(reason.startswith("send queue over budget (2000000 bytes) for 1 s: client reads too slowly; "),
                        reason)
        self.assertTrue(warnings and warnings[0].startswith("subscribe: dropped ") and topic in warnings[0], warnings)
        self.assertGreater(int(self.diagnostics.values.get("dropped %s" % topic, 0)), 0)


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_bridge_burst", BridgeBurstTest)
