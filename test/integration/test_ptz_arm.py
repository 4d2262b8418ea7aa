#!/usr/bin/env python3
"""rostest: robot_arm with the simulated arm (every command via service and topic, record/play)."""
import os
import shutil
import unittest

import rospy
import rostest

from inspection_robot.msg import ControlStatus
from rostest_helpers import TwinClient, control_proxy, wait_for, wait_subscribed


def floats(text):
    return [float(v) for v in text.split(",")]


class ArmTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_ptz_arm")
        cls.root = rospy.get_param("~root")
        cls.arm = TwinClient("arm_control", "arm_cmd", "arm_ack", "robot_arm")
        cls.acks = cls.arm.acks
        cls.sim = control_proxy("robot_arm/sim_control", 10.0)
        cls.control = rospy.Publisher("control_status", ControlStatus, queue_size=10, latch=True)
        wait_subscribed(cls.control)
        cls.control.publish(ControlStatus(mode=0))

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.root, ignore_errors=True)

    def setUp(self):
        self.sim(cmd="fault", data="")
        self.call("stop_orbit")
        self.assertEqual(self.call("reset").ack, "success")

    def call(self, cmd, data="", sender="server"):
        return self.arm.call(cmd, data, sender)

    def topic(self, cmd, data="", sender="server"):
        return self.arm.topic(cmd, data, sender)

    def both(self):
        return self.arm.both()

    def position(self):
        return floats(self.call("get_position").data)

    def orientation(self):
        return floats(self.call("get_orientation").data)

    def assertWithin(self, text, target, tolerance=0.5):
        values = [float(v) for v in text.split(",")]
        self.assertEqual(len(values), 3, text)
        self.assertLessEqual(max(abs(a - b) for a, b in zip(values, target)), tolerance, (text, target))

    def test_set_get_position_orientation_reset_both_twins(self):
        for name, run in self.both():
            with self.subTest(twin=name):
                # the ack comes once the arm is within robot_arm's tolerance (0.5 mm, 0.5 deg), where it
                # may still be settling: a get right after reads within that of the target
                self.assertEqual(run("set_position", "120.5,-40,300").ack, "success")
                self.assertWithin(run("get_position").data, (120.5, -40.0, 300.0))
                self.assertEqual(run("set_orientation", "10,-20.5,45").ack, "success")
                self.assertWithin(run("get_orientation").data, (10.0, -20.5, 45.0))
                self.assertEqual(run("reset").ack, "success")
                self.assertWithin(run("get_position").data, (0.0, 0.0, 0.0))
                self.assertWithin(run("get_orientation").data, (0.0, 0.0, 0.0))

    def test_move_stop_move_rotate_stop_rotate_both_twins(self):
        for name, run in self.both():
            with self.subTest(twin=name):
                self.assertEqual(run("move", "+,0,-").ack, "success")
                wait_for(lambda: self.position()[0] > 20 and self.position()[2] < -20, 3.0, "jog x+ z-")
                self.assertEqual(run("stop_move", "0,0,+").ack, "success")   # x stops, z continues
                x_stopped = self.position()[0]
                wait_for(lambda: self.position()[2] < -60, 3.0, "z still moving")
                self.assertAlmostEqual(self.position()[0], x_stopped, delta=1.0)
                self.assertEqual(run("stop_move").ack, "success")
                self.assertEqual(run("rotate", "0,+,-").ack, "success")
                wait_for(lambda: self.orientation()[1] > 5 and self.orientation()[2] < -5, 3.0, "rotate")
                self.assertEqual(run("stop_rotate", "0,0,0").ack, "success")
                still = self.orientation()
                self.assertEqual(self.orientation()[0], 0.0)
                self.assertAlmostEqual(self.orientation()[2], still[2], delta=1.0)
                self.assertEqual(run("reset").ack, "success")

    def test_record_play_forward_and_reverse(self):
        path = os.path.join(self.root, "orbit_a.csv")
        self.assertEqual(self.call("set_position", "50,0,100").ack, "success")
        start = self.position()
        reply = self.topic("record_orbit", path)
        self.assertEqual((reply.ack, reply.data), ("success", path))
        self.assertEqual(self.call("set_position", "200,100,250").ack, "success")
        self.assertEqual(self.call("set_orientation", "0,30,-20").ack, "success")
        end = self.position()
        reply = self.topic("stop_orbit")
        self.assertEqual(reply.ack, "success")
        self.assertTrue(reply.data.startswith(path + ","), reply.data)
        self.assertGreater(int(reply.data.split(",")[1]), 5)
        with open(path) as f:
            self.assertEqual(f.readline().strip(), "# inspection_robot arm trajectory v1")
        self.assertEqual(self.call("reset").ack, "success")
        self.acks.clear()
        for name, run in self.both():
            with self.subTest(twin=name):
                reply = run("play_orbit", path + ",+")
                self.assertEqual(reply.ack, "success", reply.data)
                done = self.acks.wait(lambda m: m.trans_id == 0 and "finished" in m.data, 10.0, "forward end")
                self.assertIn(",+", done.data)
                for got, want in zip(self.position(), end):
                    self.assertAlmostEqual(got, want, delta=1.0)
                for got, want in zip(self.orientation(), [0.0, 30.0, -20.0]):
                    self.assertAlmostEqual(got, want, delta=0.5)
                self.acks.clear()
                self.assertEqual(run("play_orbit", path + ",-").ack, "success")
                self.acks.wait(lambda m: m.trans_id == 0 and "finished" in m.data, 10.0, "reverse end")
                for got, want in zip(self.position(), start):
                    self.assertAlmostEqual(got, want, delta=1.0)
                for got in self.orientation():
                    self.assertAlmostEqual(got, 0.0, delta=0.5)
                self.acks.clear()

    def test_default_trajectory_file(self):
        self.assertEqual(self.call("record_orbit").data, os.path.join(self.root, "default_orbit.csv"))
        self.assertEqual(self.call("move", "0,+,0").ack, "success")
        wait_for(lambda: self.position()[1] > 50, 3.0, "jog y")
        self.assertEqual(self.call("stop_move").ack, "success")
        self.assertEqual(self.call("stop_orbit").ack, "success")
        self.assertTrue(os.path.exists(os.path.join(self.root, "default_orbit.csv")))
        self.assertEqual(self.call("reset").ack, "success")
        self.acks.clear()
        self.assertEqual(self.call("play_orbit", ",+").ack, "success")
        self.acks.wait(lambda m: m.trans_id == 0 and "finished" in m.data, 10.0, "default played")
        self.assertGreater(self.position()[1], 50)

    def test_failure_during_playback_and_record_is_reported_unprompted(self):
        path = os.path.join(self.root, "orbit_fault.csv")
        with open(path, "w") as f:
            f.write("# inspection_robot arm trajectory v1\nt_s,x_mm,y_mm,z_mm,roll_deg,pitch_deg,yaw_deg\n"
                    "0.0,0,0,0,0,0,0\n3.0,0,0,0,0,0,0\n")
        self.acks.clear()
        self.assertEqual(self.call("play_orbit", path + ",+").ack, "success")
        self.assertIn("busy", self.call("set_position", "1,1,1").data)
        self.sim(cmd="fault", data="motor overcurrent")
        ack = self.acks.wait(lambda m: m.trans_id == 0 and m.ack == "failed", 5.0, "unprompted failure")
        self.assertIn("motor overcurrent", ack.data)
        self.sim(cmd="fault", data="")
        self.acks.clear()
        self.assertEqual(self.call("record_orbit", "rec_fault.csv").ack, "success")
        self.sim(cmd="fault", data="encoder lost")
        ack = self.acks.wait(lambda m: m.trans_id == 0 and m.ack == "failed", 5.0, "unprompted record failure")
        self.assertIn("encoder lost", ack.data)
        self.sim(cmd="fault", data="")
        self.acks.clear()
        self.assertEqual(self.call("play_orbit", path + ",-").ack, "success")
        self.assertEqual(self.call("stop_move").ack, "success")
        ack = self.acks.wait(lambda m: m.trans_id == 0 and m.ack == "failed", 5.0, "stopped report")
        self.assertIn("stopped by stop_move", ack.data)

    def test_bad_input_fails_and_nothing_moves(self):
        self.assertEqual(self.call("set_position", "10,20,30").ack, "success")
        bad_file = os.path.join(self.root, "bad.csv")
        with open(bad_file, "w") as f:
            f.write("# inspection_robot arm trajectory v1\nt_s,x_mm,y_mm,z_mm,roll_deg,pitch_deg,yaw_deg\n"
                    "0.0,0,0,0,0,0,0\n1.0,9999,0,0,0,0,0\n")
        outside = "/etc/passwd"
        cases = (("set_position", "abc,0,0", "x must be a number"), ("set_position", "1,2", "3 comma-separated"),
                 ("set_position", "1,2,3,4", "3 comma-separated"), ("set_position", "700,0,0", "x out of range"),
                 ("set_orientation", "0,95,0", "pitch out of range"), ("set_position", "nan,0,0", "finite"),
                 ("move", "+,x,0", "y must be one of"), ("rotate", "++,0,0", "roll must be one of"),
                 ("stop_rotate", "-,0,0", "roll must be one of"), ("dance", "", "unknown command"),
                 ("play_orbit", "../../etc/passwd,+", "outside the allowed roots"),
                 ("play_orbit", outside + ",+", "outside the allowed roots"),
                 ("play_orbit", "orbit_a.csv,x", "direction must be one of"),
                 ("play_orbit", "missing.csv,+", "cannot read"),
                 ("play_orbit", "bad.csv,+", "outside the arm's limits"),
                 ("play_orbit", "nocomma", "file,+"),
                 ("record_orbit", "../escape.csv", "outside the allowed roots"),
                 ("stop_orbit", "", "not recording"), ("get_position", "x", "no data"))
        for name, run in self.both():
            for cmd, data, reason in cases:
                with self.subTest(twin=name, cmd=cmd, data=data):
                    reply = run(cmd, data)
                    self.assertEqual(reply.ack, "failed", reply.data)
                    self.assertIn(reason, reply.data)
        self.assertEqual(self.call("get_position").data, "10.00,20.00,30.00")
        self.assertEqual(self.call("get_orientation").data, "0.00,0.00,0.00")

    def test_joystick_busy_rule(self):
        self.control.publish(ControlStatus(mode=2))
        wait_for(lambda: self.call("get_position").data == "busy", 3.0, "busy")
        for name, run in self.both():
            with self.subTest(twin=name):
                reply = run("set_position", "5,5,5")
                self.assertEqual((reply.ack, reply.data), ("failed", "busy"))
                self.assertEqual(run("get_position", "", "joy_control").ack, "success")
        self.control.publish(ControlStatus(mode=0))
        wait_for(lambda: self.call("get_position").ack == "success", 3.0, "not busy")
        self.assertEqual(self.call("get_position").data, "0.00,0.00,0.00")


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_ptz_arm", ArmTest)
