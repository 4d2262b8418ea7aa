#!/usr/bin/env python3
"""rostest, end to end in simulation: record a preset, calibrate it from the world's ground truth,
change the meters, come back 0.3 m / 5 deg off, find_scale, read_scale; bad goals fail with reasons;
foreign objects: stops up to 0.4 m and 5 deg off the preset pose raise no false alarm, a real
object is still found at the worst stop."""
import json
import math
import os
import sys
import unittest

import actionlib
import rospy
import rostest
from geometry_msgs.msg import PoseWithCovarianceStamped

from inspection_robot.camera.optics import ZoomOptics
from inspection_robot.inspection.calibration import calibrate
from inspection_robot.inspection.preset import load_preset
from inspection_robot.inspection.reading import request_filenames
from inspection_robot.msg import (GeneralAction, GeneralGoal, NavStatus, PresetScaleAck, PresetScaleCmd,
                                  ReadScaleAck, ReadScaleCmd)
from inspection_robot.sim.inspection_sim import RenderedHead, world_specs
from inspection_robot.sim.render import Renderer
from inspection_robot.sim.world import World

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from rostest_helpers import Latest, control_proxy, wait_for, wait_subscribed  # noqa: E402

FACE = "breaker_1/sf6_pressure"
DIST_M = 3.0
ZOOM = 4.0


class TestInspectionSim(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_inspection_sim_e2e")
        cls.root = rospy.get_param("~root")
        cls.world = World.load(rospy.get_param("~world_file"))
        face = cls.world.faces[FACE]
        normal = face.quad.normal
        spot = face.quad.centre + normal * DIST_M
        cls.pose = (float(spot[0]), float(spot[1]), math.atan2(-normal[1], -normal[0]))
        cls.tilt = math.degrees(math.atan2(cls.world.sensor_height - face.quad.centre[2], DIST_M))
        cls.pose_pub = rospy.Publisher("sim/true_pose", PoseWithCovarianceStamped, queue_size=1, latch=True)
        cls.nav_pub = rospy.Publisher("nav_status", NavStatus, queue_size=1, latch=True)
        cls.preset_pub = rospy.Publisher("preset_scale_cmd", PresetScaleCmd, queue_size=1)
        cls.read_pub = rospy.Publisher("read_scale_cmd", ReadScaleCmd, queue_size=1)
        cls.preset_acks = Latest("preset_scale_ack", PresetScaleAck)
        cls.read_acks = Latest("read_scale_ack", ReadScaleAck)
        cls.publish_pose(cls.pose)
        cls.terrace, cls.camera, cls.set_value = (
            control_proxy(n, 30.0) for n in ("terrace_control", "camera_control", "sim/set_world_value"))
        cls.find = actionlib.SimpleActionClient("find_scale_action", GeneralAction)
        assert cls.find.wait_for_server(rospy.Duration(30.0)), "find_scale_action server"
        wait_subscribed(cls.preset_pub, 20.0)
        wait_subscribed(cls.read_pub, 20.0)
        # the replies' publishers must have added this node before the first request (Latest.wait_connected)
        cls.preset_acks.wait_connected(20.0)
        cls.read_acks.wait_connected(20.0)

    @classmethod
    def publish_pose(cls, pose):
        msg = PoseWithCovarianceStamped()
        msg.header.frame_id = "map"
        msg.header.stamp = rospy.Time.now()
        msg.pose.pose.position.x, msg.pose.pose.position.y = pose[0], pose[1]
        o = msg.pose.pose.orientation
        o.z, o.w = math.sin(pose[2] / 2.0), math.cos(pose[2] / 2.0)
        cls.pose_pub.publish(msg)
        cls.nav_pub.publish(NavStatus(position=[pose[0], pose[1]], orientation=pose[2]))

    def call(self, proxy, cmd, data=""):
        reply = proxy(sender="test", cmd=cmd, data=data)
        self.assertEqual(reply.ack, "success", "%s %s: %s" % (cmd, data, reply.data))
        return reply.data

    def goal(self, goal_type, data, timeout=90.0):
        self.find.send_goal(GeneralGoal(type=goal_type, data=data))
        self.assertTrue(self.find.wait_for_result(rospy.Duration(timeout)), "find_scale result")
        return self.find.get_result()

    def test_end_to_end(self):
        self.call(self.terrace, "set_angle", "0,%d" % round(self.tilt * 100))
        self.call(self.camera, "set_zoom_level", "%.2f" % ZOOM)
        wait_for(lambda: self.preset_pub.get_num_connections() > 0, 10.0, "preset_scale")
        self.preset_pub.publish(PresetScaleCmd(sender="server", trans_id=7, preset_id="breaker_1", type="meter"))
        ack = self.preset_acks.wait(lambda a: a.trans_id == 7, timeout=60.0, what="preset_scale_ack")
        self.assertEqual(ack.result, "success", ack.directory)
        preset_dir = ack.directory
        self.assertTrue(os.path.isfile(os.path.join(preset_dir, "zoom0.jpg")))
        self.assertTrue(os.path.isfile(os.path.join(preset_dir, "zoom2.jpg")))
        self.assertEqual(float(self.call(self.camera, "get_zoom_level")), ZOOM)   # zoom restored

        # calibrate automatically from the world's ground truth at the recorded view
        optics_cfg = rospy.get_param("/find_scale/camera_optics")
        optics = ZoomOptics(optics_cfg["zoom_hfov_deg"], optics_cfg["width"], optics_cfg["height"])
        info = load_preset(preset_dir, need_calibration=False).info
        head = RenderedHead(Renderer(self.world, seed=5), optics, info.pose, self.world.sensor_height,
                            info.width, info.height)
        head.set_angles(info.pan_deg, info.tilt_deg)
        head.set_zoom(info.zoom)
        specs = world_specs(self.world, head, switch_picture_path=os.path.join(self.root, "%s_%s.png"))
        names = [s["name"] for s in specs]
        self.assertIn(FACE, names)
        calibrate(preset_dir, specs, optics)

        # the meters change; the robot comes back 0.3 m to the side, 5 deg turned
        face = self.world.faces[FACE]
        truth = face.range[0] + 0.71 * (face.range[1] - face.range[0])
        self.call(self.set_value, FACE, "%g" % truth)
        back = (self.pose[0] + 0.3 * math.sin(self.pose[2]), self.pose[1] - 0.3 * math.cos(self.pose[2]),
                self.pose[2] + math.radians(5.0))
        self.publish_pose(back)
        self.call(self.camera, "set_zoom_level", "1.00")
        result = self.goal("find_both", json.dumps({"preset_path": preset_dir}))
        data = json.loads(result.data)
        self.assertEqual(result.ret_code, "0", data)
        self.assertEqual(sorted(data), ["filename", "foreign_filename", "infrared_filename", "infrared_roi_vertex",
                                        "roi_vertex", "second_filename"])
        self.assertEqual(len(data["roi_vertex"]), 8 * len(specs))
        # "_still<k>": a second look showed the view moved, the later picture was found again
        self.assertRegex(os.path.basename(data["filename"]), r"^zoom0_\d{8}_\d{6}_\d{2}(_still\d)?\.jpg$")
        self.assertEqual(data["second_filename"], data["filename"].replace(".jpg", "_look2.jpg"))

        files = request_filenames([t.kind for t in load_preset(preset_dir).targets], data["filename"], "",
                                  data["second_filename"])
        self.read_pub.publish(ReadScaleCmd(sender="server", trans_id=9, directory=preset_dir, foreign_detect=2,
                                           filename=files,
                                           foreign_filename=[data["foreign_filename"]],
                                           roi_vertex=data["roi_vertex"]))
        read = self.read_acks.wait(lambda a: a.trans_id == 9, timeout=60.0, what="read_scale_ack")
        self.assertEqual(read.result, "success", read.foreign_result)
        value = read.scale[names.index(FACE)]
        self.assertLess(abs(value - truth) / (face.range[1] - face.range[0]) * 100.0, 1.0, (value, truth))
        self.assertEqual(list(read.foreign_scale), [0.0])

    def record_calibrated(self, equipment, trans_id, dist=3.5, zoom=2.0):
        """A preset of ``equipment``'s front seen from ``dist`` m, calibrated from the world; (dir, pose)."""
        eq = self.world.equipment[equipment]
        base, normal, _right, _width = eq.side_frame("front")
        spot = base + normal * dist
        pose = (float(spot[0]), float(spot[1]), math.atan2(-normal[1], -normal[0]))
        tilt = math.degrees(math.atan2(self.world.sensor_height - 1.4, dist))
        self.publish_pose(pose)
        self.call(self.terrace, "set_angle", "0,%d" % round(tilt * 100))
        self.call(self.camera, "set_zoom_level", "%.2f" % zoom)
        self.preset_pub.publish(PresetScaleCmd(sender="server", trans_id=trans_id, preset_id=equipment,
                                               type="meter"))
        ack = self.preset_acks.wait(lambda a: a.trans_id == trans_id, timeout=60.0, what="preset_scale_ack")
        self.assertEqual(ack.result, "success", ack.directory)
        optics_cfg = rospy.get_param("/find_scale/camera_optics")
        optics = ZoomOptics(optics_cfg["zoom_hfov_deg"], optics_cfg["width"], optics_cfg["height"])
        info = load_preset(ack.directory, need_calibration=False).info
        head = RenderedHead(Renderer(self.world, seed=5), optics, info.pose, self.world.sensor_height,
                            info.width, info.height)
        head.set_angles(info.pan_deg, info.tilt_deg)
        head.set_zoom(info.zoom)
        calibrate(ack.directory, world_specs(self.world, head, switch_picture_path=os.path.join(
            self.root, "%s_%s.png")), optics)
        return ack.directory, pose

    def foreign_count(self, preset_dir, pose, back_m, side_m, yaw_deg, trans_id):
        fwd = (math.cos(pose[2]), math.sin(pose[2]))
        stop = (pose[0] - fwd[0] * back_m - fwd[1] * side_m, pose[1] - fwd[1] * back_m + fwd[0] * side_m,
                pose[2] + math.radians(yaw_deg))
        self.publish_pose(stop)
        result = self.goal("find_foreign", json.dumps({"preset_path": preset_dir}))
        data = json.loads(result.data)
        self.assertEqual(result.ret_code, "0", data)
        self.read_pub.publish(ReadScaleCmd(sender="server", trans_id=trans_id, directory=preset_dir,
                                           foreign_detect=1, foreign_filename=[data["foreign_filename"]]))
        read = self.read_acks.wait(lambda a: a.trans_id == trans_id, timeout=60.0, what="read_scale_ack")
        self.assertEqual(read.result, "success", read.foreign_result)
        return read.foreign_scale[0]

    def test_foreign_objects_survive_an_inexact_stop(self):
        preset_dir, pose = self.record_calibrated("cabinet_1", 31)
        stops = [(back, 0.0, yaw) for back in (0.1, 0.2, 0.3, 0.4) for yaw in (-5.0, 0.0, 5.0)] + [(0.4, 0.3, 5.0)]
        counts = [self.foreign_count(preset_dir, pose, back, side, yaw, 40 + i)
                  for i, (back, side, yaw) in enumerate(stops)]
        self.assertEqual(counts, [0.0] * len(stops), list(zip(stops, counts)))
        self.call(self.set_value, "foreign/nest", "cabinet_1,front,0.1,1.62,0.2,0.15")
        try:
            self.assertEqual(self.foreign_count(preset_dir, pose, 0.4, 0.3, 5.0, 60), 1.0)
        finally:
            self.call(self.set_value, "foreign/nest", "")

    def test_bad_preset_requests_fail_with_reasons(self):
        for trans_id, preset_id, extra, reason in ((21, "", "", "invalid preset_id"),
                                                   (22, "../up", "", "invalid preset_id"),
                                                   (23, "arm_1", "1,/etc/passwd", "outside")):
            self.preset_pub.publish(PresetScaleCmd(sender="server", trans_id=trans_id, preset_id=preset_id,
                                                   extra_data=extra))
            ack = self.preset_acks.wait(lambda a, t=trans_id: a.trans_id == t, timeout=20.0, what="ack")
            self.assertEqual(ack.result, "failed")
            self.assertIn(reason, ack.directory)

    def test_bad_goals_fail_with_reasons(self):
        cases = [("look_around", json.dumps({"preset_path": self.root}), "unknown goal type"),
                 ("find_scale", "{not json", "not valid JSON"),
                 ("find_scale", "[" * 100000 + "]" * 100000, "not valid JSON"),
                 ("find_scale", json.dumps({"path": "x"}), "preset_path"),
                 ("find_scale", json.dumps({"preset_path": "/etc"}), "outside"),
                 ("find_scale", json.dumps({"preset_path": "presets/none/20000101_000000"}), "not found")]
        for goal_type, data, reason in cases:
            result = self.goal(goal_type, data, 20.0)
            self.assertEqual(result.ret_code, "1", (goal_type, data))
            self.assertIn(reason, json.loads(result.data)["reason"])


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_inspection_sim_e2e", TestInspectionSim)
