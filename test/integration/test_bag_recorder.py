#!/usr/bin/env python3
"""rostest (bag_recorder.test): split bags under a disk budget (the oldest closed bag goes, never the
one being written), the JPEG of an image topic recorded, a full disk that stops recording with a
diagnostics error, and a bag folder that cannot be created (a diagnostics error, no crash)."""
import os
import unittest

import rosbag
import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from sensor_msgs.msg import CompressedImage
from std_msgs.msg import String

from inspection_robot.recording.recorder import list_bags
from rostest_helpers import Latest, wait_for, wait_subscribed

MB = 1000 * 1000


def diagnostic(latest, node):
    """The latest status of ``node`` (both recorders share the hardware_id; the name starts with the node)."""
    for _t, msg in reversed(list(latest.messages)):
        for status in msg.status:
            if (status.hardware_id == "bag_recorder" and status.name.startswith(node + ":")
                    and status.message != "Node starting up"):   # diagnostic_updater's placeholder
                return status
    return None


class BagRecorderTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_bag_recorder")
        root = rospy.get_param("test_bag_dir")
        cls.bags, cls.full = os.path.join(root, "bags"), os.path.join(root, "full")
        cls.diagnostics = Latest("/diagnostics", DiagnosticArray, queue_size=200)
        cls.blob = rospy.Publisher("test_blob", String, queue_size=10)
        cls.jpeg = rospy.Publisher("test_camera/image_raw/compressed", CompressedImage, queue_size=2)

    def test_1_full_disk_stops_the_recorder_with_a_diagnostics_error(self):
        status = wait_for(lambda: diagnostic(self.diagnostics, "full_recorder"), 20.0, "full_recorder diagnostics")
        self.assertEqual(status.level, DiagnosticStatus.ERROR)
        self.assertIn("disk full", status.message)
        self.assertIn("recording stopped", status.message)
        self.assertEqual(list_bags(self.full), [])

    def test_1_a_folder_that_cannot_be_created_is_a_diagnostics_error_not_a_crash(self):
        status = wait_for(lambda: diagnostic(self.diagnostics, "nodir_recorder"), 20.0, "nodir_recorder diagnostics")
        self.assertEqual(status.level, DiagnosticStatus.ERROR)
        self.assertEqual(status.message, "cannot create the bag directory /dev/null/bags: Not a directory; "
                                         "not recording")
        self.diagnostics.clear()   # still alive: it reports again at the next check
        wait_for(lambda: diagnostic(self.diagnostics, "nodir_recorder"), 20.0, "nodir_recorder diagnostics again")

    def test_2_the_jpeg_of_an_image_topic_is_recorded(self):
        # the camera nodes publish <image topic>/compressed; the recorder's rosbag record subscribes to it
        wait_subscribed(self.jpeg, 20.0)

    def test_3_split_bags_stay_within_the_budget(self):
        wait_for(lambda: any(b[3] for b in list_bags(self.bags)), 20.0, "an active bag")
        wait_subscribed(self.blob, 20.0)
        first = [b[0] for b in list_bags(self.bags)][0]
        payload = os.urandom(150 * 1000).hex()[:200 * 1000]   # 200 kB that lz4 cannot shrink much

        def first_deleted():
            self.blob.publish(String(data=payload))
            return not os.path.exists(first) and not os.path.exists(first[:-len(".active")] if
                                                                    first.endswith(".active") else first)
        wait_for(first_deleted, 60.0, "the oldest bag deleted by the budget", period=0.05)

        # between two splits rosbag has closed one bag and not yet opened the next: no bag is active
        # for that moment (seen on a loaded machine), so recording on is an active bag again, waited for
        def recording():
            self.blob.publish(String(data=payload))
            return any(b[3] for b in list_bags(self.bags))
        wait_for(recording, 30.0, "an active bag after the budget's deletion", period=0.05)
        bags = list_bags(self.bags)
        total = sum(b[1] for b in bags)
        self.assertLessEqual(total, 3 * MB + 2 * MB, bags)   # budget + what was written since the last check

        def closed_split():
            self.blob.publish(String(data=payload))
            return [b[0] for b in list_bags(self.bags) if not b[3]]
        closed = wait_for(closed_split, 30.0, "a closed split", period=0.05)
        with rosbag.Bag(closed[-1]) as bag:   # a closed split is a valid, indexed bag
            self.assertGreater(bag.get_message_count(topic_filters=["/test_blob"]), 0)
        status = wait_for(lambda: diagnostic(self.diagnostics, "bag_recorder"), 10.0, "bag_recorder diagnostics")
        self.assertEqual(status.level, DiagnosticStatus.OK, status.message)


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_bag_recorder", BagRecorderTest)
