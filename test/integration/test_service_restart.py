#!/usr/bin/env python3
"""rostest: file_server killed and respawned while a websocket client calls it without pause.

No call fails but while the node is away (from the kill to its new registration at the master),
and those fail with the reason naming the service; the first call after the respawn answers, also
for a command that changes something (the dead connection is seen closed before the request is
written). Before issue #44 the first call on the bridge's kept connection failed with rospy's
``transport error completing service call: unable to receive data from sender``."""
import json
import os
import signal
import threading
import time
import unittest
import xmlrpc.client

import rosgraph
import rosnode
import rospy
import rostest

from inspection_robot_testing.bridge_client import RawClient
from rostest_helpers import wait_for

NODE = "/file_server"
AWAY = "is not available: its node is restarting or down"
CALLS = (("/file_control", "stat", {"path": "tasks"}),
         ("/calibration_control", "get", {"preset": "presets/none/20260101_120000"}))


class Caller(object):
    """A websocket client's call_service, answered (the node replied, whatever its ack) or failed."""

    def __init__(self, port):
        self.client = RawClient("ws://127.0.0.1:%d" % port)
        self.n = 0

    def call(self, service, cmd, data, timeout=30.0):
        self.n += 1
        call_id = "c%d" % self.n
        self.client.send({"op": "call_service", "id": call_id, "service": service,
                          "type": "inspection_robot/ControlService", "args": {"cmd": cmd, "data": json.dumps(data)}})
        reply = self.client.recv_message(lambda m: m.get("op") == "service_response" and m.get("id") == call_id,
                                         timeout=timeout)
        return bool(reply.get("result")), reply.get("values")


class ServiceRestartTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_service_restart")
        os.makedirs(os.path.join(rospy.get_param("/data_root"), "tasks"), exist_ok=True)
        cls.master = rosgraph.Master("/test_service_restart")
        port = int(wait_for(lambda: rospy.get_param("/rosbridge_websocket/actual_port", None), 60.0, "bridge port"))
        cls.caller = Caller(port)
        cls.stream = Caller(port)
        for service, cmd, data in CALLS:
            wait_for(lambda: cls.caller.call(service, cmd, data)[0], 60.0, "%s answering" % service, period=0.1)

    def uri(self, service="/file_control"):
        try:
            return self.master.lookupService(service)
        except rosgraph.MasterException:
            return None

    def kill(self, how):
        """Kill file_server; returns (time of the kill, time its respawn was seen registered)."""
        before = self.uri()
        self.assertIsNotNone(before)
        if how == "rosnode":
            killed = time.monotonic()
            rosnode.kill_nodes([NODE])
        else:
            pid = xmlrpc.client.ServerProxy(self.master.lookupNode(NODE)).getPid("/test")[2]
            killed = time.monotonic()
            os.kill(pid, signal.SIGKILL)
        wait_for(lambda: self.uri() not in (None, before) and self.uri("/calibration_control") not in (None, before),
                 90.0, "file_server's respawn registered", period=0.005)
        return killed, time.monotonic()

    def test_1_the_first_call_after_a_respawn_answers(self):
        for how in ("sigkill", "rosnode"):
            for service, cmd, data in CALLS:
                self.assertTrue(self.caller.call(service, cmd, data)[0])   # the bridge keeps these connections
            self.kill(how)
            ok, values = self.caller.call("/calibration_control", "clear_draft", {"preset": "presets/none/x"})
            self.assertTrue(ok, "first call after %s: %s" % (how, values))   # a writing command: not sent before
            for service, cmd, data in CALLS:
                ok, values = self.caller.call(service, cmd, data)
                self.assertTrue(ok, "%s after %s: %s" % (service, how, values))

    def test_2_under_a_stream_of_calls_only_the_absence_fails_and_says_why(self):
        calls, stop = [], threading.Event()

        def call_continuously():
            k = 0
            while not stop.is_set():
                service, cmd, data = CALLS[k % len(CALLS)]
                k += 1
                start = time.monotonic()
                ok, values = self.stream.call(service, cmd, data)
                calls.append((start, time.monotonic(), service, ok, values))
        streamer = threading.Thread(target=call_continuously, daemon=True)
        streamer.start()
        absences = []
        for how in ("rosnode", "sigkill", "rosnode", "sigkill"):
            wait_for(lambda: len(calls) > 20 and calls[-1][3], 30.0, "calls answered before the kill")
            absences.append(self.kill(how))
            seen = len(calls)
            wait_for(lambda: len(calls) > seen + 20, 30.0, "calls after the respawn")
        stop.set()
        streamer.join(30.0)
        failed = [c for c in calls if not c[3]]
        for start, end, service, ok, values in failed:
            self.assertTrue(any(start <= back and end >= killed for killed, back in absences),
                            "%s failed while file_server was there: %s" % (service, values))
            self.assertIn("service %s %s" % (service, AWAY), values)
        for killed, back in absences:
            after = [c for c in calls if c[0] > back]
            self.assertTrue(after and after[0][3], "the first call after the respawn: %s" % (after[:1],))
        answered = [c for c in calls if c[3]]
        self.assertGreater(len(answered), 80, "calls answered around 4 restarts (%d failed)" % len(failed))


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_service_restart", ServiceRestartTest)
