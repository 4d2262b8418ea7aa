"""check_drivers: robot.launch's start-up check that every device has a real (or ``none``) driver.

Reads each device node's ``~driver`` (inspection_robot.drivers.DEVICES: robot_control, cloud_terrace,
robot_arm, camera_node, infrared_imager, obstacle_detector, in this node's namespace). When any is
unset or ``sim`` it logs ONE fatal message naming every such setting and the file that should hold
it, then exits 1; robot.launch marks it required, so roslaunch stops the whole robot. Otherwise it
logs the chosen drivers and idles (a required node that exits would stop the launch too).

Parameters:  none of its own; reads <node>/driver of each device node.
"""
import sys

import rospy

from inspection_robot.drivers import DEVICES, PARAM, format_problems, robot_launch_problems
from inspection_robot.ros.node import init_node

NODE_NAME = "check_drivers"


def main():
    init_node(NODE_NAME)
    specs = {device: rospy.get_param("%s/%s" % (entry.node, PARAM), None) for device, entry in DEVICES.items()}
    problems = robot_launch_problems(specs)
    if problems:
        rospy.logfatal(format_problems(problems))
        sys.exit(1)
    rospy.loginfo("%s: drivers %s" % (NODE_NAME, ", ".join("%s=%s" % (d, specs[d]) for d in DEVICES)))
    rospy.spin()
