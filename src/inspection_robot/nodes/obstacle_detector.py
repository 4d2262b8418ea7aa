"""obstacle_detector: 3-D points in the robot's travel corridor -> obstacle_status (on change, and re-asserted).

Subscribes:  ~cloud_topic ("obstacle_cloud", sensor_msgs/PointCloud2, float32 x/y/z, sensor frame) with
               ~driver pointcloud (a ROS driver publishes it) or sim (sim_obstacle_cloud publishes it)
             move_cmd (MoveCmd): the travel direction (sign of velocity_x, spin in steer mode);
             a zero command keeps the last direction, so a stopped robot still sees what stopped it
Publishes:   obstacle_status (ObstacleStatus, latched): once at start-up (false), then on every change and
             again every ~republish_period: robot_control takes a state not refreshed within its
             ~obstacle_timeout for an obstacle, so a silent detector never leaves a stale clear holding
Parameters:  config/obstacle_detector.yaml: every setting, its default and meaning (read through
             ros.node.NodeSettings); ~driver is required (none: no 3-D sensor fitted, obstacle_status stays false; a
             plug-in is start(callback)ed with N x 3 float arrays)
"""
import threading

import rospy
from sensor_msgs.msg import PointCloud2, PointField

from inspection_robot.drivers import SIM, make_driver, not_fitted_reason
from inspection_robot.msg import MoveCmd, ObstacleStatus
from inspection_robot.nav.obstacle import FORWARD, CorridorDetector, direction_from_command, xyz_from_cloud
from inspection_robot.ros.node import NodeSettings, init_node


class ObstacleDetector(object):
    def __init__(self, detector, republish_period):
        self._detector = detector
        self._direction = FORWARD
        self._pub = rospy.Publisher("obstacle_status", ObstacleStatus, queue_size=10, latch=True)
        self._state = False
        # one lock over state and publish: a re-assertion must never overtake a change (a late clear)
        self._lock = threading.Lock()
        self._publish(False)
        rospy.Subscriber("move_cmd", MoveCmd, self._on_move, queue_size=10)
        self._timer = rospy.Timer(rospy.Duration(republish_period), self._on_republish)

    def _on_move(self, msg):
        self._direction = direction_from_command(msg.velocity_x, msg.velocity_yaw, msg.wheel_control, self._direction)

    def on_cloud(self, msg):
        offsets = {f.name: f.offset for f in msg.fields if f.datatype == PointField.FLOAT32}
        if not all(k in offsets for k in "xyz") or msg.is_bigendian:
            rospy.logwarn_throttle(10.0, "obstacle_detector: cloud on %s lacks little-endian float32 x/y/z; ignored"
                                   % msg.header.frame_id)
            return
        count = msg.width * msg.height
        if len(msg.data) < count * msg.point_step:
            rospy.logwarn_throttle(10.0, "obstacle_detector: cloud shorter than width*height*point_step; ignored")
            return
        self.on_points(xyz_from_cloud(msg.data, msg.point_step, (offsets["x"], offsets["y"], offsets["z"]), count))

    def on_points(self, points):
        state = self._detector.update(points, self._direction)
        with self._lock:
            if state != self._state:
                self._publish(state)

    def _on_republish(self, _event):
        with self._lock:
            self._publish(self._state, changed=False)

    def _publish(self, state, changed=True):
        self._state = state
        msg = ObstacleStatus(sender="obstacle_detector", obstacle=state)
        msg.header.stamp = rospy.Time.now()
        self._pub.publish(msg)
        if changed:
            rospy.loginfo("obstacle_detector: obstacle %s", "detected" if state else "clear")


def main():
    init_node("obstacle_detector")
    settings = NodeSettings("obstacle_detector")
    p = {name: float(settings.get("~" + name)) for name in (
        "half_width", "front_offset", "rear_offset", "distance", "ground_height", "max_height", "spin_radius")}
    sensor_pose = [float(v) for v in settings.get("~sensor_pose")]
    min_points, clear_count = int(settings.get("~min_points")), int(settings.get("~clear_count"))
    republish_period = float(settings.get("~republish_period"))
    if not republish_period > 0:
        raise ValueError("~republish_period must be positive, got %r" % republish_period)
    if len(sensor_pose) != 4:
        raise ValueError("~sensor_pose must be [x, y, z, yaw]")
    if any(p[name] <= 0 for name in ("half_width", "distance", "spin_radius")) or p["max_height"] <= p["ground_height"]:
        raise ValueError("~half_width, ~distance, ~spin_radius must be positive and ~max_height above ~ground_height")
    if min_points < 1 or clear_count < 1:
        raise ValueError("~min_points and ~clear_count must be >= 1")
    detector = CorridorDetector(p["half_width"], p["front_offset"], p["rear_offset"], p["distance"],
                                p["ground_height"], p["max_height"], p["spin_radius"], min_points, clear_count,
                                sensor_pose)
    cloud_topic = settings.get("~cloud_topic")
    node = ObstacleDetector(detector, republish_period)
    source = make_driver("sensor3d", settings.get("~driver"),
                         {SIM: lambda: cloud_topic, "pointcloud": lambda: cloud_topic},
                         settings.get("~driver_params"))
    if source is None:
        rospy.logwarn("obstacle_detector: %s: no obstacle detection, obstacle_status stays false"
                      % not_fitted_reason("sensor3d"))
    elif isinstance(source, str):
        rospy.Subscriber(source, PointCloud2, node.on_cloud, queue_size=1, buff_size=2 ** 24)
    else:  # a plug-in sensor: start(callback) calls back with an N x 3 float array (m, sensor frame)
        source.start(node.on_points)
    rospy.spin()
