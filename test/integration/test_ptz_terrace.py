#!/usr/bin/env python3
"""rostest: cloud_terrace against the simulated Pelco-D head over a pty (every command, both twins)."""
import math
import unittest

import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from inspection_robot.camera.optics import ZoomOptics
from inspection_robot.msg import ControlStatus, PresetRotate
from rostest_helpers import Latest, TwinClient, control_proxy, wait_for, wait_subscribed


class TerraceTest(unittest.TestCase):
    trans_id = 50000  # preset_rotate ids; TwinClient numbers its own from 1000

    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_ptz_terrace")
        cls.terrace = TwinClient("terrace_control", "terrace_cmd", "terrace_ack", "cloud_terrace")
        cls.acks = cls.terrace.acks
        cls.sim = control_proxy("sim_pelco_head/sim_control", 10.0)
        cls.state = Latest("terrace_state", JointState, queue_size=100)
        cls.diagnostics = Latest("diagnostics", DiagnosticArray, queue_size=100)
        cls.control = rospy.Publisher("control_status", ControlStatus, queue_size=10, latch=True)
        cls.rotate = rospy.Publisher("preset_rotate", PresetRotate, queue_size=10)
        cls.zoom = rospy.Publisher("camera_zoom", Float64, queue_size=1, latch=True)
        for pub in (cls.control, cls.rotate, cls.zoom):
            wait_subscribed(pub)
        cls.control.publish(ControlStatus(mode=0))
        wait_for(lambda: cls.call("get_angle").ack == "success", 10.0, "head answering")

    def tearDown(self):
        self.sim_cmd("fault", "none")
        self.sim_cmd("replug")
        self.control.publish(ControlStatus(mode=0))
        wait_for(lambda: self.call("get_angle").ack == "success", 5.0, "head answering again")

    @classmethod
    def call(cls, cmd, data="", sender="server"):
        return cls.terrace.call(cmd, data, sender)

    def topic(self, cmd, data="", sender="server"):
        return self.terrace.topic(cmd, data, sender)

    def sim_cmd(self, cmd, data=""):
        reply = self.sim(cmd=cmd, data=data)
        self.assertEqual(reply.ack, "success", reply.data)
        return reply.data

    def sim_state(self):
        pan, tilt, wiper, lamp = (int(v) for v in self.sim_cmd("get_state").split(","))
        return pan, tilt, wiper, lamp

    def both(self):
        return self.terrace.both()

    def test_set_and_get_angles_both_twins(self):
        for name, run in self.both():
            with self.subTest(twin=name):
                reply = run("set_angle", "12300,-300")
                self.assertEqual((reply.ack, reply.data), ("success", ""))
                self.assertEqual(run("get_angle").data, "12300,-300")
                self.assertEqual(self.sim_state()[:2], (12300, -300))
                self.assertEqual(run("set_pan_angle", "-4550").ack, "success")
                self.assertEqual(run("get_pan_angle").data, "-4550")
                self.assertEqual(run("set_tilt_angle", "4500").ack, "success")
                self.assertEqual(run("get_tilt_angle").data, "4500")
                self.assertEqual(run("get_angle").data, "-4550,4500")
                self.assertEqual(run("set_angle", "18000,9000").ack, "success")
                self.assertEqual(run("get_angle").data, "18000,9000")
                self.assertEqual(run("set_angle", "0,0").ack, "success")

    def test_terrace_state_is_standard_radians(self):
        self.assertEqual(self.call("set_angle", "9000,-4500").ack, "success")
        msg = self.state.wait(lambda m: abs(m.position[0] - math.pi / 2) < 1e-3, 2.0, "terrace_state")
        self.assertEqual(list(msg.name), ["pan", "tilt"])
        self.assertAlmostEqual(msg.position[1], -math.pi / 4, places=3)

    def test_directional_moves_and_stop_both_twins(self):
        cases = (("pan_left", 0, +1), ("pan_right", 0, -1), ("tilt_up", 1, -1), ("tilt_down", 1, +1))
        for name, run in self.both():
            for cmd, axis, sign in cases:
                with self.subTest(twin=name, cmd=cmd):
                    self.assertEqual(self.call("set_angle", "0,0").ack, "success")
                    self.assertEqual(run(cmd, "high_speed").ack, "success")
                    wait_for(lambda: sign * self.sim_state()[axis] > 300, 3.0, "%s moving" % cmd)
                    self.assertEqual(run("terrace_stop").ack, "success")
                    # the ack means the stop frame is on the wire; the head acts when it reads it
                    wait_for(lambda: self.sim_cmd("get_motion") == "still", 2.0, "%s stopped at the head" % cmd)
                    still = self.sim_state()
                    rospy.sleep(0.2)   # measuring that nothing moves needs an interval
                    self.assertEqual(self.sim_state()[:2], still[:2])
        self.assertEqual(self.call("set_angle", "0,0").ack, "success")

    def test_speed_classes_differ(self):
        rates = {}
        for speed in ("high_speed", "low_speed"):
            self.assertEqual(self.call("set_angle", "0,0").ack, "success")
            self.assertEqual(self.call("pan_left", speed).ack, "success")
            start = rospy.get_time()
            wait_for(lambda: self.sim_state()[0] > 200, 5.0, "pan moving at %s" % speed)
            rates[speed] = self.sim_state()[0] / (rospy.get_time() - start)
            self.assertEqual(self.call("terrace_stop").ack, "success")
        self.assertGreater(rates["high_speed"], 3 * rates["low_speed"])

    def test_wiper_and_lamp_both_twins(self):
        for name, run in self.both():
            with self.subTest(twin=name):
                for cmd, index, value in (("brush_on", 2, 1), ("light_on", 3, 1), ("brush_off", 2, 0),
                                          ("light_off", 3, 0)):
                    self.assertEqual(run(cmd).ack, "success")
                    wait_for(lambda: self.sim_state()[index] == value, 2.0, "%s applied" % cmd)

    def test_bad_input_fails_and_nothing_moves(self):
        self.assertEqual(self.call("set_angle", "1000,1000").ack, "success")
        before = self.sim_state()
        cases = (("set_angle", "abc", "comma-separated"), ("set_angle", "abc,0", "pan must be an integer"),
                 ("set_angle", "1,2,3", "2 comma-separated"),
                 ("set_pan_angle", "18001", "out of range"), ("set_pan_angle", "-18000", "out of range"),
                 ("set_tilt_angle", "9001", "out of range"), ("set_pan_angle", "123.5", "integer"),
                 ("set_pan_angle", "", "missing"), ("set_angle", "100, 200", "spaces"),
                 ("pan_left", "warp_speed", "speed"), ("tilt_up", "", "speed"), ("fly", "", "unknown command"),
                 ("terrace_stop", "now", "no data"), ("get_angle", "x", "no data"))
        for name, run in self.both():
            for cmd, data, reason in cases:
                with self.subTest(twin=name, cmd=cmd, data=data):
                    reply = run(cmd, data)
                    self.assertEqual(reply.ack, "failed")
                    self.assertIn(reason, reply.data)
        self.assertEqual(self.sim_state(), before)

    def test_joystick_busy_rule(self):
        self.control.publish(ControlStatus(mode=2))
        wait_for(lambda: self.call("get_angle").data == "busy", 3.0, "busy under joystick")
        for name, run in self.both():
            with self.subTest(twin=name):
                self.assertEqual((run("set_angle", "500,500").ack, run("set_angle", "500,500").data),
                                 ("failed", "busy"))
                self.assertEqual(run("set_angle", "600,600", "joy_control").ack, "success")
        self.assertEqual(self.sim_state()[:2], (600, 600))
        self.control.publish(ControlStatus(mode=0))
        wait_for(lambda: self.call("get_angle").ack == "success", 3.0, "not busy after joystick")

    def test_unplugged_head_fails_clearly_then_recovers(self):
        self.sim_cmd("unplug")
        reply = wait_for(lambda: (lambda r: r if r.ack == "failed" else None)(self.call("get_angle")), 3.0,
                         "failure while unplugged")
        self.assertIn("head", reply.data)
        self.assertEqual(self.call("set_angle", "100,100").ack, "failed")
        self.diagnostics.wait(lambda m: any(s.hardware_id == "pan_tilt_head" and s.level == DiagnosticStatus.ERROR
                                            for s in m.status), 3.0, "diagnostics ERROR")
        self.sim_cmd("replug")
        wait_for(lambda: self.call("get_angle").ack == "success", 5.0, "recovery after replug")
        self.assertEqual(self.call("set_angle", "2000,-1000").ack, "success")
        self.assertEqual(self.call("get_angle").data, "2000,-1000")
        self.diagnostics.wait(lambda m: any(s.hardware_id == "pan_tilt_head" and s.level == DiagnosticStatus.OK
                                            for s in m.status), 3.0, "diagnostics OK")

    def test_faults_silence_checksum_garbage(self):
        self.sim_cmd("fault", "silence")
        reply = self.call("get_pan_angle")
        self.assertEqual(reply.ack, "failed")
        self.assertIn("no reply", reply.data)
        self.assertIn("did not reach", self.call("set_pan_angle", "100").data)
        self.sim_cmd("fault", "bad_checksum")
        self.assertIn("no reply", self.call("get_tilt_angle").data)
        self.sim_cmd("fault", "garbage")
        for _ in range(20):
            self.assertEqual(self.call("get_angle").ack, "success")
        self.assertEqual(self.call("set_angle", "-3000,2000").ack, "success")
        self.assertEqual(self.call("get_angle").data, "-3000,2000")

    def rotate_and_check(self, start, zoom, width, height, dx, dy):
        self.assertEqual(self.call("set_angle", "%d,%d" % start).ack, "success")
        self.diagnostics.clear()
        self.zoom.publish(Float64(zoom))
        # camera_zoom and preset_rotate are separate connections: rotate once the head node has the zoom
        wait_for(lambda: any(s.hardware_id == "pan_tilt_head" and
                             any(kv.key == "camera_zoom" and float(kv.value) == zoom for kv in s.values)
                             for _, m in list(self.diagnostics.messages) for s in m.status),
                 5.0, "camera_zoom %g heard by cloud_terrace" % zoom)
        optics_param = rospy.get_param("cloud_terrace/camera_optics")
        optics = ZoomOptics(optics_param["zoom_hfov_deg"], optics_param["width"], optics_param["height"])
        focal = optics.focal_px(zoom, width)
        # the pixel's ray in the base frame (x forward, y left, z up) from the start orientation
        pan0, tilt0 = math.radians(start[0] / 100.0), math.radians(start[1] / 100.0)
        cam = (focal, -dx, dy)
        x = cam[0] * math.cos(tilt0) + cam[2] * math.sin(tilt0)
        z = -cam[0] * math.sin(tilt0) + cam[2] * math.cos(tilt0)
        y = cam[1]
        x, y = x * math.cos(pan0) - y * math.sin(pan0), x * math.sin(pan0) + y * math.cos(pan0)
        want_pan, want_tilt = math.degrees(math.atan2(y, x)), math.degrees(math.atan2(-z, math.hypot(x, y)))
        TerraceTest.trans_id += 1
        tid = TerraceTest.trans_id
        self.rotate.publish(PresetRotate(sender="server", trans_id=tid, width=width, height=height,
                                         delta_x=dx, delta_y=dy))
        ack = self.acks.wait(lambda m: m.trans_id == tid, 6.0, "preset_rotate outcome")
        self.assertEqual(ack.ack, "success", ack.data)
        pan, tilt = self.sim_state()[:2]
        self.assertLess(abs(pan / 100.0 - want_pan), 0.5)
        self.assertLess(abs(tilt / 100.0 - want_tilt), 0.5)
        return pan, tilt

    def test_preset_rotate_centres_the_pixel(self):
        pan, tilt = self.rotate_and_check((0, 0), 1.0, 1920, 1080, 480, 270)
        self.assertLess(pan, -1000)      # right of centre: pan clockwise (negative)
        self.assertLess(tilt, -500)      # above centre: tilt up (negative)
        self.rotate_and_check((4500, 2000), 4.0, 1920, 1080, -300, -200)
        self.rotate_and_check((-17000, -3000), 30.0, 640, 360, 100, 50)

    def test_preset_rotate_bad_input_and_busy(self):
        self.assertEqual(self.call("set_angle", "0,0").ack, "success")
        for tid, msg in ((9001, PresetRotate(width=0, height=1080, delta_x=1, delta_y=1)),
                         (9002, PresetRotate(width=1920, height=1080, delta_x=5000, delta_y=0))):
            msg.trans_id, msg.sender = tid, "server"
            self.rotate.publish(msg)
            ack = self.acks.wait(lambda m: m.trans_id == tid, 3.0, "preset_rotate refusal")
            self.assertEqual(ack.ack, "failed")
        self.control.publish(ControlStatus(mode=2))
        wait_for(lambda: self.call("get_angle").data == "busy", 3.0, "busy under joystick")
        self.rotate.publish(PresetRotate(sender="server", trans_id=9003, width=1920, height=1080, delta_x=100))
        ack = self.acks.wait(lambda m: m.trans_id == 9003, 3.0, "busy preset_rotate")
        self.assertEqual((ack.ack, ack.data), ("failed", "busy"))
        self.assertEqual(self.sim_state()[:2], (0, 0))


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_ptz_terrace", TerraceTest)
