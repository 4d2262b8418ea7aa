"""ROS inputs of the simulated camera and thermal imager: where the head looks and the world's values.

Subscribes:  sim/true_pose (geometry_msgs/PoseWithCovarianceStamped, map): robot ground truth
             terrace_state (sensor_msgs/JointState, names pan/tilt, rad, pan CCW +, tilt down +)
             sim/world_state (GeneralTopic, latched JSON {"values": {id: value}}) from sim_world
Until a topic is heard the view uses the world's start pose and pan = tilt = 0.
"""
import json
import math
import threading

import rospy
from geometry_msgs.msg import PoseWithCovarianceStamped
from sensor_msgs.msg import JointState

from inspection_robot.angles import yaw_from_quaternion
from inspection_robot.msg import GeneralTopic
from inspection_robot.sim.world import WorldError


class SimView(object):
    def __init__(self, world):
        self._world = world
        self._lock = threading.Lock()
        self._pose = tuple(world.start_pose)
        self._pan = 0.0
        self._tilt = 0.0
        self._subs = [rospy.Subscriber("sim/true_pose", PoseWithCovarianceStamped, self._on_pose, queue_size=1),
                      rospy.Subscriber("terrace_state", JointState, self._on_joints, queue_size=1),
                      rospy.Subscriber("sim/world_state", GeneralTopic, self._on_world, queue_size=10)]

    def __call__(self):
        """((x, y, yaw), pan, tilt) for the renderers."""
        with self._lock:
            return self._pose, self._pan, self._tilt

    def _on_pose(self, msg):
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        yaw = yaw_from_quaternion(q.x, q.y, q.z, q.w)
        if all(math.isfinite(v) for v in (p.x, p.y, yaw)):
            with self._lock:
                self._pose = (p.x, p.y, yaw)

    def _on_joints(self, msg):
        values = dict(zip(msg.name, msg.position))
        with self._lock:
            if math.isfinite(values.get("pan", float("nan"))):
                self._pan = values["pan"]
            if math.isfinite(values.get("tilt", float("nan"))):
                self._tilt = values["tilt"]

    def _on_world(self, msg):
        try:
            values = json.loads(msg.data)["values"]
            for item_id, value in values.items():
                self._world.set_value(item_id, value)
        except (ValueError, KeyError, TypeError, AttributeError, WorldError) as err:
            rospy.logwarn_throttle(5.0, "sim/world_state ignored: %s" % err)
