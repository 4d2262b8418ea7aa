"""virtual_obstacles_replay: move_base's virtual obstacle commands during a replay (replay.launch).

A backend or the console asks move_base for the virtual obstacles (``query``) whenever
virtual_obstacle_map changes; during a replay no move_base runs, so this node answers in its place,
with move_base's name in the ack: ``query`` from the list the bag recorded (move_base's latched
virtual_obstacles topic, repeated at the start of every split), every change (add, modify, delete,
clear) ``failed`` with ``not_allowed: replay (...)``. Runs on ROS time (the bag's clock).

Subscribes:  virtual_obstacles (GeneralTopic, JSON list, from the bag)
             virtual_obstacle_cmd (GeneralCmd) from a backend (replay.launch moves the recorded
             commands to recorded/virtual_obstacle_cmd, so they are not answered again)
Publishes:   virtual_obstacle_ack (GeneralAck, sender "move_base")
Parameters:  none
"""
import json

import rospy

from inspection_robot.interface import SENDER_MOVE_BASE
from inspection_robot.msg import GeneralTopic
from inspection_robot.nav.virtual_obstacles import VirtualObstacles, replay_table
from inspection_robot.ros.data_root import data_root
from inspection_robot.ros.node import init_node
from inspection_robot.ros.twin import CommandTwin


class ReplayedObstacles(object):
    def __init__(self, data_root):
        self.obstacles = VirtualObstacles("")
        self.known = False
        self._sub = rospy.Subscriber("virtual_obstacles", GeneralTopic, self._on_listing, queue_size=5)
        self._twin = CommandTwin(replay_table(self.obstacles, lambda: self.known), None, "virtual_obstacle_cmd",
                                 "virtual_obstacle_ack", SENDER_MOVE_BASE, busy_when_joystick=False,
                                 data_root=data_root)

    def _on_listing(self, msg):
        try:
            self.obstacles.replace(json.loads(msg.data), "virtual_obstacles from the bag")
        except ValueError as exc:   # bad JSON or a malformed entry: keep the last good list
            rospy.logwarn_throttle(10.0, "virtual_obstacles_replay: %s; keeping the previous list" % (exc,))
            return
        self.known = True


def main():
    init_node("virtual_obstacles_replay")
    ReplayedObstacles(data_root())
    rospy.spin()
