#!/usr/bin/env python3
"""rostest: camera_node with the Hikvision ISAPI driver against a local fake ISAPI camera.

Covers the digest challenge, every camera command reaching the documented endpoint, the snapshot
fallback, and an unreachable camera: clear failure, sensor_status bit 0, then recovery.
"""
import os
import shutil
import unittest

import roslaunch
import rospy
import rostest
import yaml

from inspection_robot.interface import SENSOR_CAMERA_ALARM
from inspection_robot.msg import GeneralAck, GeneralCmd, RobotStatus
from inspection_robot_testing.fake_isapi import FakeIsapiCamera
from rostest_helpers import Latest, control_proxy, wait_for, wait_subscribed

ROOT = "/tmp/ir_camera_isapi_rostest"
PKG = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


class CameraIsapiTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_camera_isapi")
        shutil.rmtree(ROOT, ignore_errors=True)
        os.makedirs(ROOT)
        cls.fake = FakeIsapiCamera(user="admin", password="s3cret").start()
        optics = yaml.safe_load(open(os.path.join(PKG, "config", "camera_optics.yaml")))["camera_optics"]
        rospy.set_param("camera_node", {"driver": "isapi", "camera_optics": optics, "roots": [ROOT],
                                        "image_rate": 0.0, "status_rate": 5.0,
                                        "isapi": {"url": cls.fake.url, "user": "admin", "password": "s3cret",
                                                  "timeout": 1.0}})
        cls.launch = roslaunch.scriptapi.ROSLaunch()
        cls.launch.start()
        cls.process = cls.launch.launch(roslaunch.core.Node("inspection_robot", "camera_node", name="camera_node",
                                                            output="screen"))
        cls.control = control_proxy("camera_control", 20.0)
        cls.status = Latest("robot_status", RobotStatus)
        cls.acks = Latest("camera_ack", GeneralAck)
        cls.cmd = rospy.Publisher("camera_cmd", GeneralCmd, queue_size=10)
        wait_subscribed(cls.cmd, 10.0)
        cls.acks.wait_connected(10.0)

    @classmethod
    def tearDownClass(cls):
        cls.process.stop()
        cls.launch.stop()
        cls.fake.stop()

    def call(self, cmd, data=""):
        resp = self.control(sender="server", trans_id=7, cmd=cmd, data=data)
        self.assertEqual(resp.trans_id, 7)
        return resp.ack, resp.data

    def last_put(self, fragment):
        puts = [body for method, path, body in self.fake.requests if method == "PUT" and fragment in path]
        self.assertTrue(puts, "no PUT to %s" % fragment)
        return puts[-1]

    def test_a_every_command_reaches_the_camera(self):
        cases = [("set_zoom_level", "4", "", "absolute", "<absoluteZoom>40</absoluteZoom>"),
                 ("get_zoom_level", "", "4.00", None, None),
                 ("set_focus_mode", "semiauto", "", "focusConfiguration", "SEMIAUTOMATIC"),
                 ("get_focus_mode", "", "semiauto", None, None),
                 ("set_focus_position", "0xA000", "", "absoluteEx", "<focus>40960</focus>"),
                 ("get_focus_position", "", "40960", None, None),
                 ("zoom_in", "0", "", "continuous", "<zoom>60</zoom>"),
                 ("zoom_out", "0", "", "continuous", "<zoom>-60</zoom>"),
                 ("focus_far", "0", "", "inputs/channels/1/focus", "<focus>60</focus>"),
                 ("focus_near", "0", "", "inputs/channels/1/focus", "<focus>-60</focus>"),
                 ("camera_stop", "", "", "inputs/channels/1/focus", "<focus>0</focus>"),
                 ("set_osd_mode", "0", "", "overlays", "<enabled>false</enabled>"),
                 ("set_min_focus_distance", "1000", "", "focusConfiguration", "<focusLimited>1000</focusLimited>"),
                 ("get_min_focus_distance", "", "1000", None, None),
                 ("set_wdr_level", "33", "", "WDR", "<WDRLevel>33</WDRLevel>"),
                 ("get_wdr_level", "", "33", None, None),
                 ("set_wdr_mode", "1", "", "WDR", "<mode>open</mode>"),
                 ("get_wdr_mode", "", "1", None, None),
                 ("set_exposure_mode", "manual", "", "exposure", "<ExposureType>manual</ExposureType>"),
                 ("get_exposure_mode", "", "manual", None, None),
                 ("set_iris", "1100", "", "Iris", "<IrisLevel>1100</IrisLevel>"),
                 ("get_iris", "", "1100", None, None)]
        for cmd, data, expected, path, fragment in cases:
            self.assertEqual(self.call(cmd, data), ("success", expected), cmd)
            if path:
                self.assertIn(fragment, self.last_put(path), cmd)
        self.assertEqual(self.fake.continuous, {"zoom": 0, "focus": 0})   # camera_stop stopped both
        self.assertGreater(self.fake.challenges, 0)    # every exchange went through a digest challenge
        picture = os.path.join(ROOT, "shot.jpg")
        self.assertEqual(self.call("capture_picture", picture), ("success", picture))
        with open(picture, "rb") as stream:
            self.assertEqual(stream.read(), self.fake.picture)
        # topic twin with trans_id echo
        self.cmd.publish(GeneralCmd(sender="server", trans_id=4242, cmd="get_wdr_level"))
        ack = self.acks.wait(lambda m: m.trans_id == 4242, 5.0, "ack 4242")
        self.assertEqual((ack.ack, ack.data, ack.receiver, ack.sender), ("success", "33", "server", "camera_node"))

    def test_b_snapshot_fallback(self):
        self.fake.picture_endpoint = False
        try:
            picture = os.path.join(ROOT, "fallback.jpg")
            self.assertEqual(self.call("capture_picture", picture), ("success", picture))
            self.assertTrue(any("/onvif-http/snapshot" in path for _, path, _ in self.fake.requests))
        finally:
            self.fake.picture_endpoint = True

    def test_c_unreachable_camera_sets_the_sensor_bit_and_recovers(self):
        self.status.wait(lambda m: not m.sensor_status & SENSOR_CAMERA_ALARM, 5.0, "camera healthy")
        self.fake.stop()
        try:
            ack, reason = self.call("get_zoom_level")
            self.assertEqual(ack, "failed")
            self.assertIn("unreachable", reason)
            self.assertEqual(self.call("capture_picture", os.path.join(ROOT, "none.jpg"))[0], "failed")
            self.status.wait(lambda m: m.sensor_status & SENSOR_CAMERA_ALARM, 5.0, "sensor_status camera bit")
        finally:
            self.fake.start()   # same port: the camera is back
        self.status.wait(lambda m: not m.sensor_status & SENSOR_CAMERA_ALARM, 5.0, "camera bit cleared")
        wait_for(lambda: self.call("get_zoom_level")[0] == "success", 3.0, "camera answers again")


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_camera_isapi", CameraIsapiTest)
