#!/usr/bin/env python3
"""rostest: robot_voice speaks markup and clips into WAV files and acks every request."""
import os
import unittest

import rospy
import rostest

from inspection_robot.msg import GeneralAck, VoiceCmd
from rostest_helpers import Latest, wait_subscribed


class RobotVoiceTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_robot_voice")
        cls.out_dir = rospy.get_param("voice_out_dir")
        cls.acks = Latest("voice_ack", GeneralAck)
        cls.pub = rospy.Publisher("voice_cmd", VoiceCmd, queue_size=10)
        wait_subscribed(cls.pub)
        cls.acks.wait_connected()
        cls.acks.handshake(lambda: cls.pub.publish(VoiceCmd(sender="rostest", trans_id=999, language="english",
                                                            data=["[0]"])),
                           lambda m: m.trans_id == 999)

    def say(self, trans_id, language, data):
        self.pub.publish(VoiceCmd(sender="server", trans_id=trans_id, language=language, data=data))
        return self.acks.wait(lambda m: m.trans_id == trans_id, 20.0, "voice_ack %d" % trans_id)

    def test_markup_and_clip_are_spoken(self):
        before = set(os.listdir(self.out_dir)) if os.path.isdir(self.out_dir) else set()
        ack = self.say(1, "chinese", ["beep", "[123]", "(34)", "%17%", "{123}"])
        self.assertEqual(ack.ack, "success", ack.data)
        self.assertEqual(ack.data, "<beep.wav> 一百二十三 三十四摄氏度 百分之十七 一二三")
        self.assertEqual(ack.receiver, "server")
        self.assertEqual(len(set(os.listdir(self.out_dir)) - before), 5)

    def test_bad_requests_fail_with_reason(self):
        for trans_id, language, data, reason in [(11, "english", ["no_such_clip"], "not found"),
                                                 (12, "french", ["[1]"], "language"),
                                                 (13, "english", [], "empty"),
                                                 (14, "english", ["../../etc/passwd"], "clip name")]:
            ack = self.say(trans_id, language, data)
            self.assertEqual(ack.ack, "failed")
            self.assertIn(reason, ack.data)
        self.assertEqual(self.say(15, "english", ["[7]"]).data, "seven")  # still serving


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "robot_voice", RobotVoiceTest)
