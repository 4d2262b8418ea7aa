"""sim_obstacle_cloud: the simulated 3-D sensor, point clouds of the yard around the true robot pose.

Subscribes:  sim/true_pose (geometry_msgs/PoseWithCovarianceStamped) from the chassis simulator
Publishes:   obstacle_cloud (sensor_msgs/PointCloud2, frame "base_link", float32 x/y/z) at ~rate
Services:    sim_obstacle_control (ControlService): drop "id,x,y[,size[,height]]" (map m, default 0.5 m
             cube), remove "id", clear, list -> "id,id,..."
Parameters:  config/sim_obstacle_cloud.yaml: every setting, its default and meaning (read through
             ros.node.NodeSettings); ~world (the world: block of config/sim_world.yaml, required; the launch loads
             it)
"""
import math

import rospy
from geometry_msgs.msg import PoseWithCovarianceStamped
from sensor_msgs.msg import PointCloud2, PointField

from inspection_robot.angles import yaw_from_quaternion
from inspection_robot.command import CommandError, CommandTable, parse_float, success
from inspection_robot.nav.obstacle import cloud_bytes
from inspection_robot.ros.node import NodeSettings, init_node
from inspection_robot.ros.twin import serve_table
from inspection_robot.sim.nav_yard import ObstacleCloud

FIELDS = [PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1) for i, n in enumerate("xyz")]


class SimObstacleCloud(object):
    def __init__(self, cloud, rate_hz):
        self._cloud = cloud
        self._pose = None
        self._table = CommandTable({"drop": self._drop, "remove": self._remove, "clear": self._clear,
                                    "list": lambda _d: ",".join(self._cloud.dropped)})
        self._pub = rospy.Publisher("obstacle_cloud", PointCloud2, queue_size=1)
        rospy.Subscriber("sim/true_pose", PoseWithCovarianceStamped, self._on_pose, queue_size=1)
        self._service = serve_table("sim_obstacle_control", self._table)
        rospy.Timer(rospy.Duration(1.0 / rate_hz), self._tick)

    def _on_pose(self, msg):
        p = msg.pose.pose
        self._pose = (p.position.x, p.position.y,
                      yaw_from_quaternion(p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w))

    def _drop(self, data):
        fields = data.split(",")
        if not 3 <= len(fields) <= 5 or not fields[0]:
            raise CommandError("drop needs 'id,x,y[,size[,height]]', got '%s'" % data)
        x, y = parse_float(fields[1], "x"), parse_float(fields[2], "y")
        size = parse_float(fields[3], "size", 0.01, 20.0) if len(fields) > 3 else 0.5
        height = parse_float(fields[4], "height", 0.01, 20.0) if len(fields) > 4 else 0.5
        self._cloud.drop(fields[0], x, y, size, height)
        return success()

    def _remove(self, data):
        if not self._cloud.remove(data):
            raise CommandError("no dropped obstacle '%s'" % data)

    def _clear(self, _data):
        self._cloud.clear()

    def _tick(self, _event):
        if self._pose is None or not all(math.isfinite(v) for v in self._pose):
            return
        points = self._cloud.points_in_robot_frame(*self._pose)
        msg = PointCloud2(height=1, width=len(points), fields=FIELDS, is_bigendian=False, point_step=12,
                          row_step=12 * len(points), is_dense=True, data=cloud_bytes(points))
        msg.header.stamp = rospy.Time.now()
        msg.header.frame_id = "base_link"
        self._pub.publish(msg)


def main():
    init_node("sim_obstacle_cloud")
    settings = NodeSettings("sim_obstacle_cloud")
    world = rospy.get_param("~world")
    rate_hz = float(settings.get("~rate"))
    sensor_range = float(settings.get("~range"))
    spacing = float(settings.get("~spacing"))
    if rate_hz <= 0 or sensor_range <= 0 or spacing <= 0:
        raise ValueError("~rate, ~range and ~spacing must be positive")
    cloud = ObstacleCloud(world, sensor_range, spacing)
    SimObstacleCloud(cloud, rate_hz)
    rospy.spin()
