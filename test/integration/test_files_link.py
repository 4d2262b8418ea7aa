#!/usr/bin/env python3
"""rostest: mode_ack, file_control and calibration_control seen from the backend (roslibpy over
the websocket). rospy is used only to read the bridge's port and the data root, to lay out a
recorded preset and a capture the way preset_scale and camera_node would, and to press the pad's
buttons on /joy as joystick_reader would."""
import base64
import hashlib
import itertools
import json
import os
import threading
import unittest

import cv2
import numpy as np
import roslibpy
import rospy
import rostest
from sensor_msgs.msg import Joy

from inspection_robot.files import write_atomic
from inspection_robot.inspection.preset import CALIB_INI, PresetInfo, load_preset
from rostest_helpers import rosapi_names, wait_for

PRESET = "presets/p1/20260101_120000"
BOX = [800, 400, 1100, 400, 1100, 700, 800, 700]
TRANS_IDS = itertools.count(1)


class FilesLinkTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_files_link")
        cls.root = rospy.get_param("/data_root")
        rng = np.random.RandomState(1)
        cls.picture = rng.randint(0, 255, (1080, 1920, 3)).astype(np.uint8)
        ok, jpeg = cv2.imencode(".jpg", cls.picture)
        cls.jpeg = jpeg.tobytes()
        preset = os.path.join(cls.root, PRESET)
        info = PresetInfo("p1", "visible", False, "20260101_120000", 0.0, 0.0, 1.0, 0x4000, (0.0, 0.0, 0.0),
                          [1.0, 4.0], 1920, 1080)
        write_atomic(os.path.join(preset, "preset.ini"), info.to_ini())
        write_atomic(os.path.join(preset, "zoom0.jpg"), cls.jpeg)
        write_atomic(os.path.join(cls.root, "captures", "c1.jpg"), cls.jpeg)
        os.symlink("/etc", os.path.join(cls.root, "captures", "link_out"))
        port = int(wait_for(lambda: rospy.get_param("/rosbridge_websocket/actual_port", None), 60.0, "bridge port"))
        cls.ros = roslibpy.Ros("127.0.0.1", port)
        cls.ros.run(timeout=20)
        cls.files = roslibpy.Service(cls.ros, "/file_control", "inspection_robot/ControlService")
        cls.calibration = roslibpy.Service(cls.ros, "/calibration_control", "inspection_robot/ControlService")
        cls.mode_acks = []
        cls.lock = threading.Lock()
        roslibpy.Topic(cls.ros, "/mode_ack", "inspection_robot/GeneralAck").subscribe(cls._on_mode_ack)
        cls.mode_cmd = roslibpy.Topic(cls.ros, "/mode_cmd", "inspection_robot/GeneralCmd")
        cls.server_status = roslibpy.Topic(cls.ros, "/server_status", "inspection_robot/GeneralTopic")
        # joystick_reader's part, on the robot's side (a backend may not publish /joy: the backend surface)
        cls.joy = rospy.Publisher("/joy", Joy, queue_size=10)
        for name in ("/file_control", "/calibration_control"):
            wait_for(lambda: name in rosapi_names(cls.ros.get_services), 30.0, name)

    @classmethod
    def _on_mode_ack(cls, msg):
        with cls.lock:
            cls.mode_acks.append(msg)

    @classmethod
    def tearDownClass(cls):
        cls.ros.terminate()

    def call(self, service, cmd, **fields):
        trans_id = next(TRANS_IDS)
        reply = service.call(roslibpy.ServiceRequest({"sender": "server", "trans_id": trans_id, "cmd": cmd,
                                                      "data": json.dumps(fields)}), timeout=20)
        self.assertEqual(reply["trans_id"], trans_id)
        return reply["ack"], (json.loads(reply["data"]) if reply["ack"] == "success" else reply["data"])

    def mode(self, sender, cmd, data):
        """Send one mode_cmd (repeated until its mode_ack arrives: the first publish through a new
        bridge topic may precede the ROS connection) and return that ack."""
        trans_id = next(TRANS_IDS)

        def answered():
            self.mode_cmd.publish(roslibpy.Message({"sender": sender, "trans_id": trans_id, "cmd": cmd,
                                                    "data": data}))
            with self.lock:
                found = [a for a in self.mode_acks if a["trans_id"] == trans_id]
            return found[0] if found else None
        ack = wait_for(answered, 15.0, "mode_ack of trans_id %d" % trans_id, period=0.5)
        self.assertEqual((ack["receiver"], ack["sender"]), (sender, "robot_control"))
        return ack["ack"], ack["data"]

    def joystick(self, button):
        """Press a pad button (config/joy_control.yaml: 7 START acquires, 6 BACK releases) on /joy, as
        joystick_reader would, until joy_control's mode_cmd is answered; returns that ack. Only
        joy_control's own mode_cmd takes joystick mode: the link's claim to be it is refused."""
        with self.lock:
            seen = len(self.mode_acks)

        def answered():
            for pressed in (0, 1):
                buttons = [0] * 11
                buttons[button] = pressed
                self.joy.publish(Joy(axes=[0.0] * 8, buttons=buttons))
            with self.lock:
                # joy_control's own, not the late answers to the link's repeated claim to be it
                found = [a for a in self.mode_acks[seen:] if a["receiver"] == "joy_control"
                         and "from /rosbridge_websocket/tcpros" not in a["data"]]
            return found[0] if found else None
        ack = wait_for(answered, 15.0, "mode_ack of joy_control's mode_cmd", period=0.5)
        return ack["ack"], ack["data"]

    def test_1_mode_ack_says_why(self):
        # no heartbeat yet: the backend is offline
        self.assertEqual(self.mode("server", "acquire", "server")[0], "failed")
        self.assertTrue(self.mode("server", "acquire", "server")[1].startswith("offline: "))
        stop = threading.Event()

        def heartbeat():
            while not stop.wait(0.2):
                self.server_status.publish(roslibpy.Message({"sender": "server", "data": "alive"}))
        thread = threading.Thread(target=heartbeat)
        thread.daemon = True
        thread.start()
        try:
            wait_for(lambda: self.mode("server", "acquire", "server")[0] == "success", 15.0, "server mode granted")
            self.assertEqual(self.mode("server", "acquire", "server"), ("success", "server"))
            ack, data = self.mode("joy_control", "acquire", "joy")   # the link is not the joystick
            self.assertEqual(ack, "failed")
            self.assertTrue(data.startswith("not_allowed: sender 'joy_control' from /rosbridge_websocket/tcpros "
                                            "ignored: only /joy_control may send it"), data)
            self.assertEqual(self.joystick(7), ("success", "joy"))
            self.assertEqual(self.mode("server", "acquire", "server"),
                             ("failed", "busy: acquire server refused: joy mode has priority"))
            self.assertEqual(self.mode("server", "grab", "server")[1].split(":")[0], "bad_request")
            self.assertEqual(self.joystick(6), ("success", "task"))
            self.assertTrue(self.mode("server", "release", "")[1].startswith("not_held: "))
        finally:
            stop.set()
            thread.join(2.0)

    def test_2_fetch_a_capture_in_chunks(self):
        ack, listing = self.call(self.files, "list", path="")
        self.assertEqual(ack, "success")
        self.assertEqual(sorted(e["name"] for e in listing["entries"]), ["captures", "presets"])
        ack, stat = self.call(self.files, "stat", path="captures/c1.jpg")
        self.assertEqual((stat["size"], stat["sha256"]), (len(self.jpeg), hashlib.sha256(self.jpeg).hexdigest()))
        data, offset, chunks = b"", 0, 0
        while True:
            ack, chunk = self.call(self.files, "read", path="captures/c1.jpg", offset=offset)
            self.assertEqual(ack, "success")
            self.assertLessEqual(chunk["length"], 65536)
            data += base64.b64decode(chunk["data"])
            offset, chunks = offset + chunk["length"], chunks + 1
            if chunk["eof"]:
                break
        self.assertEqual(data, self.jpeg)
        self.assertGreater(chunks, 1)
        for fields, reason in (({"path": "captures/none.jpg"}, "no such file: 'captures/none.jpg'"),
                               ({"path": "../../etc/passwd"}, "path '../../etc/passwd' is outside the allowed roots ("),
                               ({"path": "captures/link_out/passwd"}, "path 'captures/link_out/passwd' is outside"),
                               ({"path": "captures/c1.jpg\n"}, "control or unprintable character"),
                               ({"path": "captures/c1.jpg", "length": 65537}, "length out of range")):
            ack, out = self.call(self.files, "read", **fields)
            self.assertEqual(ack, "failed")
            self.assertIn(reason, out)
            self.assertNotIn(self.root, out)   # the request's own words, never the robot's layout

    def test_2b_a_link_out_of_the_roots_is_listed_not_followed(self):
        ack, listing = self.call(self.files, "list", path="captures")
        self.assertEqual(ack, "success")
        entries = dict((e["name"], e) for e in listing["entries"])
        self.assertEqual(entries["link_out"]["type"], "link")
        self.assertEqual(entries["link_out"]["size"], len("/etc"))   # the link's own, not the target's
        self.assertEqual(entries["c1.jpg"]["type"], "file")

    def test_3_calibrate_a_preset_over_the_link(self):
        preset_dir = os.path.join(self.root, PRESET)
        before = sorted(os.listdir(preset_dir))
        ack, out = self.call(self.calibration, "upload", preset=PRESET,
                             targets=[{"kind": "pointer", "box": BOX, "start_angle": -135}])
        self.assertEqual(ack, "failed")
        self.assertIn("nothing written", out)
        self.assertEqual(sorted(os.listdir(preset_dir)), before)
        for cmd, fields in (("mark_box", {"target": 0, "box": BOX}),
                            ("set_zero", {"target": 0, "angle": -135, "value": 0}),
                            ("set_full_scale", {"target": 0, "angle": 135, "value": 1.6}),
                            ("set_values", {"target": 0, "values": {"unit": "MPa", "name": "oil"}}),
                            ("apply", {})):
            ack, out = self.call(self.calibration, cmd, preset=PRESET, **fields)
            self.assertEqual(ack, "success", "%s: %s" % (cmd, out))
        self.assertEqual(load_preset(preset_dir).targets[0].params["unit"], "MPa")
        ack, out = self.call(self.calibration, "get", preset=PRESET)
        self.assertTrue(out["calibrated"])
        self.assertEqual(out["targets"][0]["name"], "oil")
        ack, listing = self.call(self.files, "list", path=PRESET)
        self.assertIn(CALIB_INI, [e["name"] for e in listing["entries"]])
        ack, out = self.call(self.calibration, "apply", preset="../captures")   # a path leaving the preset roots
        self.assertEqual(ack, "failed")
        self.assertIn("outside the allowed roots", out)
        ack, out = self.call(self.calibration, "apply", preset="captures")   # a preset id: presets/captures
        self.assertEqual((ack, out), ("failed", "preset directory not found: presets/captures"))


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_files_link", FilesLinkTest)
