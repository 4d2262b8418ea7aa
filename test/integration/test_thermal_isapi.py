#!/usr/bin/env python3
"""rostest: infrared_imager with the Hikvision ISAPI driver against the fake bi-spectrum camera.

End to end through the real driver: the temperatures of the camera's matrix, the radiometric file
and the camera's own picture, auto_focus unsupported on a fixed lens; refused credentials and a
device answering garbage fail with the setting to check and raise sensor_status bit 1; a camera
restart is picked up again without restarting the node.
"""
import json
import os
import shutil
import unittest

import numpy as np
import roslaunch
import rospy
import rostest
from sensor_msgs.msg import Image

from inspection_robot.interface import SENSOR_THERMAL_ALARM
from inspection_robot.msg import GeneralTopic, RobotStatus
from inspection_robot_testing.fake_isapi import FakeIsapiCamera
from inspection_robot.thermal.commands import load_radiometric
from rostest_helpers import Latest, control_proxy, wait_for

ROOT = "/tmp/ir_thermal_isapi_rostest"


class ThermalIsapiTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_thermal_isapi")
        shutil.rmtree(ROOT, ignore_errors=True)
        os.makedirs(ROOT)
        password_file = os.path.join(ROOT, "thermal_password")
        with open(os.open(password_file, os.O_WRONLY | os.O_CREAT, 0o600), "w") as stream:
            stream.write("th3rmal\n")
        cls.fake = FakeIsapiCamera(user="operator", password="th3rmal").start()
        rospy.set_param("infrared_imager", {
            "driver": "isapi", "roots": [os.path.join(ROOT, "out")], "status_rate": 5.0, "image_rate": 5.0,
            "isapi": {"host": "127.0.0.1", "port": cls.fake.port, "user": "operator", "password_file": password_file,
                      "channel": 2, "timeout": 1.0, "picture_timeout": 2.0}})
        cls.launch = roslaunch.scriptapi.ROSLaunch()
        cls.launch.start()
        cls.process = cls.launch.launch(roslaunch.core.Node("inspection_robot", "infrared_imager",
                                                            name="infrared_imager", output="screen"))
        cls.control = control_proxy("infrared_control", 30.0)
        cls.status = Latest("robot_status", RobotStatus)

    @classmethod
    def tearDownClass(cls):
        cls.process.stop()
        cls.launch.stop()
        cls.fake.stop()

    def call(self, cmd, data=""):
        resp = self.control(sender="server", trans_id=11, cmd=cmd, data=data)
        self.assertEqual(resp.trans_id, 11)
        return resp.ack, resp.data

    def out(self, name):
        return os.path.join(ROOT, "out", name)

    def test_a_temperatures_and_pictures_come_from_the_camera(self):
        self.status.wait(lambda m: not m.sensor_status & SENSOR_THERMAL_ALARM, 10.0, "thermal imager healthy")
        self.assertEqual(self.call("get_spot_temperature", "200,100"), ("success", "95.25"))
        self.assertEqual(self.call("get_spot_temperature", "0,5"), ("success", "18.00"))
        self.assertEqual(self.call("get_high_temperature"), ("success", "95.25"))
        self.assertEqual(self.call("get_low_temperature"), ("success", "18.00"))
        self.assertEqual(self.call("set_measure_spot", "205,100"), ("success", ""))
        self.assertEqual(self.call("get_max_temperature"), ("success", "95.25"))
        self.assertEqual(self.call("set_measure_spot", "300,200"), ("success", ""))
        area = self.fake.thermal_frame[192:208, 292:308]   # measure_box_px 16 around (300, 200)
        self.assertEqual(self.call("get_max_temperature"), ("success", "%.2f" % area.max()))
        self.assertEqual(self.call("save_temperature", self.out("t.png")), ("success", self.out("t.png")))
        self.assertTrue(np.allclose(load_radiometric(self.out("t.png")), self.fake.thermal_frame, atol=0.006))
        self.assertEqual(self.call("capture_picture", self.out("p.jpg")), ("success", self.out("p.jpg")))
        with open(self.out("p.jpg"), "rb") as stream:   # the JPEG of jpegPicWithAppendData, as sent
            self.assertEqual(stream.read(), self.fake.thermal_picture)
        self.assertEqual(self.call("auto_focus"), ("failed", "unsupported"))   # the fake has a fixed lens
        self.assertGreater(self.fake.challenges, 0)   # digest challenges were answered
        paths = [path for _, path, _ in self.fake.requests]
        self.assertIn("/ISAPI/Thermal/channels/2/thermometry/jpegPicWithAppendData?format=json", paths)
        # the status probe runs on infrared_imager's status timer: its first tick may come after the above
        probe = "/ISAPI/Thermal/channels/2/thermometry/basicParam"
        wait_for(lambda: probe in [path for _, path, _ in list(self.fake.requests)], 10.0, "the status probe")
        hottest = Latest("thermal/hottest", GeneralTopic)
        image = Latest("thermal/image_raw", Image)
        self.assertEqual(json.loads(hottest.wait(timeout=10.0, what="thermal/hottest").data)["temperature"], 95.25)
        self.assertEqual((image.wait(timeout=10.0, what="thermal/image_raw").width, image.last.height), (384, 288))

    def assert_failure_then_recovery(self, fault_on, fault_off, words):
        self.status.wait(lambda m: not m.sensor_status & SENSOR_THERMAL_ALARM, 10.0, "thermal imager healthy")
        fault_on()
        try:
            ack, reason = self.call("get_high_temperature")
            self.assertEqual(ack, "failed")
            for word in words:
                self.assertIn(word, reason)
            self.assertEqual(self.call("save_temperature", self.out("never.png"))[0], "failed")
            self.assertFalse(os.path.exists(self.out("never.png")))   # nothing written
            self.status.wait(lambda m: m.sensor_status & SENSOR_THERMAL_ALARM, 10.0, "sensor_status thermal bit")
        finally:
            fault_off()
        self.status.wait(lambda m: not m.sensor_status & SENSOR_THERMAL_ALARM, 10.0, "thermal bit cleared")
        wait_for(lambda: self.call("get_high_temperature") == ("success", "95.25"), 5.0, "temperatures again")

    def test_b_refused_credentials_name_the_settings(self):
        self.assert_failure_then_recovery(lambda: self.fake.set_fault("401"), lambda: self.fake.set_fault(None),
                                          ["HTTP 401", "~isapi/user", "~isapi/password_file"])

    def test_c_garbage_names_the_device_settings(self):
        self.assert_failure_then_recovery(lambda: self.fake.set_fault("garbage"),
                                          lambda: self.fake.set_fault(None),
                                          ["no radiometric picture", "~isapi/host", "~isapi/port", "~isapi/channel"])

    def test_d_camera_restart_is_picked_up(self):
        self.assert_failure_then_recovery(self.fake.stop, self.fake.start, ["unreachable", "~isapi/host"])


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_thermal_isapi", ThermalIsapiTest)
