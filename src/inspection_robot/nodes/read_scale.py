"""read_scale: reads the meters of a found preset (INTERFACE.md section 4, "Meter reading").

Subscribes:  read_scale_cmd (ReadScaleCmd)
Publishes:   read_scale_ack (ReadScaleAck): result success | "uncertain: box <i>: <why>; ..." (a
             pointer reading under the confidence threshold) | failed; on failure foreign_result holds
             the reason. scale/possibility/picture_path aligned with the calibrated targets,
             foreign_* aligned with foreign_filename.
Parameters:  config/read_scale.yaml: every setting, its default and meaning (read through ros.node.NodeSettings);
             data_root (namespace)
Requests are served one at a time in arrival order by a worker thread.
"""
import os
import time
import traceback

import rospy

from inspection_robot.files import hide_root
from inspection_robot.inspection.locate import Locator
from inspection_robot.inspection.reading import ReadError, ScaleReader, result_text
from inspection_robot.interface import ACK_FAILED, ACK_SUCCESS
from inspection_robot.msg import ReadScaleAck, ReadScaleCmd
from inspection_robot.ros.node import NodeSettings, init_node
from inspection_robot.ros.worker import RequestWorker
from inspection_robot.ros.data_root import data_root

NODE_NAME = "read_scale"


class ReadScaleNode(object):
    def __init__(self, reader, queue_size, data_root):
        self._reader = reader
        self._data_root = data_root   # taken out of every refusal (files.hide_root)
        self._pub = rospy.Publisher("read_scale_ack", ReadScaleAck, queue_size=10)
        self._worker = RequestWorker(NODE_NAME, lambda msg: self._publish(self.serve(msg)),
                                     lambda msg: self._publish(self._failed(msg, "busy: request queue full")),
                                     queue_size)
        self._sub = rospy.Subscriber("read_scale_cmd", ReadScaleCmd, self._worker.submit, queue_size=queue_size)

    def serve(self, msg):
        """Turn one ReadScaleCmd into its ReadScaleAck; never raises."""
        started = time.monotonic()
        try:
            outcome = self._reader.read(msg.directory, msg.foreign_detect, list(msg.filename),
                                        list(msg.foreign_filename), list(msg.roi_vertex),
                                        list(msg.roi_vertex_thermal), time.strftime("%Y%m%d_%H%M%S"))
        except ReadError as err:
            rospy.logwarn("read_scale: trans_id %d failed: %s" % (msg.trans_id, err))
            return self._failed(msg, str(err))
        except Exception as err:  # boundary: one bad request must not kill the node
            rospy.logerr("read_scale: trans_id %d raised %s\n%s" % (msg.trans_id, err, traceback.format_exc()))
            return self._failed(msg, "internal error: %s" % (err,))
        ack = self._ack(msg)
        ack.result = result_text(outcome, ACK_SUCCESS)
        ack.foreign_result = ACK_SUCCESS if outcome.foreign_picture_path else ""
        ack.scale, ack.possibility, ack.picture_path = outcome.scale, outcome.possibility, outcome.picture_path
        ack.foreign_scale = outcome.foreign_scale
        ack.foreign_possibility = outcome.foreign_possibility
        ack.foreign_picture_path = outcome.foreign_picture_path
        rospy.loginfo("read_scale: trans_id %d read %d box(es), %d foreign picture(s) in %.2f s"
                      % (msg.trans_id, len(ack.scale), len(ack.foreign_scale), time.monotonic() - started))
        return ack

    def _ack(self, msg):
        ack = ReadScaleAck(sender=NODE_NAME, receiver=msg.sender, trans_id=msg.trans_id)
        ack.header.stamp = rospy.Time.now()
        return ack

    def _failed(self, msg, reason):
        ack = self._ack(msg)
        ack.result = ACK_FAILED
        ack.foreign_result = hide_root(reason, self._data_root)
        return ack

    def _publish(self, ack):
        self._pub.publish(ack)


def main():
    init_node(NODE_NAME)
    settings = NodeSettings("read_scale")
    root = data_root()
    preset_root = settings.path("~preset_root", root)
    picture_root = settings.path("~picture_root", root)
    extra = settings.path_list("~extra_picture_roots", root)
    detector = settings.get("~detector")
    queue_size = int(settings.get("~queue_size"))
    if queue_size < 1:
        raise ValueError("~queue_size must be >= 1, got %d" % queue_size)
    for folder in (preset_root, picture_root):
        os.makedirs(folder, exist_ok=True)
    reader = ScaleReader([preset_root], [picture_root, preset_root] + extra, picture_root, Locator(detector))
    ReadScaleNode(reader, queue_size, root)
    rospy.spin()
