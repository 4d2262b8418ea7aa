#!/usr/bin/env python3
"""rostest: camera_node and infrared_imager against the simulated world (every command, both twins)."""
import math
import os
import shutil
import unittest

import cv2
import numpy as np
import rospy
import rostest
import yaml
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseWithCovarianceStamped
from sensor_msgs.msg import CameraInfo, CompressedImage, Image, JointState
from std_msgs.msg import Float64

from inspection_robot.camera.optics import ZoomOptics
from inspection_robot.msg import ControlStatus, GeneralAck, GeneralCmd
from inspection_robot.camera.optics import focal_for_hfov
from inspection_robot.sim.render import PinholeCamera, ground_truth
from inspection_robot.sim.world import World
from inspection_robot.thermal.commands import load_radiometric
from rostest_helpers import Latest, control_proxy, wait_for, wait_subscribed

ROOT = "/tmp/ir_camera_rostest"
PKG = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def view_of(quad, distance, sensor_height):
    """(pose, tilt) of a robot ``distance`` m in front of ``quad`` with the optical axis through its centre."""
    x, y, z = quad.centre
    nx, ny = quad.normal[0], quad.normal[1]
    pose = (x + nx * distance, y + ny * distance, math.atan2(-ny, -nx))
    return pose, math.atan2(sensor_height - z, distance)


class CameraSimTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_camera_sim")
        shutil.rmtree(ROOT, ignore_errors=True)
        os.makedirs(ROOT)
        cls.world = World.load(os.path.join(PKG, "config", "sim_world.yaml"))
        optics = yaml.safe_load(open(os.path.join(PKG, "config", "camera_optics.yaml")))["camera_optics"]
        cls.optics = ZoomOptics(optics["zoom_hfov_deg"], optics["width"], optics["height"])
        cls.trans_id = 100
        cls.services = {}
        for name in ("camera_control", "infrared_control", "vendor/infrared_control", "sim/set_world_value",
                     "sim/get_world_value"):
            cls.services[name] = control_proxy(name, 20.0)
        cls.acks = {"camera": Latest("camera_ack", GeneralAck), "infrared": Latest("infrared_ack", GeneralAck)}
        cls.cmds = {"camera": rospy.Publisher("camera_cmd", GeneralCmd, queue_size=10),
                    "infrared": rospy.Publisher("infrared_cmd", GeneralCmd, queue_size=10)}
        cls.pose_pub = rospy.Publisher("sim/true_pose", PoseWithCovarianceStamped, queue_size=1, latch=True)
        cls.joint_pub = rospy.Publisher("terrace_state", JointState, queue_size=1, latch=True)
        cls.control_pub = rospy.Publisher("control_status", ControlStatus, queue_size=1, latch=True)
        cls.zoom = Latest("camera_zoom", Float64)
        for pub in list(cls.cmds.values()) + [cls.pose_pub, cls.joint_pub, cls.control_pub]:
            wait_subscribed(pub, 10.0)
        for latest in cls.acks.values():
            latest.wait_connected(10.0)

    def call(self, service, cmd, data="", sender="server"):
        CameraSimTest.trans_id += 1
        resp = self.services[service](sender=sender, trans_id=self.trans_id, cmd=cmd, data=data)
        self.assertEqual(resp.trans_id, self.trans_id)
        return resp.ack, resp.data

    def ok(self, service, cmd, data=""):
        ack, reply = self.call(service, cmd, data)
        self.assertEqual(ack, "success", "%s %s(%r): %s" % (service, cmd, data, reply))
        return reply

    def topic(self, device, cmd, data=""):
        CameraSimTest.trans_id += 1
        trans_id = self.trans_id
        self.cmds[device].publish(GeneralCmd(sender="server", trans_id=trans_id, cmd=cmd, data=data))
        ack = self.acks[device].wait(lambda m: m.trans_id == trans_id, 10.0, "%s ack %d" % (cmd, trans_id))
        self.assertEqual(ack.receiver, "server")
        return ack.ack, ack.data

    def aim(self, pose, pan, tilt):
        """Publish the robot pose and head angles (a test then waits until the pictures show that view)."""
        msg = PoseWithCovarianceStamped()
        msg.header.frame_id = "map"
        msg.pose.pose.position.x, msg.pose.pose.position.y = pose[0], pose[1]
        msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = math.sin(pose[2] / 2), math.cos(pose[2] / 2)
        self.pose_pub.publish(msg)
        self.joint_pub.publish(JointState(name=["pan", "tilt"], position=[pan, tilt]))

    # --- camera -------------------------------------------------------------------------
    def test_camera_every_command_via_service_and_topic(self):
        cases = [("set_zoom_level", "4", ""), ("get_zoom_level", "", "4.00"),
                 ("set_focus_mode", "manual", ""), ("get_focus_mode", "", "manual"),
                 ("set_focus_position", "0x2000", ""), ("get_focus_position", "", "8192"),
                 ("set_focus_position", "40000", ""), ("get_focus_position", "", "40000"),
                 ("set_osd_mode", "0", ""), ("set_osd_mode", "1", ""),
                 ("set_min_focus_distance", "300", ""), ("get_min_focus_distance", "", "300"),
                 ("set_wdr_level", "77", ""), ("get_wdr_level", "", "77"),
                 ("set_wdr_mode", "1", ""), ("get_wdr_mode", "", "1"),
                 ("set_exposure_mode", "manual", ""), ("get_exposure_mode", "", "manual"),
                 ("set_iris", "560", ""), ("get_iris", "", "560"),
                 ("set_exposure_mode", "auto", ""), ("get_exposure_mode", "", "auto"),
                 ("zoom_in", "0", None), ("camera_stop", "", ""), ("zoom_out", "100", None),
                 ("focus_far", "0", None), ("focus_near", "50", None), ("camera_stop", "", ""),
                 ("set_focus_mode", "auto", ""), ("set_zoom_level", "1", "")]
        for via in ("service", "topic"):
            for cmd, data, expected in cases:
                ack, reply = self.call("camera_control", cmd, data) if via == "service" else \
                    self.topic("camera", cmd, data)
                self.assertEqual(ack, "success", "%s via %s: %s" % (cmd, via, reply))
                if expected is not None:
                    self.assertEqual(reply, expected, "%s via %s" % (cmd, via))
            path = os.path.join(ROOT, via, "shot.jpg")
            ack, reply = self.call("camera_control", "capture_picture", path) if via == "service" else \
                self.topic("camera", "capture_picture", path)
            self.assertEqual((ack, reply), ("success", path))
            img = cv2.imread(path)
            self.assertEqual(img.shape, (1080, 1920, 3))

    def test_continuous_zoom_with_duration_stops_by_itself(self):
        self.ok("camera_control", "set_zoom_level", "2")
        self.ok("camera_control", "zoom_in", "300")
        wait_for(lambda: float(self.ok("camera_control", "get_zoom_level")) > 2.2, 3.0, "zoom moving")
        first = wait_for(lambda: self._stable_zoom(), 3.0, "zoom stopped")
        self.assertLess(first, 2.0 * 2.0 ** 0.6)   # 0.3 s at 2x/s, with slack for latency
        self.zoom.wait(lambda m: abs(m.data - first) < 0.02, 3.0, "camera_zoom latched at the final zoom")
        self.ok("camera_control", "set_zoom_level", "1")

    def _stable_zoom(self):
        a = float(self.ok("camera_control", "get_zoom_level"))
        rospy.sleep(0.1)
        b = float(self.ok("camera_control", "get_zoom_level"))
        return a if a == b and a > 2.0 else None

    def test_capture_at_two_zooms_shows_the_gauge_at_the_expected_scale(self):
        face = self.world.faces["transformer_1/oil_temp"]
        distance = 5.0
        pose, tilt = view_of(face.quad, distance, self.world.sensor_height)
        self.aim(pose, 0.0, tilt)
        extents = {}
        for zoom in (2.0, 4.0):
            self.ok("camera_control", "set_zoom_level", "%g" % zoom)
            path = os.path.join(ROOT, "zoom%g.jpg" % zoom)
            # the node may still render the previous view for one message latency: retry until centred
            expected = 2 * face.dial_layout()[2] * self.optics.focal_px(zoom) / distance
            extents[zoom] = wait_for(lambda: self._dial_extent(path, expected), 5.0, "gauge centred at zoom %g" % zoom)
            self.assertAlmostEqual(extents[zoom] / expected, 1.0, delta=0.05)
        self.assertAlmostEqual(extents[4.0] / extents[2.0],
                               self.optics.focal_px(4.0) / self.optics.focal_px(2.0), delta=0.06)
        truth = ground_truth(self.world, PinholeCamera.from_pose(pose, 0.0, tilt, self.world.sensor_height,
                                                                 self.optics.focal_px(4.0), 1920, 1080))
        self.assertTrue(truth["faces"][face.id]["visible"])

    def _dial_extent(self, path, expected):
        """Width in px of the bright dial along the picture's centre row, if it is centred."""
        self.ok("camera_control", "capture_picture", path)
        gray = cv2.cvtColor(cv2.imread(path), cv2.COLOR_BGR2GRAY)
        os.unlink(path)   # a capture never replaces a file: the next try needs the name free
        window = int(0.6 * expected)   # the dial only, not the neighbouring gauges
        extents = []
        # centred along both axes: the view the test aimed at, not the previous one still rendered
        # (a stale pose or head angle can centre another dial along one axis, never along both)
        for line in (gray[540, 960 - window:960 + window], gray[540 - window:540 + window, 960]):
            bright = np.nonzero(line > 185)[0] - window
            if len(bright) < 10 or abs((bright.min() + bright.max()) / 2.0) > 15:
                return None
            extents.append(float(bright.max() - bright.min()))
        return extents[0]

    def test_camera_bad_input(self):
        cases = [("set_zoom_level", "0.5"), ("set_zoom_level", "31"), ("set_zoom_level", "abc"),
                 ("set_zoom_level", " 2"), ("set_focus_mode", "blurry"), ("set_focus_position", "0x0FFF"),
                 ("set_focus_position", "49153"), ("set_focus_position", "0xZZ"), ("zoom_in", "-1"),
                 ("zoom_in", "fast"), ("focus_far", "1.5"), ("set_osd_mode", "2"), ("set_min_focus_distance", "50"),
                 ("set_wdr_level", "101"), ("set_wdr_level", "-1"), ("set_wdr_mode", "on"),
                 ("set_exposure_mode", "semi"), ("set_iris", "500"), ("capture_picture", ""),
                 ("capture_picture", "/etc/shadow.jpg"), ("capture_picture", ROOT + "/../escape.jpg"),
                 ("capture_picture", ROOT), ("no_such_command", "")]
        for cmd, data in cases:
            ack, reply = self.call("camera_control", cmd, data)
            self.assertEqual(ack, "failed", "%s(%r) -> %s" % (cmd, data, reply))
            self.assertTrue(reply, cmd)
        # iris needs manual exposure
        self.ok("camera_control", "set_exposure_mode", "auto")
        ack, reply = self.call("camera_control", "set_iris", "400")
        self.assertEqual(ack, "failed")
        self.assertIn("manual", reply)
        # unwritable folder inside the root
        locked = os.path.join(ROOT, "locked")
        os.makedirs(locked, exist_ok=True)
        os.chmod(locked, 0o500)
        try:
            if os.geteuid() != 0:
                ack, reply = self.call("camera_control", "capture_picture", os.path.join(locked, "x.jpg"))
                self.assertEqual(ack, "failed")
                self.assertIn("cannot write", reply)
        finally:
            os.chmod(locked, 0o700)
        self.assertEqual(self.topic("camera", "set_wdr_level", "x")[0], "failed")

    def test_captures_never_replace_a_file_nor_leave_the_root(self):
        """A capture onto an existing file (a calibrated preset's, in the finding) fails and the file
        stays; a path leaving the root or carrying junk fails before the camera is asked; nothing written."""
        kept = os.path.join(ROOT, "kept", "preset.ini")
        os.makedirs(os.path.dirname(kept), exist_ok=True)
        with open(kept, "w") as f:
            f.write("[preset]\ncalibrated = 1\n")
        outside = ROOT + "_outside"
        shutil.rmtree(outside, ignore_errors=True)
        os.makedirs(outside)
        link = os.path.join(ROOT, "link_out")
        if not os.path.islink(link):
            os.symlink(outside, link)
        before = sorted(os.walk(ROOT))
        cases = [(kept, "already exists"), ("kept/preset.ini", "already exists"),
                 ("kept/../kept/preset.ini", "contains '..'"), ("link_out/x.jpg", "outside the allowed roots"),
                 ("x.jpg\n", "control or unprintable character"), ("a\x01.jpg", "control or unprintable"),
                 ("n" * 300 + ".jpg", "has a name of 304 bytes"), ("d/" * 2100 + "x.jpg", "too long")]
        for service in ("camera_control", "infrared_control"):
            for data, reason in cases:
                ack, reply = self.call(service, "capture_picture", data)
                self.assertEqual(ack, "failed", "%s %r -> %s" % (service, data, reply))
                self.assertIn(reason, reply, "%s %r" % (service, data))
        ack, frame = self.call("infrared_control", "save_temperature", os.path.join(ROOT, "kept", "frame.png"))
        self.assertEqual(ack, "success", frame)
        self.assertEqual(self.call("infrared_control", "save_temperature", frame)[0], "failed")   # not twice
        os.unlink(frame)
        with open(kept) as f:
            self.assertEqual(f.read(), "[preset]\ncalibrated = 1\n")
        self.assertEqual(sorted(os.walk(ROOT)), before)
        self.assertEqual(os.listdir(outside), [])

    def test_joystick_busy_rule(self):
        try:
            self.control_pub.publish(ControlStatus(mode=2))
            # camera_node and infrared_imager each take control_status in their own time
            wait_for(lambda: self.call("camera_control", "get_zoom_level") == ("failed", "busy"), 3.0, "busy")
            wait_for(lambda: self.call("infrared_control", "get_high_temperature") == ("failed", "busy"), 3.0,
                     "thermal busy")
            self.assertEqual(self.topic("camera", "get_wdr_level"), ("failed", "busy"))
            ack, _ = self.call("camera_control", "get_zoom_level", sender="joy_control")
            self.assertEqual(ack, "success")
        finally:
            self.control_pub.publish(ControlStatus(mode=0))
            wait_for(lambda: self.call("camera_control", "get_zoom_level")[0] == "success", 3.0, "not busy")

    def test_image_topic_zoom_topic_and_diagnostics(self):
        images = Latest("camera/image_raw", Image, queue_size=5)
        infos = Latest("camera/camera_info", CameraInfo, queue_size=5)
        diagnostics = Latest("diagnostics", DiagnosticArray, queue_size=50)
        self.ok("camera_control", "set_zoom_level", "3")
        self.zoom.wait(lambda m: abs(m.data - 3.0) < 1e-6, 3.0, "camera_zoom 3")
        img = images.wait(timeout=5.0, what="image")
        self.assertEqual((img.width, img.height, img.encoding), (320, 180, "bgr8"))
        info = infos.wait(lambda m: abs(m.K[0] - self.optics.focal_px(3.0, 320)) < 0.5, 5.0, "camera_info at zoom 3")
        self.assertEqual(info.width, 320)
        for topic, size, frame_id in (("camera/image_raw/compressed", (180, 320), "camera_optical_frame"),
                                      ("thermal/image_raw/compressed", (288, 384), "thermal_imager")):
            jpeg = Latest(topic, CompressedImage, queue_size=5).wait(timeout=10.0, what=topic)
            picture = cv2.imdecode(np.frombuffer(jpeg.data, np.uint8), cv2.IMREAD_COLOR)
            self.assertEqual((jpeg.format, jpeg.header.frame_id, picture.shape[:2]), ("jpeg", frame_id, size))
            self.assertGreater(float(picture.std()), 5.0)   # a picture of the world, not a blank frame
        for hardware_id in ("camera", "thermal_imager"):
            status = diagnostics.wait(lambda m: m.status and m.status[0].hardware_id == hardware_id, 5.0, hardware_id)
            self.assertEqual(status.status[0].level, DiagnosticStatus.OK)
        self.ok("camera_control", "set_zoom_level", "1")

    # --- thermal ------------------------------------------------------------------------
    def thermal_view(self, spot_id, distance=6.0):
        spot = self.world.hot_spots[spot_id]
        pose, tilt = view_of(spot.quad, distance, self.world.sensor_height)
        self.aim(pose, 0.0, tilt)
        camera = PinholeCamera.from_pose(pose, 0.0, tilt, self.world.sensor_height, focal_for_hfov(384, 25.0), 384, 288)
        u, v = ground_truth(self.world, camera)["hot_spots"][spot_id]["center"]
        return int(round(u)), int(round(v))

    def test_thermal_every_command_and_spot_temperature(self):
        u, v = self.thermal_view("busbar_support/joint")
        spot = "%d,%d" % (u, v)
        wait_for(lambda: abs(float(self.ok("infrared_control", "get_spot_temperature", spot)) - 95.0) < 0.5, 5.0,
                 "spot temperature of the joint")
        for via in ("service", "topic"):
            run = (lambda c, d="": self.call("infrared_control", c, d)) if via == "service" else \
                (lambda c, d="": self.topic("infrared", c, d))
            self.assertEqual(run("set_measure_spot", spot), ("success", ""))
            ack, value = run("get_max_temperature")
            self.assertEqual(ack, "success")
            self.assertAlmostEqual(float(value), 95.0, delta=0.5)
            ack, value = run("get_spot_temperature", spot)
            self.assertAlmostEqual(float(value), 95.0, delta=0.5)
            ack, high = run("get_high_temperature")
            self.assertAlmostEqual(float(high), 95.0, delta=0.5)
            ack, low = run("get_low_temperature")
            self.assertEqual(ack, "success")
            self.assertLess(float(low), 33.0)
            self.assertEqual(run("auto_focus"), ("success", ""))
            png = os.path.join(ROOT, via, "frame.png")
            self.assertEqual(run("save_temperature", png), ("success", png))
            frame = load_radiometric(png)
            self.assertEqual(frame.shape, (288, 384))
            self.assertAlmostEqual(float(frame[v, u]), 95.0, delta=0.5)
            npy = os.path.join(ROOT, via, "frame.npy")
            self.assertEqual(run("save_temperature", npy), ("success", npy))
            self.assertAlmostEqual(float(np.load(npy)[v, u]), 95.0, delta=0.5)
            jpg = os.path.join(ROOT, via, "thermal.jpg")
            self.assertEqual(run("capture_picture", jpg), ("success", jpg))
            self.assertEqual(cv2.imread(jpg).shape, (288, 384, 3))

    def test_world_value_change_reaches_the_imager(self):
        u, v = self.thermal_view("transformer_1/bushing_a")
        spot = "%d,%d" % (u, v)
        self.assertEqual(self.call("sim/set_world_value", "transformer_1/bushing_a", "110.5"), ("success", "110.5"))
        self.assertEqual(self.call("sim/get_world_value", "transformer_1/bushing_a"), ("success", "110.5"))
        wait_for(lambda: abs(float(self.ok("infrared_control", "get_spot_temperature", spot)) - 110.5) < 0.5, 5.0,
                 "new hot spot temperature")
        self.assertEqual(self.call("sim/set_world_value", "transformer_1/bushing_a", "hot")[0], "failed")
        self.assertEqual(self.call("sim/set_world_value", "no/such", "1")[0], "failed")
        self.assertEqual(self.call("sim/set_world_value", "breaker_1/lamp_open", "on"), ("success", "on"))
        self.ok("sim/set_world_value", "transformer_1/bushing_a", "78")

    def test_a_new_day_warms_the_heating_clamp_in_the_imager(self):
        u, v = self.thermal_view("busbar_support/clamp_a", distance=3.0)
        spot = "%d,%d" % (u, v)
        try:
            self.assertEqual(self.call("sim/set_world_value", "day", "6"), ("success", "6"))
            self.assertEqual(self.call("sim/get_world_value", "busbar_support/clamp_a"), ("success", "81.5"))
            wait_for(lambda: abs(float(self.ok("infrared_control", "get_spot_temperature", spot)) - 81.5) < 0.5, 5.0,
                     "the clamp's temperature on day 6")
            self.assertEqual(self.call("sim/set_world_value", "day", "-2")[0], "failed")
        finally:
            self.ok("sim/set_world_value", "day", "0")

    def test_thermal_bad_input_and_unsupported(self):
        cases = [("get_spot_temperature", "384,0"), ("get_spot_temperature", "-1,5"), ("get_spot_temperature", "a,b"),
                 ("get_spot_temperature", "1,2,3"), ("get_spot_temperature", "1, 2"), ("set_measure_spot", "0,288"),
                 ("set_measure_spot", ""), ("save_temperature", os.path.join(ROOT, "t.txt")),
                 ("save_temperature", "/etc/x.png"), ("capture_picture", "/root/../etc/x.jpg"),
                 ("capture_picture", ""), ("calibrate", "")]
        for cmd, data in cases:
            ack, reply = self.call("infrared_control", cmd, data)
            self.assertEqual(ack, "failed", "%s(%r) -> %s" % (cmd, data, reply))
            self.assertTrue(reply)
        self.assertEqual(self.call("vendor/infrared_control", "auto_focus"), ("failed", "unsupported"))
        self.assertEqual(self.call("vendor/infrared_control", "save_temperature", os.path.join(ROOT, "v.png")),
                         ("failed", "unsupported"))
        self.assertEqual(self.call("vendor/infrared_control", "get_high_temperature")[0], "success")


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_camera_sim", CameraSimTest)
