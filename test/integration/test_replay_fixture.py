#!/usr/bin/env python3
"""rostest (replay_fixture.test): replay.launch plays the fixture bag with use_sim_time;
status_control must rebuild the recorded robot_status field by field, raise offline_warn at the
recorded bag time, the latched map must come back, and a backend on the websocket must see it and
get its virtual obstacle query answered from the recorded list (changes refused) as on the robot,
and the bridge must serve the operator console as on the robot."""
import json
import os
import queue
import sys
import time
import unittest
import urllib.request

import rosgraph
import rospy
import rostest
from nav_msgs.msg import OccupancyGrid
from std_srvs.srv import SetBool

from inspection_robot_testing.bridge_client import CLOSED, RawClient
from inspection_robot.msg import GeneralAck, GeneralCmd, RobotStatus
from inspection_robot.nav.virtual_obstacles import REPLAY_REFUSAL
from inspection_robot.recording.compare import compare_runs, rising_edges
from inspection_robot.recording.ros_bag_reading import status_fields
from rostest_helpers import Latest, wait_for

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "scripts"))
import make_bag_fixture  # noqa: E402

# Played at 2x, so that a wall-clock timeout would show: the 3 s heartbeat timeout measured on the
# wall clock would fire 3 s of bag time late. Replayed statuses are stamped with rospy's sim time,
# which follows /clock through its own subscriber thread: on this shared 2-core machine it was
# seen up to ~0.65 s of bag time off the message being handled (scheduling, not a clock leak).
# Hence a 1 s window; within it, positions must agree within 0.1 m and modes and bits exactly.
TIME_TOL = 1.0
POS_TOL = 0.1
END = make_bag_fixture.FIXTURE_START + make_bag_fixture.FIXTURE_DURATION - 0.2


def wired(state, topic, subscriber):
    _pubs, subs, _srvs = state
    return any(name == topic and subscriber in nodes for name, nodes in subs)


class ReplayFixtureTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_replay_fixture")
        cls.replayed = Latest("robot_status", RobotStatus, queue_size=1000)
        cls.recorded = Latest("recorded/robot_status", RobotStatus, queue_size=1000)
        cls.map = Latest("map", OccupancyGrid, queue_size=2)
        port = int(wait_for(lambda: rospy.get_param("rosbridge_websocket/actual_port", None), 60.0, "bridge port"))
        # A backend's view: a plain rosbridge v2 client (JSON frames) on the replay's websocket.
        cls.port = port
        cls.client = RawClient("ws://127.0.0.1:%d" % port, timeout=20.0)
        cls.client.send({"op": "subscribe", "topic": "/robot_status", "type": "inspection_robot/RobotStatus"})
        cls.client.send({"op": "subscribe", "topic": "/virtual_obstacle_ack", "type": "inspection_robot/GeneralAck"})
        cls.client.send({"op": "advertise", "topic": "/virtual_obstacle_cmd", "type": "inspection_robot/GeneralCmd"})
        cls.frames = []   # every message the backend received: (topic, msg)
        cls.recorded_acks = Latest("recorded/virtual_obstacle_ack", GeneralAck, queue_size=10)
        cls.vo_acks = Latest("virtual_obstacle_ack", GeneralAck, queue_size=50)
        cls.vo_cmd = rospy.Publisher("virtual_obstacle_cmd", GeneralCmd, queue_size=10)
        master = rosgraph.Master(rospy.get_name())
        wait_for(lambda: all(wired(master.getSystemState(), topic, node) for topic, node in (
            ("/control_status", "/status_control"), ("/nav_status", "/status_control"),
            ("/robot_odom", "/status_control"), ("/recorded/server_status", "/status_control"),
            ("/robot_status", "/rosbridge_websocket"), ("/robot_status", rospy.get_name()),
            ("/recorded/robot_status", rospy.get_name()), ("/virtual_obstacle_cmd", "/virtual_obstacles_replay"),
            ("/virtual_obstacle_ack", "/rosbridge_websocket"), ("/virtual_obstacles", "/virtual_obstacles_replay"))),
            30.0, "replay nodes subscribed")
        cls.replayed.wait_connected(10.0)
        cls.recorded.wait_connected(10.0)
        rospy.wait_for_service("replay_player/pause_playback", 10.0)
        rospy.ServiceProxy("replay_player/pause_playback", SetBool)(False)
        # past the recorded query (3 s): a backend asks for the virtual obstacles, as the console does
        wait_for(lambda: cls.recorded_acks.last is not None, 30.0, "the recorded query's ack")
        cls.vo_answers = cls.ask_over_ros()
        cls.backend_answers = cls.ask_over_the_websocket()
        wait_for(lambda: cls.recorded.last is not None and cls.recorded.last.header.stamp.to_sec() >= END, 90.0,
                 "the end of the bag")
        cls.drain(lambda _topic, _msg: False, 0.5)
        cls.backend = [m for topic, m in cls.frames if topic == "/robot_status"]

    @classmethod
    def drain(cls, done, timeout):
        """Read the backend's frames (all kept in cls.frames) until ``done(topic, msg)`` or ``timeout`` s pass."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                frame = cls.client.recv(max(0.01, min(0.5, deadline - time.monotonic())))
            except queue.Empty:
                continue
            if frame is CLOSED:
                return None
            message = json.loads(frame)
            if message.get("op") == "publish":
                cls.frames.append((message["topic"], message["msg"]))
                if done(message["topic"], message["msg"]):
                    return message["msg"]
        return None

    @classmethod
    def ask_over_the_websocket(cls):
        """query, add, query one id, each from the backend until answered; {trans_id: ack msg}."""
        answers = {}
        for trans_id, cmd, data in ((11, "query", ""), (12, "add", json.dumps(
                {"id": "new", "points": [[0, 0], [1, 1]]})), (13, "query", '{"id": "fixture_wall"}')):
            deadline = time.monotonic() + 20.0
            while trans_id not in answers and time.monotonic() < deadline:
                cls.client.send({"op": "publish", "topic": "/virtual_obstacle_cmd",
                                 "msg": {"sender": "server", "trans_id": trans_id, "cmd": cmd, "data": data}})
                answers[trans_id] = cls.drain(lambda topic, m, i=trans_id: topic == "/virtual_obstacle_ack" and
                                              m["trans_id"] == i, 1.0)
                if answers[trans_id] is None:
                    del answers[trans_id]
        return answers

    @classmethod
    def ask_over_ros(cls):
        answers = {}
        for trans_id, cmd, data in ((1, "query", ""), (2, "clear", ""), (3, "query", '{"id": "nope"}')):
            answers[trans_id] = cls.vo_acks.handshake(
                lambda: cls.vo_cmd.publish(GeneralCmd(sender="test", trans_id=trans_id, cmd=cmd, data=data)),
                lambda m, i=trans_id: m.trans_id == i, timeout=20.0)
        return answers

    @classmethod
    def tearDownClass(cls):
        cls.client.close()

    @staticmethod
    def stream(latest):
        return [(m.header.stamp.to_sec(), status_fields(m)) for _t, m in list(latest.messages)]

    def test_robot_status_matches_the_recording_field_by_field(self):
        recorded, replayed = self.stream(self.recorded), self.stream(self.replayed)
        checked, mismatches = compare_runs(recorded, replayed, time_tol=TIME_TOL, pos_tol=POS_TOL)
        self.assertGreater(checked, 250)
        self.assertEqual(mismatches[:5], [], "%d of %d replayed statuses differ" % (len(mismatches), checked))
        modes = {f["mode"] for _t, f in replayed}
        self.assertEqual(modes, {0, 1})

    def test_heartbeat_loss_raises_offline_warn_at_the_same_bag_time(self):
        recorded = rising_edges(self.stream(self.recorded), "offline_warn")
        replayed = rising_edges(self.stream(self.replayed), "offline_warn")
        self.assertEqual(len(recorded), 1)
        self.assertEqual(len(replayed), 1, (replayed, [(t, f["offline_warn"]) for t, f in
                                                       self.stream(self.replayed)[:8]]))
        self.assertAlmostEqual(recorded[0] - make_bag_fixture.FIXTURE_START, make_bag_fixture.FIXTURE_OFFLINE_AT,
                               delta=0.15)
        self.assertAlmostEqual(replayed[0], recorded[0], delta=TIME_TOL)

    def test_map_comes_back_latched(self):
        grid = self.map.wait(lambda m: True, 5.0, "map")
        self.assertEqual((grid.info.width, grid.info.height), (200, 160))

    def test_backend_sees_the_replay_over_the_websocket(self):
        self.assertGreater(len(self.backend), 100)
        offline = [m for m in self.backend if m["offline_warn"] == 1]
        server_mode = [m for m in self.backend if m["mode"] == 1]
        self.assertTrue(offline and server_mode)
        far = [m for m in self.backend if abs(m["position"][0] - 8.0) < 0.05 and m["position"][1] > 5.5]
        self.assertTrue(far, "the end of the drive at (8, 5.6)")

    def test_the_console_is_served(self):
        with urllib.request.urlopen("http://127.0.0.1:%d/console/" % self.port, timeout=10.0) as reply:
            self.assertEqual(reply.status, 200)
            self.assertIn(b"<html", reply.read().lower())

    def test_virtual_obstacle_query_is_answered_from_the_recording(self):
        listing = make_bag_fixture.FIXTURE_VIRTUAL_OBSTACLES
        web = self.backend_answers
        self.assertEqual(sorted(web), [11, 12, 13], "every backend command answered")
        self.assertEqual((web[11]["ack"], json.loads(web[11]["data"])), ("success", listing))
        self.assertEqual((web[11]["sender"], web[11]["receiver"]), ("move_base", "server"))
        self.assertEqual((web[12]["ack"], web[12]["data"]), ("failed", REPLAY_REFUSAL))
        self.assertTrue(REPLAY_REFUSAL.startswith("not_allowed: replay"))
        self.assertEqual(json.loads(web[13]["data"]), listing)
        ros = self.vo_answers
        self.assertEqual((ros[1].ack, json.loads(ros[1].data), ros[1].receiver), ("success", listing, "test"))
        self.assertEqual((ros[2].ack, ros[2].data), ("failed", REPLAY_REFUSAL))
        self.assertEqual((ros[3].ack, ros[3].data), ("failed", "no virtual obstacle with id 'nope'"))

    def test_recorded_virtual_obstacle_commands_are_not_answered_again(self):
        recorded = self.recorded_acks.last
        self.assertEqual((recorded.trans_id, recorded.sender), (make_bag_fixture.FIXTURE_QUERY_TRANS_ID, "move_base"))
        live = [m for topic, m in self.frames if topic == "/virtual_obstacle_ack"]
        self.assertTrue(live)
        self.assertFalse([m for m in live if m["trans_id"] == make_bag_fixture.FIXTURE_QUERY_TRANS_ID])
        self.assertFalse([m for _t, m in list(self.vo_acks.messages)
                          if m.trans_id == make_bag_fixture.FIXTURE_QUERY_TRANS_ID])


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_replay_fixture", ReplayFixtureTest)
