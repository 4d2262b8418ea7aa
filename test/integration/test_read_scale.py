#!/usr/bin/env python3
"""rostest: read_scale on a recorded synthetic preset: readings, foreign objects, bad requests."""
import os
import shutil
import sys
import unittest

import cv2
import numpy as np
import rospy
import rostest

from inspection_robot_testing import fixtures as S
from inspection_robot.inspection.geometry import flat_from_quads
from inspection_robot.msg import ReadScaleAck, ReadScaleCmd

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from rostest_helpers import Latest, wait_subscribed  # noqa: E402

SIZE = (480, 270)


class TestReadScale(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_read_scale_node")
        cls.presets = rospy.get_param("~preset_root")
        cls.pictures = rospy.get_param("~picture_root")
        os.makedirs(cls.pictures, exist_ok=True)
        rng = np.random.default_rng(12)
        scene = S.PlanarScene(rng, targets=S.demo_targets())
        cls.preset = S.record_synthetic_preset(cls.presets, "meter_7", "20260101_120000", scene, (1200, 750),
                                               [1.5, 0.75, 0.375], SIZE, S.linear_optics(*SIZE))
        scene.targets[0]["value"], scene.targets[1]["on"], scene.targets[2]["closed"] = 0.77, True, False
        matrix = scene.homography((1190, 745), 1.55, SIZE)
        cls.picture = os.path.join(cls.pictures, "zoom0_20260102_090000_01.jpg")
        cv2.imwrite(cls.picture, scene.render(matrix, SIZE))
        # a second look whose needle stands 3 % FS higher (a misreading the pair must catch)
        scene.targets[0]["value"] = 0.82
        cls.other_look = cls.picture.replace("_01.jpg", "_01_look2.jpg")
        cv2.imwrite(cls.other_look, scene.render(matrix, SIZE))
        cls.roi = flat_from_quads([scene.quad_in_view(t, matrix) for t in scene.targets])
        cls.trans_id = 100
        cls.pub = rospy.Publisher("read_scale_cmd", ReadScaleCmd, queue_size=10)
        cls.acks = Latest("read_scale_ack", ReadScaleAck)
        wait_subscribed(cls.pub, 10.0)
        cls.acks.wait_connected(10.0)

        def probe():  # a request refused at once: its ack proves both connections carry messages
            cls.trans_id += 1
            cls.pub.publish(ReadScaleCmd(sender="server", trans_id=cls.trans_id, directory="/nonexistent"))
        cls.acks.handshake(probe, lambda a: a.trans_id == cls.trans_id, timeout=20.0)

    def request(self, **fields):
        TestReadScale.trans_id += 1
        msg = ReadScaleCmd(sender="server", trans_id=self.trans_id, directory=self.preset, foreign_detect=0,
                           filename=[self.picture], roi_vertex=self.roi)
        for key, value in fields.items():
            setattr(msg, key, value)
        self.pub.publish(msg)
        trans_id = self.trans_id
        return self.acks.wait(lambda a: a.trans_id == trans_id, timeout=20.0, what="ack %d" % trans_id)

    def test_reads_gauge_lamp_and_switch(self):
        ack = self.request()
        self.assertEqual(ack.result, "success", ack.foreign_result)
        self.assertEqual(ack.receiver, "server")
        self.assertLess(abs(ack.scale[0] - 0.77) / 1.6 * 100.0, 1.0)
        self.assertEqual(list(ack.scale[1:]), [1.0, 0.0])  # red lamp lit (code 1), switch open
        self.assertEqual(len(ack.possibility), 3)
        self.assertEqual(len(ack.picture_path), 3)
        for path in ack.picture_path:
            self.assertTrue(path.startswith(os.path.join(self.pictures, "meter_7") + "/"), path)
            self.assertTrue(os.path.isfile(path))

    def test_two_looks(self):
        agree = self.request(filename=[self.picture, self.picture])
        self.assertEqual(agree.result, "success", agree.foreign_result)
        self.assertLess(abs(agree.scale[0] - 0.77) / 1.6 * 100.0, 1.0)
        apart = self.request(filename=[self.picture, self.other_look])
        self.assertRegex(apart.result, r"^uncertain: box 0: two looks disagree: 0\.7\d* and 0\.8\d* \(\d\.\d % FS\)$")
        self.assertEqual(list(apart.scale[1:]), [1.0, 0.0])   # lamp and switch read once, as before

    def test_foreign_detection_both(self):
        dirty = cv2.imread(self.picture)
        cv2.ellipse(dirty, (60, 232), (40, 22), 0, 0, 360, (30, 60, 90), -1)
        path = self.picture.replace("_01.jpg", "_02.jpg")
        cv2.imwrite(path, dirty)
        ack = self.request(foreign_detect=2, foreign_filename=[self.picture, path])
        self.assertEqual(ack.result, "success", ack.foreign_result)
        self.assertEqual(ack.foreign_scale[0], 0.0)
        self.assertGreaterEqual(ack.foreign_scale[1], 1.0)
        self.assertEqual(len(ack.foreign_picture_path), 2)
        self.assertEqual(len(ack.scale), 3)

    def test_bad_requests_fail_with_reasons(self):
        corrupt = os.path.join(self.presets, "meter_7", "20260101_130000")
        shutil.copytree(self.preset, corrupt)
        with open(os.path.join(corrupt, "preset_calib_info.ini"), "w") as f:
            f.write("[calibration]\ntarget_count = two\n")
        cases = [
            (dict(directory=os.path.join(self.presets, "meter_7", "19990101_000000")), "not found"),
            (dict(directory=corrupt), "corrupt calibration"),
            (dict(directory="/etc"), "outside the allowed roots"),
            (dict(roi_vertex=[v + 500 for v in self.roi]), "outside"),
            (dict(roi_vertex=self.roi[:16]), "roi_vertex has 2 box"),
            (dict(filename=[]), "filename has 0 entries"),
            (dict(filename=[self.picture] * 4), "filename has 4 entries"),
            (dict(foreign_detect=7), "foreign_detect"),
            (dict(foreign_detect=1), "foreign_filename is empty"),
        ]
        for fields, reason in cases:
            ack = self.request(**fields)
            self.assertEqual(ack.result, "failed", fields)
            self.assertIn(reason, ack.foreign_result)
        self.assertEqual(self.request().result, "success")  # still alive and well


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_read_scale_node", TestReadScale)
