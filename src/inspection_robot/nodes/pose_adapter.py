"""pose_adapter: a localizer's pose as move_base reads it (logic: nav/pose_adapter.py).

Subscribes:  ~input_topic (geometry_msgs/PoseWithCovarianceStamped; mode topic), TF (mode tf)
Publishes:   ~output_topic (geometry_msgs/PoseWithCovarianceStamped, frame ~map_frame): mode topic
             on every input, mode tf at ~rate while the lookup ~map_frame -> ~base_frame succeeds
Parameters:  config/pose_adapter.yaml: every setting, its default and meaning (read through ros.node.NodeSettings)
             (~mode none: nothing to adapt, the node only idles, since robot.launch always starts it and the site
             file's pose_adapter/mode switches it on)
"""
import rospy
import tf2_ros
from geometry_msgs.msg import PoseWithCovarianceStamped

from inspection_robot.angles import quaternion_from_yaw
from inspection_robot.nav.pose_adapter import (ADAPTER_SETTINGS, MODE_NONE, MODE_TF, AdapterParams, LookupWatch,
                                               planar_covariance, pose_from_transform)
from inspection_robot.ros.node import NodeSettings, init_node


class TfPoseAdapter(object):
    def __init__(self, params):
        self.params = params
        self._covariance = planar_covariance(params.sigma_xy, params.sigma_yaw)
        self._watch = LookupWatch(params.map_frame, params.base_frame, params.error_period)
        self._buffer = tf2_ros.Buffer()
        self._listener = tf2_ros.TransformListener(self._buffer)
        self._pub = rospy.Publisher(params.output_topic, PoseWithCovarianceStamped, queue_size=10)
        rospy.Timer(rospy.Duration(1.0 / params.rate), self._tick)

    def _tick(self, _event):
        p = self.params
        try:
            tf = self._buffer.lookup_transform(p.map_frame, p.base_frame, rospy.Time(0))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException) as err:
            message = self._watch.failed(rospy.get_time(), err)
            if message:
                rospy.logerr("pose_adapter: %s" % message)
            return
        if self._watch.succeeded():
            rospy.loginfo("pose_adapter: transform %s -> %s available again", p.map_frame, p.base_frame)
        t, r = tf.transform.translation, tf.transform.rotation
        x, y, yaw = pose_from_transform((t.x, t.y, t.z), (r.x, r.y, r.z, r.w))
        msg = PoseWithCovarianceStamped()
        msg.header.stamp = tf.header.stamp if tf.header.stamp else rospy.Time.now()   # static TF: 0
        msg.header.frame_id = p.map_frame
        msg.pose.pose.position.x, msg.pose.pose.position.y = x, y
        _, _, msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = quaternion_from_yaw(yaw)
        msg.pose.covariance = self._covariance
        self._pub.publish(msg)


class TopicPoseAdapter(object):
    def __init__(self, params):
        self._pub = rospy.Publisher(params.output_topic, PoseWithCovarianceStamped, queue_size=10)
        rospy.Subscriber(params.input_topic, PoseWithCovarianceStamped, self._pub.publish, queue_size=10)


def main():
    init_node("pose_adapter")
    settings = NodeSettings("pose_adapter")
    params = AdapterParams(settings.get("~mode"), **{n: settings.get("~" + n) for n in ADAPTER_SETTINGS})
    if params.mode == MODE_NONE:
        rospy.loginfo("pose_adapter: mode none, nothing to adapt (move_base reads the localizer's own topic, "
                      "the site setting move_base/pose_topic)")
        rospy.spin()
        return
    if params.mode == MODE_TF:
        TfPoseAdapter(params)
        source = "transform %s -> %s at %.1f Hz" % (params.map_frame, params.base_frame, params.rate)
    else:
        TopicPoseAdapter(params)
        source = rospy.resolve_name(params.input_topic)
    rospy.loginfo("pose_adapter: %s -> %s", source, rospy.resolve_name(params.output_topic))
    rospy.spin()
