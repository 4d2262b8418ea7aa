"""sim_localizer: a noisy simulated localizer (logic: sim/noisy_localizer.py).

Subscribes:  sim/true_pose (geometry_msgs/PoseWithCovarianceStamped) from the chassis simulator
Publishes:   ~output_topic (geometry_msgs/PoseWithCovarianceStamped, frame map, sim/localization/pose) at
             ~rate while true poses arrive, each with gaussian noise and the matching covariance
Parameters:  config/sim_localizer.yaml: every setting, its default and meaning (read through ros.node.NodeSettings);
             ~seed (int; unset: random noise)
"""
import rospy
from geometry_msgs.msg import PoseWithCovarianceStamped

from inspection_robot.angles import quaternion_from_yaw, yaw_from_quaternion
from inspection_robot.nav.localization import MAP_FRAME
from inspection_robot.ros.node import NodeSettings, init_node
from inspection_robot.sim.noisy_localizer import NoisyLocalizer


class SimLocalizer(object):
    def __init__(self, localizer, rate_hz, output_topic):
        self._loc = localizer
        self._pub = rospy.Publisher(output_topic, PoseWithCovarianceStamped, queue_size=10)
        rospy.Subscriber("sim/true_pose", PoseWithCovarianceStamped, self._on_pose, queue_size=10)
        rospy.Timer(rospy.Duration(1.0 / rate_hz), self._tick)

    def _on_pose(self, msg):
        p = msg.pose.pose
        yaw = yaw_from_quaternion(p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w)
        self._loc.add(rospy.get_time(), msg.header.stamp, (p.position.x, p.position.y, yaw))

    def _tick(self, _event):
        out = self._loc.output(rospy.get_time())
        if out is None:
            return
        stamp, (x, y, yaw) = out
        msg = PoseWithCovarianceStamped()
        msg.header.stamp, msg.header.frame_id = stamp, MAP_FRAME
        msg.pose.pose.position.x, msg.pose.pose.position.y = x, y
        _, _, msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = quaternion_from_yaw(yaw)
        msg.pose.covariance = self._loc.covariance
        self._pub.publish(msg)


def main():
    init_node("sim_localizer")
    settings = NodeSettings("sim_localizer")
    rate_hz = float(settings.get("~rate"))
    if not rate_hz > 0:
        raise ValueError("~rate must be positive, got %r" % rate_hz)
    seed = rospy.get_param("~seed", None)
    localizer = NoisyLocalizer(float(settings.get("~sigma_xy")), float(settings.get("~sigma_yaw")),
                               float(settings.get("~latency")), seed)
    output_topic = settings.get("~output_topic")
    SimLocalizer(localizer, rate_hz, output_topic)
    rospy.loginfo("sim_localizer: sim/true_pose + noise (%.3f m, %.4f rad, %.2f s late, %.0f Hz) -> %s",
                  localizer.sigma_xy, localizer.sigma_yaw, localizer.latency, rate_hz,
                  rospy.resolve_name(output_topic))
    rospy.spin()
