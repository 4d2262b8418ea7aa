#!/usr/bin/env python3
"""rostest: joystick device (a FIFO fed with js_event bytes) -> joystick_reader -> joy_control -> robot_control."""
import os
import time
import unittest

import rospy
import rostest
from geometry_msgs.msg import TwistStamped
from sensor_msgs.msg import Joy

from inspection_robot.interface import LIGHT_SOFT_ESTOP, MODE_JOY, MODE_TASK
from inspection_robot.motion.joystick import JS_EVENT_AXIS, JS_EVENT_BUTTON, JS_EVENT_INIT, js_event
from inspection_robot.msg import ControlStatus, GeneralCmd
from rostest_helpers import Latest, wait_for

# config/joy_control.yaml
DEADMAN, ACQUIRE, RELEASE, ESTOP, ESTOP_RELEASE = 4, 7, 6, 1, 2
AXIS_X, AXIS_PAN = 1, 3


class JoystickTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_motion_joystick")
        cls.device = rospy.get_param("~device")
        if os.path.exists(cls.device):
            os.unlink(cls.device)
        os.mkfifo(cls.device)
        cls.fd = None
        cls.joy = Latest("joy", Joy)
        cls.status = Latest("control_status", ControlStatus, queue_size=1000)
        cls.driver = Latest("sim/chassis_cmd", TwistStamped, queue_size=1000)
        cls.terrace = Latest("terrace_cmd", GeneralCmd)
        for sub in (cls.status, cls.driver, cls.terrace):
            sub.wait_connected(10.0)

    @classmethod
    def tearDownClass(cls):
        if cls.fd is not None:
            os.close(cls.fd)
        os.unlink(cls.device)

    def connect(self):
        if JoystickTest.fd is None:
            JoystickTest.fd = os.open(self.device, os.O_RDWR)  # O_RDWR: does not wait for the reader
            self.send(js_event(JS_EVENT_BUTTON | JS_EVENT_INIT, 7, 0) + js_event(JS_EVENT_AXIS | JS_EVENT_INIT, 4, 0))
            self.joy.wait(lambda m: len(m.buttons) == 8 and len(m.axes) == 5, 5.0, "joy from the reader")

    def send(self, data):
        os.write(JoystickTest.fd, data)

    def button(self, number, pressed):
        self.send(js_event(JS_EVENT_BUTTON, number, 1 if pressed else 0))

    def click(self, number):
        self.button(number, True)
        self.joy.wait(lambda m: m.buttons[number] == 1, 2.0, "button %d down" % number)
        self.button(number, False)
        self.joy.wait(lambda m: m.buttons[number] == 0, 2.0, "button %d up" % number)

    def wait_driver(self, predicate, since, timeout, what):
        def found():
            return [m for _t, m in self.driver.messages[-200:] if m.header.stamp.to_sec() >= since and predicate(m)]
        return wait_for(found, timeout, what)[0]

    def test_1_acquire_move_deadman_release(self):
        self.connect()
        # joy_control's mode_cmd connection to robot_control may still be forming right after
        # start-up: press acquire again until the mode is taken (a repeat acquire is harmless)
        self.status.handshake(lambda: self.click(ACQUIRE), lambda m: m.mode == MODE_JOY, 10.0, period=1.0)
        since = rospy.get_time()
        self.send(js_event(JS_EVENT_AXIS, AXIS_X, -32767))  # stick fully up: forward
        self.button(DEADMAN, True)
        self.wait_driver(lambda m: abs(m.twist.linear.x - 0.8) < 1e-9, since, 2.0, "forward at 0.8 m/s")
        released = rospy.get_time()
        self.button(DEADMAN, False)
        stop = self.wait_driver(lambda m: m.twist.linear.x == 0.0, released, 1.0, "dead-man stop")
        self.assertLess(stop.header.stamp.to_sec() - released, 0.2)
        self.send(js_event(JS_EVENT_AXIS, AXIS_X, 0))

    def test_2_pan_tilt_and_estop(self):
        self.connect()
        self.send(js_event(JS_EVENT_AXIS, AXIS_PAN, -30000))  # right stick left: pan_left
        msg = self.terrace.wait(lambda m: m.cmd == "pan_left", 2.0, "pan_left")
        self.assertEqual((msg.sender, msg.data), ("joy_control", "mid_speed"))
        self.send(js_event(JS_EVENT_AXIS, AXIS_PAN, 0))
        self.terrace.wait(lambda m: m.cmd == "terrace_stop", 2.0, "terrace_stop")
        self.click(ESTOP)
        self.status.wait(lambda m: m.light_status & LIGHT_SOFT_ESTOP, 2.0, "soft e-stop from the joystick")
        self.click(ESTOP_RELEASE)
        self.status.wait(lambda m: not m.light_status & LIGHT_SOFT_ESTOP, 2.0, "e-stop released")

    def test_3_device_loss_stops(self):
        self.connect()
        if self.status.last.mode != MODE_JOY:
            self.click(ACQUIRE)
            self.status.wait(lambda m: m.mode == MODE_JOY, 2.0, "joystick mode")
        since = rospy.get_time()
        self.send(js_event(JS_EVENT_AXIS, AXIS_X, -16000))
        self.button(DEADMAN, True)
        self.wait_driver(lambda m: m.twist.linear.x > 0.3, since, 2.0, "moving")
        lost = rospy.get_time()
        os.close(JoystickTest.fd)  # unplugged while the dead-man is held
        JoystickTest.fd = None
        stop = self.wait_driver(lambda m: m.twist.linear.x == 0.0, lost, 2.0, "stop after device loss")
        self.assertLess(stop.header.stamp.to_sec() - lost, 0.8)
        t = time.monotonic()
        self.status.wait(lambda m: time.monotonic() > t, 1.0, "robot_control alive")
        self.connect()
        self.click(RELEASE)
        self.status.wait(lambda m: m.mode == MODE_TASK, 2.0, "released to task mode")


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_motion_joystick", JoystickTest)
