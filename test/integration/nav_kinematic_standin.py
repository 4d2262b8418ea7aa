#!/usr/bin/env python3
"""TEST-ONLY kinematic stand-in for robot_control + the simulated chassis (not shipped).

Honours the motion team's contract so the navigation rostests run before robot_control lands:
task mode obeys move_cmd from sender "move_base" only; a move_cmd stream silent for 0.5 s stops
the robot; wheel_control 1 spins in place, 0 drives straight with velocity_yaw turning; switching
modes takes ~switch_time s without motion; obstacle_status true stops the robot; the true pose is
published on sim/true_pose (PoseWithCovarianceStamped, frame map) at 50 Hz from
config/sim_world.yaml world.robot.start_pose (param ~world/robot/start_pose).
"""
import math
import time

import rospy
from geometry_msgs.msg import PoseWithCovarianceStamped

from inspection_robot.interface import MOVE_VELOCITY_X_UNIT_M_S, MOVE_VELOCITY_YAW_UNIT_RAD_S, SENDER_MOVE_BASE
from inspection_robot.msg import MoveCmd, ObstacleStatus

CMD_TIMEOUT = 0.5


class Standin(object):
    def __init__(self, start_pose, switch_time):
        self.x, self.y, self.yaw = [float(v) for v in start_pose]
        self.switch_time = switch_time
        self.cmd = (0.0, 0.0, 0)
        self.cmd_time = 0.0
        self.wheel = 0
        self.switch_until = 0.0
        self.obstacle = False
        self.pub = rospy.Publisher("sim/true_pose", PoseWithCovarianceStamped, queue_size=10)
        rospy.Subscriber("move_cmd", MoveCmd, self.on_cmd, queue_size=10)
        rospy.Subscriber("obstacle_status", ObstacleStatus, self.on_obstacle, queue_size=10)
        self.last = time.monotonic()
        rospy.Timer(rospy.Duration(0.02), self.tick)

    def on_cmd(self, msg):
        if msg.sender != SENDER_MOVE_BASE:
            return
        self.cmd = (msg.velocity_x * MOVE_VELOCITY_X_UNIT_M_S, msg.velocity_yaw * MOVE_VELOCITY_YAW_UNIT_RAD_S,
                    msg.wheel_control)
        self.cmd_time = time.monotonic()

    def on_obstacle(self, msg):
        self.obstacle = msg.obstacle

    def tick(self, _event):
        now = time.monotonic()
        dt, self.last = now - self.last, now
        v, w, wheel = self.cmd
        if now - self.cmd_time > CMD_TIMEOUT or self.obstacle:
            v, w = 0.0, 0.0
        elif wheel != self.wheel:
            self.wheel = wheel
            self.switch_until = now + self.switch_time
        if now < self.switch_until:
            v, w = 0.0, 0.0
        if self.wheel == 1:
            v = 0.0
        self.yaw = math.atan2(math.sin(self.yaw + w * dt), math.cos(self.yaw + w * dt))
        self.x += v * math.cos(self.yaw) * dt
        self.y += v * math.sin(self.yaw) * dt
        msg = PoseWithCovarianceStamped()
        msg.header.stamp = rospy.Time.now()
        msg.header.frame_id = "map"
        msg.pose.pose.position.x, msg.pose.pose.position.y = self.x, self.y
        msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = math.sin(self.yaw / 2), math.cos(self.yaw / 2)
        msg.pose.covariance[0] = msg.pose.covariance[7] = 0.01 ** 2
        msg.pose.covariance[35] = 0.005 ** 2
        self.pub.publish(msg)


def main():
    rospy.init_node("nav_kinematic_standin")
    start = rospy.get_param("~world/robot/start_pose", [5.0, 5.0, 0.0])
    Standin(start, float(rospy.get_param("~switch_time", 0.3)))
    rospy.spin()


if __name__ == "__main__":
    main()
