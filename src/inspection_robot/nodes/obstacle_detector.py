"""obstacle_detector: 3-D points in the robot's travel corridor -> obstacle_status (on change only).

Subscribes:  ~cloud_topic ("obstacle_cloud", sensor_msgs/PointCloud2, float32 x/y/z, sensor frame)
             move_cmd (MoveCmd): the travel direction (sign of velocity_x, spin in steer mode);
             a zero command keeps the last direction, so a stopped robot still sees what stopped it
Publishes:   obstacle_status (ObstacleStatus, latched): once at start-up (false), then on every change
Parameters:  ~half_width (m, 0.45), ~front_offset (m, 0.45), ~rear_offset (m, 0.45), ~distance (m, 1.2),
             ~ground_height (m, 0.08), ~max_height (m, 1.8), ~spin_radius (m, 0.8), ~min_points (5),
             ~clear_count (clouds, 3), ~sensor_pose ([x, y, z, yaw] of the sensor in the robot frame, m/rad)
"""
import rospy
from sensor_msgs.msg import PointCloud2, PointField

from inspection_robot.msg import MoveCmd, ObstacleStatus
from inspection_robot.nav.obstacle import FORWARD, CorridorDetector, direction_from_command, xyz_from_cloud


class ObstacleDetector(object):
    def __init__(self, detector, cloud_topic):
        self._detector = detector
        self._direction = FORWARD
        self._pub = rospy.Publisher("obstacle_status", ObstacleStatus, queue_size=10, latch=True)
        self._state = False
        self._publish(False)
        rospy.Subscriber("move_cmd", MoveCmd, self._on_move, queue_size=10)
        rospy.Subscriber(cloud_topic, PointCloud2, self._on_cloud, queue_size=1, buff_size=2 ** 24)

    def _on_move(self, msg):
        self._direction = direction_from_command(msg.velocity_x, msg.velocity_yaw, msg.wheel_control, self._direction)

    def _on_cloud(self, msg):
        offsets = {f.name: f.offset for f in msg.fields if f.datatype == PointField.FLOAT32}
        if not all(k in offsets for k in "xyz") or msg.is_bigendian:
            rospy.logwarn_throttle(10.0, "obstacle_detector: cloud on %s lacks little-endian float32 x/y/z; ignored"
                                   % msg.header.frame_id)
            return
        count = msg.width * msg.height
        if len(msg.data) < count * msg.point_step:
            rospy.logwarn_throttle(10.0, "obstacle_detector: cloud shorter than width*height*point_step; ignored")
            return
        points = xyz_from_cloud(msg.data, msg.point_step, (offsets["x"], offsets["y"], offsets["z"]), count)
        state = self._detector.update(points, self._direction)
        if state != self._state:
            self._publish(state)

    def _publish(self, state):
        self._state = state
        msg = ObstacleStatus(sender="obstacle_detector", obstacle=state)
        msg.header.stamp = rospy.Time.now()
        self._pub.publish(msg)
        rospy.loginfo("obstacle_detector: obstacle %s", "detected" if state else "clear")


def main():
    rospy.init_node("obstacle_detector")
    p = {name: float(rospy.get_param("~" + name, default)) for name, default in (
        ("half_width", 0.45), ("front_offset", 0.45), ("rear_offset", 0.45), ("distance", 1.2),
        ("ground_height", 0.08), ("max_height", 1.8), ("spin_radius", 0.8))}
    sensor_pose = [float(v) for v in rospy.get_param("~sensor_pose", [0.0, 0.0, 0.0, 0.0])]
    min_points, clear_count = int(rospy.get_param("~min_points", 5)), int(rospy.get_param("~clear_count", 3))
    if len(sensor_pose) != 4:
        raise ValueError("~sensor_pose must be [x, y, z, yaw]")
    if any(p[name] <= 0 for name in ("half_width", "distance", "spin_radius")) or p["max_height"] <= p["ground_height"]:
        raise ValueError("~half_width, ~distance, ~spin_radius must be positive and ~max_height above ~ground_height")
    if min_points < 1 or clear_count < 1:
        raise ValueError("~min_points and ~clear_count must be >= 1")
    detector = CorridorDetector(p["half_width"], p["front_offset"], p["rear_offset"], p["distance"],
                                p["ground_height"], p["max_height"], p["spin_radius"], min_points, clear_count,
                                sensor_pose)
    ObstacleDetector(detector, rospy.get_param("~cloud_topic", "obstacle_cloud"))
    rospy.spin()
