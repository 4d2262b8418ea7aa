#!/usr/bin/env python3
"""rostest (record_replay.test): record a short simulated run with sim.launch record:=true (driving
under backend control, a navigation goal, a virtual obstacle added, a soft e-stop, a heartbeat
loss; task_manager's task_status is latched from the start), close the bag, check that it holds
the task and virtual obstacle topics, replay
it with replay.launch in a second ROS master (use_sim_time, its own status_control), capture the
replayed robot_status with rosbag record, and compare: field by field with the live robot_status
the bag holds, and the heartbeat loss raising offline_warn at the same bag time."""
import glob
import json
import os
import threading
import unittest

import actionlib
import rosbag
import rosnode
import rospy
import rostest

from inspection_robot.interface import LIGHT_SOFT_ESTOP, MODE_SERVER, MODE_TASK
from inspection_robot.msg import GeneralAck, GeneralAction, GeneralCmd, GeneralGoal, GeneralTopic, MoveCmd, RobotStatus
from inspection_robot.recording.compare import compare_runs, rising_edges
from inspection_robot.recording.ros_bag_reading import status_fields
from rostest_helpers import Latest, replay_bag, wait_for, wait_subscribed

WALL = {"id": "record_test_wall", "points": [[30.0, 30.0], [31.0, 30.0]], "closed": False}   # far from the drive

HEARTBEAT_TIMEOUT = 3.0   # config/status_control.yaml
TIME_TOL = 0.5            # s: sim time lags under load, see test_replay_fixture.py (played at 1x here)
POS_TOL = 0.1             # m
STATUS_INPUTS = ["/control_status", "/nav_status", "/robot_odom", "/server_status"]


def bag_stream(path, topic):
    with rosbag.Bag(path) as bag:
        return [(m.header.stamp.to_sec(), status_fields(m)) for _t, m, _s in bag.read_messages(topics=[topic])]


def inputs_start(path):
    """Bag time from which the bag holds every input of status_control: an input (e.g. nav_status of a
    move_base that is still loading its map) may start later than the recorded robot_status; before
    that a replay cannot rebuild it."""
    first = {}
    with rosbag.Bag(path) as bag:
        for topic, _msg, t in bag.read_messages(topics=STATUS_INPUTS):
            first.setdefault(topic, t.to_sec())
            if len(first) == len(STATUS_INPUTS):
                return max(first.values())
    raise AssertionError("the bag lacks %s" % sorted(set(STATUS_INPUTS) - set(first)))


def goal_data(x, y, velocity_x=0.5):
    return json.dumps({"velocity_x": velocity_x, "goal_pose": {"position": {"x": x, "y": y, "z": 0},
                                                               "orientation": {"x": 0, "y": 0, "z": 0, "w": 1}}})


class RecordReplayTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_record_replay")
        cls.dir = rospy.get_param("test_bag_dir")
        cls.status = Latest("robot_status", RobotStatus, queue_size=5000)
        cls.server = rospy.Publisher("server_status", GeneralTopic, queue_size=10)
        cls.mode_cmd = rospy.Publisher("mode_cmd", GeneralCmd, queue_size=10)
        cls.control = rospy.Publisher("control_cmd", GeneralCmd, queue_size=10)
        cls.move = rospy.Publisher("move_cmd", MoveCmd, queue_size=10)
        cls.vo_cmd = rospy.Publisher("virtual_obstacle_cmd", GeneralCmd, queue_size=10)
        cls.vo_ack = Latest("virtual_obstacle_ack", GeneralAck, queue_size=10)
        cls.client = actionlib.SimpleActionClient("move_action", GeneralAction)
        assert cls.client.wait_for_server(rospy.Duration(60.0)), "move_action server"
        for pub in (cls.server, cls.mode_cmd, cls.control, cls.move, cls.vo_cmd):
            wait_subscribed(pub, 30.0)
        cls.beating = threading.Event()
        cls.beating.set()
        cls.timer = rospy.Timer(rospy.Duration(0.2), cls.beat)
        wait_for(lambda: glob.glob(os.path.join(cls.dir, "bags", "*.bag.active")), 30.0, "recording")
        cls.bag = cls.run_live()
        cls.replayed_bag = cls.replay(cls.bag)

    @classmethod
    def tearDownClass(cls):
        cls.timer.shutdown()

    @classmethod
    def beat(cls, _event):
        if cls.beating.is_set():
            cls.server.publish(GeneralTopic(sender="server", data="alive"))

    @classmethod
    def run_live(cls):
        """The scenario; returns the closed bag."""
        cls.status.wait(lambda m: m.offline_warn == 0 and m.mode == MODE_TASK, 30.0, "online, task mode")
        # backend drives for 2 s at 0.3 m/s, then gives the robot back
        cls.mode_cmd.publish(GeneralCmd(sender="server", cmd="acquire", data="server"))
        cls.status.wait(lambda m: m.mode == MODE_SERVER, 5.0, "server mode")
        start = rospy.get_time()
        wait_for(lambda: cls.move.publish(MoveCmd(sender="server", velocity_x=300.0)) or
                 rospy.get_time() - start > 2.0, 5.0, "2 s of driving", period=0.05)
        cls.status.wait(lambda m: m.velocity_x > 0.1, 2.0, "moving")
        cls.move.publish(MoveCmd(sender="server", velocity_x=0.0))
        cls.status.wait(lambda m: abs(m.velocity_x) < 0.01, 5.0, "stopped")
        cls.mode_cmd.publish(GeneralCmd(sender="server", cmd="release", data="server"))
        x0, y0 = cls.status.wait(lambda m: m.mode == MODE_TASK, 5.0, "task mode").position
        # a navigation goal 1.5 m away
        cls.client.send_goal(GeneralGoal(sender="task_manager", type="move", data=goal_data(x0 - 1.5, y0)))
        assert cls.client.wait_for_result(rospy.Duration(60.0)), "goal result"
        cls.goal_result = cls.client.get_result()
        # a virtual obstacle: move_base republishes its list (recorded, for a replay's query)
        cls.vo_ack.handshake(lambda: cls.vo_cmd.publish(GeneralCmd(sender="server", trans_id=77, cmd="add",
                                                                   data=json.dumps(WALL))),
                             lambda m: m.trans_id == 77, timeout=20.0)
        # soft e-stop on and off
        cls.control.publish(GeneralCmd(sender="server", cmd="enable_stop"))
        cls.status.wait(lambda m: m.light_status & LIGHT_SOFT_ESTOP, 5.0, "soft e-stop")
        rospy.sleep(1.0)
        cls.control.publish(GeneralCmd(sender="server", cmd="disable_stop"))
        cls.status.wait(lambda m: not m.light_status & LIGHT_SOFT_ESTOP, 5.0, "e-stop released")
        # heartbeat loss
        cls.beating.clear()
        cls.status.wait(lambda m: m.offline_warn == 1, HEARTBEAT_TIMEOUT + 3.0, "offline")
        rospy.sleep(1.0)
        cls.beating.set()
        cls.status.wait(lambda m: m.offline_warn == 0, 5.0, "online again")
        rospy.sleep(2.0)
        # stop recording: the node closes its bag on shutdown (respawn starts a new one, ignored)
        active = glob.glob(os.path.join(cls.dir, "bags", "*.bag.active"))
        assert len(active) == 1, active
        rosnode.kill_nodes(["/bag_recorder"])
        closed = active[0][:-len(".active")]
        wait_for(lambda: os.path.exists(closed), 30.0, "the bag closed")
        return closed

    @classmethod
    def replay(cls, bag):
        """Plays ``bag`` with replay.launch on a second master; returns the bag of replayed robot_status."""
        out = os.path.join(cls.dir, "replayed.bag")
        replay_bag(bag, out, os.path.join(cls.dir, "replay.log"))
        return out

    def test_the_run_did_what_the_scenario_says(self):
        live = bag_stream(self.bag, "/robot_status")
        self.assertEqual(self.goal_result.ret_code, "0", self.goal_result.data)
        self.assertEqual({f["mode"] for _t, f in live}, {MODE_TASK, MODE_SERVER})
        self.assertTrue(any(f["light_status"] & LIGHT_SOFT_ESTOP for _t, f in live))
        self.assertGreater(max(f["velocity_x"] for _t, f in live), 0.2)

    def test_the_bag_holds_the_task_and_virtual_obstacle_topics(self):
        with rosbag.Bag(self.bag) as bag:
            topics = bag.get_type_and_topic_info().topics
            self.assertEqual(topics["/task_status"].msg_type, "inspection_robot/GeneralTopic")
            status = [json.loads(m.data) for _t, m, _s in bag.read_messages(topics=["/task_status"])]
            listings = [json.loads(m.data) for _t, m, _s in bag.read_messages(topics=["/virtual_obstacles"])]
            acks = [m for _t, m, _s in bag.read_messages(topics=["/virtual_obstacle_ack"])]
        self.assertIn("state", status[0])
        self.assertIn(WALL, listings[-1])
        self.assertNotIn(WALL, listings[0])   # the list before the add, latched from move_base's start
        self.assertIn((77, "success"), [(a.trans_id, a.ack) for a in acks])

    def test_replayed_robot_status_matches_the_live_one_field_by_field(self):
        start = inputs_start(self.bag)
        live, replayed = bag_stream(self.bag, "/robot_status"), bag_stream(self.replayed_bag, "/robot_status")
        live, replayed = [s for s in live if s[0] >= start], [s for s in replayed if s[0] >= start]
        checked, mismatches = compare_runs(live, replayed, time_tol=TIME_TOL, pos_tol=POS_TOL)
        self.assertGreater(checked, 0.5 * len(live), "replayed %d of %d live statuses" % (checked, len(live)))
        self.assertEqual(mismatches[:5], [], "%d of %d replayed statuses differ" % (len(mismatches), checked))
        self.assertEqual({f["mode"] for _t, f in replayed}, {MODE_TASK, MODE_SERVER})

    def test_heartbeat_loss_raises_offline_warn_at_the_same_bag_time(self):
        live = rising_edges(bag_stream(self.bag, "/robot_status"), "offline_warn")
        replayed = rising_edges(bag_stream(self.replayed_bag, "/robot_status"), "offline_warn")
        self.assertEqual(len(live), 1, live)
        self.assertEqual(len(replayed), 1, replayed)
        self.assertAlmostEqual(replayed[0], live[0], delta=TIME_TOL)


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_record_replay", RecordReplayTest)
