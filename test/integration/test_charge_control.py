#!/usr/bin/env python3
"""rostest: charge_control against the simulated chassis, battery and dock (charge_control.test).

This script plays task_manager (task_control service + latched task_status) and proves: low
battery -> patrol paused -> dock -> relay on -> charging -> charged -> relay off -> back off ->
patrol resumed; a dead dock (no charging current) retried then reported by alarm + voice; an
unreachable dock reported the same way; manual dock/undock; bad commands refused.
"""
import json
import math
import threading
import time
import unittest

import rospy
import rostest

from inspection_robot.interface import BATTERY_CHARGING, LIGHT_CHARGE_RELAY
from inspection_robot.msg import GeneralAck, GeneralCmd, GeneralTopic, RobotStatus, VoiceCmd
from inspection_robot.srv import ControlService, ControlServiceResponse
from rostest_helpers import (GroundTruth, Latest, TwinClient, control_proxy, set_pose_when_at_rest, wait_for,
                             wait_subscribed)

DOCK = (2.2, 5.0)
APPROACH = (3.7, 5.0)
LONG = 120.0  # s, a whole charge cycle in the simulator is ~40 s on a quiet machine


class FakeTaskManager(object):
    """task_control + task_status as the contract with task_manager says: pause "charge" adds a hold,
    a running patrol finishes its preset (here 1 s) and reports paused; resume removes the hold."""

    def __init__(self):
        self.calls = []
        self.state = "running"
        self.holds = set()
        self.lock = threading.Lock()
        self.events = []  # (monotonic time, state) of every published state
        self.pub = rospy.Publisher("task_status", GeneralTopic, queue_size=10, latch=True)
        self.service = rospy.Service("task_control", ControlService, self.on_call)
        self.publish()

    def publish(self):
        with self.lock:
            self.events.append((time.monotonic(), self.state))
            data = json.dumps({"task_id": "t1" if self.state != "idle" else "", "state": self.state,
                               "holds": sorted(self.holds)})
        self.pub.publish(GeneralTopic(sender="task_manager", data=data))

    def set_state(self, state):
        with self.lock:
            self.state = state
        self.publish()

    def on_call(self, req):
        with self.lock:
            self.calls.append((req.cmd, req.data))
        if req.cmd == "pause" and req.data == "charge":
            with self.lock:
                self.holds.add("charge")
                running = self.state == "running"
            if running:
                threading.Timer(1.0, self.set_state, ("paused",)).start()  # finishes its current preset
            self.publish()
            return ControlServiceResponse(trans_id=req.trans_id, ack="success", data="")
        if req.cmd == "resume" and req.data == "charge":
            with self.lock:
                self.holds.discard("charge")
                if self.state == "paused" and not self.holds:
                    self.state = "running"
            self.publish()
            return ControlServiceResponse(trans_id=req.trans_id, ack="success", data="")
        return ControlServiceResponse(trans_id=req.trans_id, ack="failed", data="unknown command '%s'" % req.cmd)


class ChargeControlTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_charge_control")
        cls.task_manager = FakeTaskManager()
        cls.status = Latest("charge_status", GeneralTopic, queue_size=500)
        cls.voice = Latest("voice_cmd", VoiceCmd)
        cls.control = Latest("control_cmd", GeneralCmd)
        cls.robot = Latest("robot_status", RobotStatus, queue_size=2000)
        cls.true_pose = GroundTruth()   # where the robot is (robot_status carries the localizer's noisy pose)
        cls.alarms = Latest("charge_ack", GeneralAck)
        cls.vo_acks = Latest("virtual_obstacle_ack", GeneralAck)
        cls.vo_cmd = rospy.Publisher("virtual_obstacle_cmd", GeneralCmd, queue_size=10)
        cls.sim = control_proxy("sim/inject_fault", 30.0)
        cls.charge = TwinClient("charge_control", "charge_cmd", "charge_ack", "charge_control", timeout=30.0)
        wait_subscribed(cls.vo_cmd, 30.0)
        # the replies' publishers must have added this node before the first request (Latest.wait_connected)
        cls.alarms.wait_connected(30.0)
        cls.vo_acks.wait_connected(30.0)
        cls.robot.wait(lambda m: len(m.position) == 2, 30.0, "robot_status with a pose")
        cls.status.wait(lambda m: json.loads(m.data)["state"] == "idle", 30.0, "charge_control idle")
        # the contract's late joiner: charge_control must have heard the latched task_status
        wait_for(lambda: cls.task_manager.pub.get_num_connections() > 0, 30.0, "task_status subscriber")
        # start-up at 90 %: robot_status before robot_control's first control_status (zeros, flagged stale)
        # must not start a charge cycle
        cls.robot.wait(lambda m: m.battery_quantity >= 80, 30.0, "robot_status with the battery")
        cls.startup_status = json.loads(cls.charge.call("status").data)
        cls.startup_calls = list(cls.task_manager.calls)

    def setUp(self):
        self.sim_cmd("set_soc", "90")
        self.sim_cmd("charger_off", "0")
        self.task_manager.set_state("running")
        if json.loads(self.charge.call("status").data)["state"] != "idle":
            self.charge.call("undock")  # a failed test left a cycle behind
        self.wait_state("idle", 60.0)
        for latest in (self.status, self.voice, self.control, self.alarms):
            latest.clear()
        del self.task_manager.calls[:]

    def sim_cmd(self, cmd, data):
        reply = self.sim(sender="rostest", cmd=cmd, data=data)
        self.assertEqual(reply.ack, "success", "%s %s: %s" % (cmd, data, reply.data))

    def current(self):
        last = self.status.last
        return json.loads(last.data) if last is not None else {}

    def wait_state(self, state, timeout=LONG):
        return self.status.wait(lambda m: json.loads(m.data)["state"] == state, timeout, "charge state " + state)

    def states_seen(self):
        """The states charge_control went through since setUp, from the first one after idle."""
        seen = []
        for _, msg in list(self.status.messages):
            state = json.loads(msg.data)["state"]
            if (seen or state != "idle") and (not seen or seen[-1] != state):
                seen.append(state)
        return seen

    def relay_commands(self):
        return [m.cmd for _, m in list(self.control.messages) if m.sender == "charge_control"]

    def assert_relay_commands(self, expected):
        """control_cmd and charge_status are separate topics: wait for the commands to arrive, then compare."""
        try:
            wait_for(lambda: self.relay_commands() == expected, 5.0, "control_cmd %s" % (expected,))
        except AssertionError:
            self.assertEqual(self.relay_commands(), expected)

    def pose_near(self, point, tol):
        """The robot (ground truth) within ``tol`` of ``point`` on each axis."""
        pos = self.true_pose.pose()
        return abs(pos[0] - point[0]) < tol and abs(pos[1] - point[1]) < tol

    def test_0_no_cycle_at_start_up(self):
        self.assertEqual((self.startup_status["trigger"], self.startup_status["state"]), ("", "idle"))
        self.assertEqual(self.startup_calls, [])

    def test_1_low_battery_cycle_pauses_docks_charges_and_resumes(self):
        self.sim_cmd("set_soc", "38")  # below low_level 40
        self.wait_state("charging")
        self.assertIn(("pause", "charge"), self.task_manager.calls)
        self.robot.wait(
            lambda m: m.battery_status & BATTERY_CHARGING and m.light_status & LIGHT_CHARGE_RELAY, 10.0,
            "robot_status charging with the relay on")
        docked = self.true_pose.pose()
        rospy.loginfo("test_charge_control: charging %.4f m from the dock in ground truth (move_base drove on the "
                      "localizer's pose)", math.hypot(docked[0] - DOCK[0], docked[1] - DOCK[1]))
        self.assertTrue(self.pose_near(DOCK, 0.05), "charging on the dock: %s" % (docked,))
        self.wait_state("idle")
        self.assertEqual(self.task_manager.calls, [("pause", "charge"), ("resume", "charge")])
        self.assertEqual(self.task_manager.state, "running")
        self.assertEqual(self.states_seen(), ["pausing_task", "to_approach", "docking", "relay_on", "wait_current",
                                              "charging", "relay_off", "backing_off", "resuming_task", "idle"])
        self.assert_relay_commands(["enable_charge", "disable_charge"])
        # the patrol reported paused before the robot left for the dock
        paused_at = [t for t, s in self.task_manager.events if s == "paused"][-1]
        drive_at = [t for t, m in self.status.messages if json.loads(m.data)["state"] == "to_approach"][0]
        self.assertLess(paused_at, drive_at)
        # charged to full_level before the relay opened, relay off and backed off to the approach pose
        relay_off = [m for _, m in self.status.messages if json.loads(m.data)["state"] == "relay_off"][0]
        self.assertGreaterEqual(json.loads(relay_off.data)["battery"], 60)
        self.robot.wait(lambda m: not m.light_status & LIGHT_CHARGE_RELAY, 5.0, "relay open")
        self.assertTrue(self.pose_near(APPROACH, 0.1), "backed off to %s" % (self.true_pose.pose(),))
        spoken = [list(m.data) for _, m in self.voice.messages if m.sender == "charge_control"]
        self.assertEqual(spoken, [["charge_battery_low", "charge_going_to_dock"], ["charge_done"]])
        self.assertEqual(self.current()["alarm"], "")

    def test_2_dead_dock_is_retried_then_alarm_and_voice(self):
        self.sim_cmd("charger_off", "1")  # the dock has no power: relay closes, no current
        reply = self.charge.call("dock")
        self.assertEqual((reply.ack, reply.data), ("success", "docking started"))
        failed = json.loads(self.wait_state("failed").data)
        self.assertTrue(failed["alarm"].startswith("no charging current: battery_status b4 not set"), failed)
        self.assertEqual(failed["attempts"], {"current": 2})
        self.assertTrue(failed["task_paused"], "the patrol stays paused while the alarm stands")
        # it docked twice (one retry), and left the contacts dead each time
        self.assert_relay_commands(["enable_charge", "disable_charge", "enable_charge", "disable_charge"])
        self.assertEqual(self.states_seen().count("docking"), 2)
        alarm = self.alarms.wait(lambda m: m.ack == "failed" and m.data.startswith("charge alarm: no charging current"),
                                 5.0, "alarm on charge_ack")
        self.assertEqual(alarm.sender, "charge_control")
        self.voice.wait(lambda m: list(m.data) == ["charge_alarm", "charge_no_current"], 5.0, "voice alarm")
        self.robot.wait(lambda m: not m.light_status & LIGHT_CHARGE_RELAY, 5.0, "relay open after the alarm")
        self.assertEqual(self.task_manager.state, "paused")
        # the operator sends undock: back off the dock, resume the patrol
        reply = self.charge.topic("undock")
        self.assertEqual((reply.ack, reply.data), ("success", "undocking"))
        self.wait_state("idle")
        self.assertEqual(self.task_manager.calls[-1], ("resume", "charge"))
        self.assertEqual(self.task_manager.state, "running")
        self.assertTrue(self.pose_near(APPROACH, 0.1), "backed off to %s" % (self.true_pose.pose(),))

    def test_3_unreachable_dock_alarm(self):
        # a virtual wall closed around the dock: the robot lines up, then the docking goal has no path
        wall = {"id": "charge_test_wall", "closed": True, "points": [[1.6, 4.4], [2.8, 4.4], [2.8, 5.6], [1.6, 5.6]]}
        trans_id = 77
        self.vo_acks.handshake(lambda: self.vo_cmd.publish(GeneralCmd(sender="server", cmd="add", trans_id=trans_id,
                                                                      data=json.dumps(wall))),
                               lambda m: m.trans_id == trans_id, 10.0)
        try:
            self.assertEqual(self.charge.call("dock").ack, "success")
            failed = json.loads(self.wait_state("failed", 60.0).data)
            expected = "dock unreachable: docking goal failed: ret_code 1: planning failed"
            self.assertTrue(failed["alarm"].startswith(expected), failed)
            self.assertEqual(failed["attempts"], {"dock": 2})
            self.voice.wait(lambda m: list(m.data) == ["charge_alarm", "charge_dock_unreachable"], 5.0, "voice alarm")
            self.assertNotIn("enable_charge", self.relay_commands())
        finally:
            self.vo_cmd.publish(GeneralCmd(sender="server", cmd="delete", trans_id=78,
                                           data=json.dumps({"id": "charge_test_wall"})))
        self.assertEqual(self.charge.call("undock").ack, "success")  # not at the dock: just resume
        self.wait_state("idle", 30.0)
        self.assertEqual(self.task_manager.state, "running")

    def test_4_manual_dock_then_undock_while_charging(self):
        self.sim_cmd("set_soc", "45")  # above low_level: no automatic cycle
        reply = self.charge.topic("dock")
        self.assertEqual((reply.ack, reply.data), ("success", "docking started"))
        self.assertEqual(self.charge.call("dock").data, "busy: charge cycle already running (pausing_task)")
        self.wait_state("charging")
        self.sim_cmd("set_soc", "10")  # a long charge ahead: the undock below interrupts it
        status = json.loads(self.charge.call("status").data)
        self.assertEqual((status["state"], status["trigger"], status["docked"]), ("charging", "manual", True))
        reply = self.charge.call("undock")
        self.assertEqual((reply.ack, reply.data), ("success", "undocking"))
        idle = json.loads(self.wait_state("idle").data)
        self.assert_relay_commands(["enable_charge", "disable_charge"])
        self.assertEqual(self.task_manager.calls, [("pause", "charge"), ("resume", "charge")])
        self.assertEqual(self.states_seen(), ["pausing_task", "to_approach", "docking", "relay_on", "wait_current",
                                              "charging", "relay_off", "backing_off", "resuming_task", "idle"])
        # below low_level after an undock the operator chose: no automatic cycle until the battery recovers
        self.assertFalse(idle["auto"])
        status = self.status.wait(lambda m: "automatic docking off" in json.loads(m.data)["waiting"], 10.0,
                                  "status saying automatic docking is off")
        self.assertEqual(json.loads(status.data)["state"], "idle")

    def test_5_bad_commands(self):
        for name, send in self.charge.both():
            reply = send("dock", "now")
            self.assertEqual((reply.ack, reply.data), ("failed", "this command takes no data, got 'now'"), name)
            reply = send("charge", "")
            self.assertEqual((reply.ack, reply.data), ("failed", "unknown command 'charge'"), name)
            reply = send("undock", "")
            self.assertEqual((reply.ack, reply.data), ("failed", "not at the dock"), name)
        self.assertEqual(json.loads(self.charge.call("status").data)["state"], "idle")
        self.assertEqual(self.relay_commands(), [])

    def test_6_waits_while_the_backend_holds_control(self):
        # away from the dock: the approach takes a while (the previous test may have just backed off)
        set_pose_when_at_rest(self.sim, (8.0, 5.0, 0.0))
        heartbeat = rospy.Publisher("server_status", GeneralTopic, queue_size=10)
        mode_cmd = rospy.Publisher("mode_cmd", GeneralCmd, queue_size=10)
        beat = rospy.Timer(rospy.Duration(0.2), lambda _e: heartbeat.publish(GeneralTopic(sender="server")))
        try:
            wait_subscribed(mode_cmd, 10.0)
            self.robot.wait(lambda m: m.offline_warn == 0, 10.0, "backend online")
            self.sim_cmd("set_soc", "38")
            self.wait_state("to_approach", 30.0)
            self.robot.handshake(lambda: mode_cmd.publish(GeneralCmd(sender="server", cmd="acquire", data="server")),
                                 lambda m: m.mode == 1, 10.0)
            waiting = self.status.wait(
                lambda m: json.loads(m.data)["waiting"].startswith("robot_control in server mode"), 10.0,
                "charge_status saying it waits for task mode")
            self.assertEqual(json.loads(waiting.data)["state"], "to_approach")
            self.robot.handshake(lambda: mode_cmd.publish(GeneralCmd(sender="server", cmd="release")),
                                 lambda m: m.mode == 0, 10.0)
        finally:
            beat.shutdown()
        self.wait_state("charging")
        done = json.loads(self.wait_state("idle").data)
        self.assertEqual((done["alarm"], done["attempts"]), ("", {}))
        self.assertEqual(self.task_manager.calls, [("pause", "charge"), ("resume", "charge")])


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_charge_control", ChargeControlTest)
