#!/usr/bin/env python3
"""rostest (replay_fixture.test): replay.launch plays the fixture bag with use_sim_time;
status_control must rebuild the recorded robot_status field by field, raise offline_warn at the
recorded bag time, the latched map must come back, and a backend on the websocket must see it."""
import json
import os
import queue
import sys
import unittest

import rosgraph
import rospy
import rostest
from nav_msgs.msg import OccupancyGrid
from std_srvs.srv import SetBool

from inspection_robot.bridge.client import CLOSED, RawClient
from inspection_robot.msg import RobotStatus
from inspection_robot.recording.compare import compare_runs, rising_edges
from inspection_robot.tools.bag_report import status_fields
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
        cls.client = RawClient("ws://127.0.0.1:%d" % port, timeout=20.0)
        cls.client.send({"op": "subscribe", "topic": "/robot_status", "type": "inspection_robot/RobotStatus"})
        master = rosgraph.Master(rospy.get_name())
        wait_for(lambda: all(wired(master.getSystemState(), topic, node) for topic, node in (
            ("/control_status", "/status_control"), ("/nav_status", "/status_control"),
            ("/robot_odom", "/status_control"), ("/recorded/server_status", "/status_control"),
            ("/robot_status", "/rosbridge_websocket"), ("/robot_status", rospy.get_name()),
            ("/recorded/robot_status", rospy.get_name()))), 30.0, "replay nodes subscribed")
        cls.replayed.wait_connected(10.0)
        cls.recorded.wait_connected(10.0)
        rospy.wait_for_service("replay_player/pause_playback", 10.0)
        rospy.ServiceProxy("replay_player/pause_playback", SetBool)(False)
        wait_for(lambda: cls.recorded.last is not None and cls.recorded.last.header.stamp.to_sec() >= END, 90.0,
                 "the end of the bag")

        cls.backend = []
        while True:
            try:
                frame = cls.client.recv(0.5)
            except queue.Empty:
                break
            if frame is not CLOSED and json.loads(frame).get("op") == "publish":
                cls.backend.append(json.loads(frame)["msg"])

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


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_replay_fixture", ReplayFixtureTest)
