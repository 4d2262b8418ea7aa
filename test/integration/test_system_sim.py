#!/usr/bin/env python3
"""rostest: sim.launch end to end, seen from the backend (roslibpy over the websocket only).

Heartbeat online -> acquire backend mode -> drive -> command timeout stops -> PTZ, camera, voice
through their twins -> a short move_action goal -> heartbeat loss stops and returns to task mode.
Then what a careless backend sends (junk velocities, huge numbers, bad JSON, data where none is
taken): each gets a clear ``failed``, nothing moves, no node restarts; query_status is spoken.
rospy is used only to read the bridge's port, the simulator's true pose and the nodes' pids.
"""
import importlib.util
import json
import math
import os
import threading
import time
import unittest
from xmlrpc.client import ServerProxy

import roslibpy
import rosgraph
import roslibpy.actionlib
import rosnode
import rospy
import rostest
from geometry_msgs.msg import PoseWithCovarianceStamped

from rostest_helpers import Latest, rosapi_names, wait_for

_SPEC = importlib.util.spec_from_file_location("runtime_graph", os.path.join(
    os.path.dirname(os.path.abspath(__file__)), "..", "..", "scripts", "runtime_graph.py"))
runtime_graph = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(runtime_graph)


class Heartbeat(object):
    """Publishes server_status every ``period`` s through the bridge until stopped."""

    def __init__(self, ros, period=0.3):
        self._topic = roslibpy.Topic(ros, "/server_status", "inspection_robot/GeneralTopic")
        self._period = period
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run)
        self._thread.daemon = True

    def start(self):
        self._thread.start()

    def stop(self):
        self._stop.set()
        self._thread.join(2.0)

    def _run(self):
        while True:  # the first one at once: the robot is online because of this heartbeat, not an earlier one
            self._topic.publish(roslibpy.Message({"sender": "server", "data": "alive"}))
            if self._stop.wait(self._period):
                return


class SystemSimTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_system_sim")
        port = int(wait_for(lambda: rospy.get_param("/rosbridge_websocket/actual_port", None), 60.0, "bridge port"))
        cls.ros = roslibpy.Ros("127.0.0.1", port)
        cls.ros.run(timeout=20)
        # every node starts at once on a shared machine: the backend waits until the services it
        # calls are offered (a camera node rendering its world can take many seconds to start)
        for name in ("/terrace_control", "/camera_control", "/infrared_control"):
            wait_for(lambda: name in rosapi_names(cls.ros.get_services), 120.0, "service " + name)
        cls.true_pose = Latest("/sim/true_pose", PoseWithCovarianceStamped)
        cls.status = []
        cls.robot_status = roslibpy.Topic(cls.ros, "/robot_status", "inspection_robot/RobotStatus")
        cls.robot_status.subscribe(cls.status.append)
        cls.acks = []
        for name in ("/voice_ack", "/control_ack"):
            roslibpy.Topic(cls.ros, name, "inspection_robot/GeneralAck").subscribe(cls.acks.append)
        cls.mode_cmd = roslibpy.Topic(cls.ros, "/mode_cmd", "inspection_robot/GeneralCmd")
        cls.move_cmd = roslibpy.Topic(cls.ros, "/move_cmd", "inspection_robot/MoveCmd")
        cls.voice_cmd = roslibpy.Topic(cls.ros, "/voice_cmd", "inspection_robot/VoiceCmd")
        cls.acks_by_topic = {}
        for name in ("/virtual_obstacle_ack", "/voice_ack", "/mode_ack"):
            cls.acks_by_topic[name] = []
            roslibpy.Topic(cls.ros, name, "inspection_robot/GeneralAck").subscribe(cls.acks_by_topic[name].append)

    @classmethod
    def tearDownClass(cls):
        cls.ros.terminate()

    def latest_status(self):
        return self.status[-1] if self.status else None

    def wait_status(self, predicate, timeout, what):
        return wait_for(lambda: self.latest_status() is not None and predicate(self.latest_status())
                        and self.latest_status(), timeout, what)

    def call(self, service, cmd, data=""):
        srv = roslibpy.Service(self.ros, service, "inspection_robot/ControlService")
        reply = srv.call(roslibpy.ServiceRequest({"sender": "server", "trans_id": 77, "cmd": cmd, "data": data}),
                         timeout=30)
        self.assertEqual(reply["trans_id"], 77)
        return reply["ack"], reply["data"]

    def pose(self):
        pose = self.true_pose.wait(timeout=10.0).pose.pose
        return pose.position.x, pose.position.y

    def pose_at_rest(self, timeout=10.0):
        """The true position once it has not changed (< 2 mm) over the last 0.5 s of simulator time
        (message stamps, not the test's clock: a loaded machine may deliver them late)."""
        def at_rest():
            messages = [m for _, m in self.true_pose.messages[-200:]]
            if not messages:
                return None
            last = messages[-1]
            earlier = [m for m in messages if (last.header.stamp - m.header.stamp).to_sec() >= 0.5]
            if not earlier:
                return None
            a, b = earlier[-1].pose.pose.position, last.pose.pose.position
            return (b.x, b.y) if math.hypot(b.x - a.x, b.y - a.y) < 0.002 else None
        return wait_for(at_rest, timeout, "robot at rest")

    def take_remote_control(self):
        """Heartbeat running, robot online, backend mode acquired: what a backend does first."""
        seen = len(self.status)
        heartbeat = Heartbeat(self.ros)
        heartbeat.start()
        self.addCleanup(heartbeat.stop)
        wait_for(lambda: any(s["offline_warn"] == 0 for s in self.status[seen:]), 20.0, "robot online")
        # once reported online, one acquire must be granted (robot_control decides on a status at
        # least as new as the one seen here, even when its copy arrives after the mode_cmd)
        acks = self.acks_by_topic["/mode_ack"]
        self.mode_cmd.publish(roslibpy.Message({"sender": "server", "trans_id": 4242, "cmd": "acquire",
                                                "data": "server"}))
        ack = wait_for(lambda: next((a for a in acks if a["trans_id"] == 4242), None), 10.0, "mode_ack")
        del acks[:]
        self.assertEqual((ack["ack"], ack["data"]), ("success", "server"))
        self.wait_status(lambda s: s["mode"] == 1, 5.0, "mode 1")
        return heartbeat

    def test_0_the_runtime_picture_is_current(self):
        """docs/runtime.dot (docs/development.md, "The running robot") is the graph of this very robot: the nodes of
        sim.launch and what they publish, subscribe to, serve and act on, as the master knows it."""
        with open(runtime_graph.DOT_FILE) as f:
            documented = f.read()
        # nodes register their topics one by one as they start (task_manager's action server last on
        # a loaded machine): the picture is compared once the graph has settled, or after 30 s
        live = None
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline:
            live = runtime_graph.live_source()
            if live == documented:
                break
            time.sleep(0.5)  # polling the master's state, not synchronisation
        if live != documented:
            missing = sorted(set(live.splitlines()) - set(documented.splitlines()))
            extra = sorted(set(documented.splitlines()) - set(live.splitlines()))
            self.fail("docs/runtime.dot is stale (run scripts/runtime_graph.py against sim.launch): not drawn %s; "
                      "drawn but gone %s" % (missing[:10], extra[:10]))

    def test_backend_session(self):
        # acquire backend remote control and drive forward for a second
        heartbeat = self.take_remote_control()
        start = self.pose()
        seen = len(self.status)
        deadline = time.monotonic() + 1.5
        while time.monotonic() < deadline:
            self.move_cmd.publish(roslibpy.Message({"sender": "server", "velocity_x": 300.0, "velocity_yaw": 0.0,
                                                    "wheel_control": 0}))
            time.sleep(0.05)  # the backend's command rate (20 Hz), not synchronisation
        # any status since the stream began (the latest may already be the cmd_timeout stop)
        wait_for(lambda: any(s["velocity_x"] > 0.1 for s in self.status[seen:]), 5.0, "moving forward")
        # the stream stops: cmd_timeout (0.5 s) brings the robot to rest
        self.wait_status(lambda s: abs(s["velocity_x"]) < 0.01, 5.0, "stopped after cmd_timeout")
        end = self.pose_at_rest()
        self.assertGreater(math.hypot(end[0] - start[0], end[1] - start[1]), 0.2)

        # the head, the camera and the voice through their interfaces
        self.assertEqual(self.call("/terrace_control", "set_angle", "4500,1000"), ("success", ""))
        self.assertEqual(self.call("/terrace_control", "get_angle"), ("success", "4500,1000"))
        ack, zoom = self.call("/camera_control", "get_zoom_level")
        self.assertEqual(ack, "success")
        self.assertGreaterEqual(float(zoom), 1.0)
        self.assertEqual(self.call("/terrace_control", "no_such_cmd")[0], "failed")
        self.voice_cmd.publish(roslibpy.Message({"sender": "server", "trans_id": 5, "language": "english",
                                                 "data": ["[42]"]}))
        wait_for(lambda: any(a.get("trans_id") == 5 and a["ack"] == "success" for a in self.acks), 20.0, "voice")

        # release, then a short navigation goal in task mode through actionlib over the bridge
        self.mode_cmd.publish(roslibpy.Message({"sender": "server", "cmd": "release", "data": ""}))
        self.wait_status(lambda s: s["mode"] == 0, 10.0, "task mode")
        x, y = self.pose_at_rest()
        client = roslibpy.actionlib.ActionClient(self.ros, "/move_action", "inspection_robot/GeneralAction")
        goal_data = {"with_direction": 0, "precision": 0, "move_style": 0, "velocity_x": 0.5, "velocity_yaw": 0.5,
                     "goal_pose": {"position": {"x": x + 2.0, "y": y, "z": 0},
                                   "orientation": {"x": 0, "y": 0, "z": 0, "w": 1}}}
        goal = roslibpy.actionlib.Goal(client, roslibpy.Message({"type": "move", "data": json.dumps(goal_data)}))
        goal.send()
        result = goal.wait(90)
        self.assertEqual(result["ret_code"], "0", result)
        x2, y2 = self.pose_at_rest()
        self.assertLess(math.hypot(x2 - (x + 2.0), y2 - y), 0.1)
        client.dispose()

        # losing the heartbeat in backend mode stops the robot and returns to task mode
        self.mode_cmd.publish(roslibpy.Message({"sender": "server", "cmd": "acquire", "data": "server"}))
        self.wait_status(lambda s: s["mode"] == 1, 10.0, "mode 1 again")
        heartbeat.stop()
        self.wait_status(lambda s: s["offline_warn"] == 1 and s["mode"] == 0, 3.0 + 2.0, "offline -> task mode")

    def node_pids(self):
        """{node: pid} of every node answering now (one still starting up on a loaded machine may be
        registered before its XML-RPC server answers: it is left out, not taken for a restart)."""
        pids = {}
        for name in rosnode.get_node_names():
            if name.startswith("/test_") or name == "/rosout":
                continue
            try:
                uri = rosgraph.Master("/test_system_sim").lookupNode(name)
                pids[name] = ServerProxy(uri).getPid("/test_system_sim")[2]
            except (rosgraph.MasterError, OSError):
                continue
        return pids

    def test_careless_backend(self):
        pids = self.node_pids()
        self.assertIn("/cloud_terrace", pids)
        self.take_remote_control()
        start = self.pose_at_rest()
        # junk velocities: refused (robot stopped), never clamped into motion
        for velocity_x, velocity_yaw, wheel in ((float("nan"), 0.0, 0), (1e308, 0.0, 0), (300.0, float("inf"), 0),
                                                (300.0, 0.0, 7)):
            for _ in range(5):
                self.move_cmd.publish(roslibpy.Message({"sender": "server", "velocity_x": velocity_x,
                                                        "velocity_yaw": velocity_yaw, "wheel_control": wheel}))
                time.sleep(0.05)  # the backend's command rate, not synchronisation
        self.mode_cmd.publish(roslibpy.Message({"sender": "server", "cmd": "release", "data": ""}))
        self.wait_status(lambda s: s["mode"] == 0, 10.0, "task mode")
        end = self.pose_at_rest()
        self.assertLess(math.hypot(end[0] - start[0], end[1] - start[1]), 0.01)

        # huge numbers and data where none is taken: a reason, never an internal error
        ack, reason = self.call("/terrace_control", "set_angle", "1" * 100000 + ",0")
        self.assertEqual(ack, "failed")
        self.assertIn("out of range", reason)
        self.assertEqual(self.call("/camera_control", "get_zoom_level", "4"),
                         ("failed", "this command takes no data, got '4'"))
        self.assertEqual(self.call("/infrared_control", "get_max_temperature", "x"),
                         ("failed", "this command takes no data, got 'x'"))

        # virtual obstacles: bad JSON, deep nesting, a unit error (mm for m)
        vo_cmd = roslibpy.Topic(self.ros, "/virtual_obstacle_cmd", "inspection_robot/GeneralCmd")
        acks = self.acks_by_topic["/virtual_obstacle_ack"]
        for trans_id, data, reason in ((301, "{bad", "not valid JSON"),
                                       (302, '{"id":"w","points":' + "[" * 50000 + "]" * 50000 + "}", "not valid JSON"),
                                       (303, '{"id":"w","points":[[2,2],[12300000,2]]}', "metres, not mm?")):
            vo_cmd.publish(roslibpy.Message({"sender": "server", "trans_id": trans_id, "cmd": "add", "data": data}))
            ack = wait_for(lambda: [a for a in acks if a["trans_id"] == trans_id], 10.0, "vo ack %d" % trans_id)[0]
            self.assertEqual(ack["ack"], "failed")
            self.assertIn(reason, ack["data"])

        # query_status is spoken (robot_voice acks robot_control's voice_cmd)
        control = roslibpy.Topic(self.ros, "/control_cmd", "inspection_robot/GeneralCmd")
        control.publish(roslibpy.Message({"sender": "server", "trans_id": 401, "cmd": "query_status", "data": ""}))
        spoken = wait_for(lambda: [a for a in self.acks_by_topic["/voice_ack"] if a["receiver"] == "robot_control"],
                          20.0, "query_status spoken")[0]
        self.assertEqual(spoken["ack"], "success", spoken["data"])

        # still the same processes, and they still answer
        self.assertEqual(self.call("/terrace_control", "get_pan_angle")[0], "success")
        after = self.node_pids()
        self.assertEqual({name: after.get(name) for name in pids}, pids)


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "system_sim", SystemSimTest)
