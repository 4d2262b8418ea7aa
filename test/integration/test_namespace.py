#!/usr/bin/env python3
"""rostest: sim.launch with ns:=robot_7 keeps every topic and service under /robot_7.

A node publishing an absolute name (or a library default such as tf2_ros's /tf left unremapped)
would mix robots when several share one master. Only the master's own /rosout plumbing and this
test node's names may lie outside.
"""
import unittest

import rosgraph
import rospy
import rostest

from rostest_helpers import wait_for

NS = "/robot_7/"
# one topic from each node of sim.launch, so every node has registered before the check
EXPECTED = ("robot_status", "voice_ack", "control_status", "robot_odom", "sim/true_pose", "move_cmd",
            "client_count", "terrace_state", "arm_ack", "sim/world_state", "camera_zoom", "infrared_ack",
            "map", "obstacle_status", "obstacle_cloud", "preset_scale_ack", "find_scale_action/status",
            "read_scale_ack", "charge_status", "sim/localization/pose")
OUTSIDE_OK = ("/rosout", "/rosout_agg")


class NamespaceTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_namespace")
        cls.master = rosgraph.Master(rospy.get_name())

    def _state(self):
        publishers, subscribers, services = self.master.getSystemState()
        return set(t for t, _ in publishers), set(t for t, _ in subscribers), set(s for s, _ in services)

    def test_every_name_is_in_the_namespace(self):
        wanted = set(NS + t for t in EXPECTED)
        wait_for(lambda: wanted <= self._state()[0], 90.0, "every node of sim.launch publishing")
        published, subscribed, services = self._state()
        mine = rospy.get_name() + "/"
        outside = sorted(n for n in published | subscribed
                         if not n.startswith(NS) and n not in OUTSIDE_OK)
        self.assertEqual(outside, [], "topics outside %s: %s" % (NS, outside))
        self.assertIn(NS + "tf", published, "robot_control's odom -> base_link TF")
        outside = sorted(s for s in services
                         if not s.startswith(NS) and not s.startswith(mine) and not s.startswith("/rosout/"))
        self.assertEqual(outside, [], "services outside %s: %s" % (NS, outside))


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_namespace", NamespaceTest)
