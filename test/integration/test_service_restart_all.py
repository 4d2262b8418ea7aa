#!/usr/bin/env python3
"""rostest: every service node of the simulated robot SIGKILLed and respawned, in turn, while a
websocket client calls its service without pause (issue #44 item 1; service_restart.test does
file_server alone, with rosnode kill too, and a command that writes).

For each service the backend surface offers (bridge.surface.ROBOT_SERVICES): no call fails but one
in flight while the node is away (from the kill to its service's new registration at the master),
each such failure says why (the node is restarting, or it closed the connection before answering),
and calls made after the respawn are answered by the node. A service with a read-only command
(interface.READ_ONLY_COMMANDS) is called with it; the others with a command no table has, which the
node answers itself ("unknown command"): the call reached it."""
import json
import os
import signal
import threading
import time
import unittest
import xmlrpc.client

import rosgraph
import rospy
import rostest

from inspection_robot.bridge.surface import ROBOT_SERVICES
from inspection_robot.interface import READ_ONLY_COMMANDS
from inspection_robot_testing.bridge_client import RawClient
from rostest_helpers import wait_for

REASONS = ("is not available: its node is restarting or down", "closed the connection before answering")
PROBE = "probe_after_restart"   # no command table has it: the node answers "unknown command"
DATA = {"file_control": json.dumps({"path": "tasks"}), "calibration_control": json.dumps({"preset": "none"}),
        "terrace_control": "", "arm_control": ""}
RETRY_PAUSE = 0.02   # s after a failed call, as a backend asking again


class ServiceRestartAllTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_service_restart_all")
        cls.master = rosgraph.Master("/test_service_restart_all")
        cls.port = int(wait_for(lambda: rospy.get_param("/rosbridge_websocket/actual_port", None), 60.0,
                                "bridge port"))
        os.makedirs(os.path.join(rospy.get_param("/data_root"), "tasks"), exist_ok=True)

    def lookup(self, service):
        try:
            return self.master.lookupService(service)
        except rosgraph.MasterException:
            return None

    def node_of(self, service):
        _pubs, _subs, services = self.master.getSystemState()
        return next(nodes[0] for name, nodes in services if name == service)

    def restart_under_calls(self, service):
        """(calls, killed, back) around one SIGKILL of ``service``'s node; calls are (start, end, answered, why)."""
        name = service.lstrip("/")
        cmd = READ_ONLY_COMMANDS.get(name, (PROBE,))[0]
        data = DATA.get(name, "")
        client = RawClient("ws://127.0.0.1:%d" % self.port, timeout=30.0)
        self.addCleanup(client.close)
        calls, stop = [], threading.Event()

        def call_continuously():
            n = 0
            while not stop.is_set():
                n += 1
                call_id = "%s%d" % (name, n)
                start = time.monotonic()
                client.send({"op": "call_service", "id": call_id, "service": service,
                             "type": "inspection_robot/ControlService",
                             "args": {"sender": "server", "trans_id": n, "cmd": cmd, "data": data}})
                reply = client.recv_message(lambda m: m.get("op") == "service_response" and m.get("id") == call_id,
                                            timeout=30.0)
                calls.append((start, time.monotonic(), bool(reply.get("result")), str(reply.get("values"))))
                if not reply.get("result"):
                    time.sleep(RETRY_PAUSE)
        wait_for(lambda: self.lookup(service), 60.0, service + " registered")
        node = self.node_of(service)
        before = self.lookup(service)
        pid = xmlrpc.client.ServerProxy(self.master.lookupNode(node)).getPid("/test")[2]
        streaming = threading.Thread(target=call_continuously, name="calls_" + name)
        streaming.daemon = True
        streaming.start()
        try:
            wait_for(lambda: sum(1 for c in calls if c[2]) >= 5, 60.0, "%s answering before the kill" % service)
            killed = time.monotonic()
            os.kill(pid, signal.SIGKILL)
            wait_for(lambda: self.lookup(service) not in (None, before), 60.0, "%s registered again" % service,
                     period=0.02)
            back = time.monotonic()
            count = len(calls)
            wait_for(lambda: len(calls) >= count + 5, 60.0, "%s called after its node came back" % service)
        finally:
            stop.set()
            streaming.join(35.0)
        return calls, killed, back

    def test_every_service_node_answers_after_its_respawn(self):
        summary = []
        for service in ["/" + s for s in ROBOT_SERVICES]:
            calls, killed, back = self.restart_under_calls(service)
            failed = [c for c in calls if not c[2]]
            for start, end, _answered, why in failed:
                self.assertTrue(start <= back and end >= killed,
                                "%s: a call failed %.2f s after the node came back: %s" % (service, start - back, why))
                self.assertTrue(any(reason in why for reason in REASONS), "%s: unclear failure %r" % (service, why))
            after = [c for c in calls if c[0] > back]
            self.assertTrue(after and after[0][2], "%s: the first call after the respawn failed: %r"
                            % (service, after[0][3] if after else "no call"))
            summary.append("%s: %d calls, %d failed while away (%.1f s)"
                           % (service, len(calls), len(failed), back - killed))
        print("\n".join(summary))


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_service_restart_all", ServiceRestartAllTest)
