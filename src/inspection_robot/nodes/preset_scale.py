"""preset_scale: records a preset (INTERFACE.md section 4, "Preset recording").

Subscribes:  preset_scale_cmd (PresetScaleCmd); nav_status (NavStatus): the robot's map pose
             terrace_state (sensor_msgs/JointState): after a set_angle, waits (<= 2 s) for the head to report it
Publishes:   preset_scale_ack (PresetScaleAck): result success|failed, directory = the new
             preset directory, or the reason on failure
Services:    camera_control (get_zoom_level, get_focus_position, set_osd_mode, set_zoom_level,
             capture_picture), infrared_control (capture_picture, save_temperature),
             terrace_control (get_angle: asked every time, so a preferred move that is still
             under way finishes first, cloud_terrace serving one command at a time): clients
Parameters:  config/preset_scale.yaml: every setting, its default and meaning (read through ros.node.NodeSettings),
             and config/camera_optics.yaml (~camera_optics: the widest zoom of the ladder); data_root (namespace)
Requests are served one at a time by a worker thread; the zoom is restored after the pictures.
"""
import os
import time
import traceback

import rospy

from inspection_robot.camera.optics import ZoomOptics
from inspection_robot.command import CommandError
from inspection_robot.files import confine_path, hide_root, shown
from inspection_robot.inspection.finder import FindError
from inspection_robot.inspection.preset import PresetError, check_preset_id
from inspection_robot.inspection.recorder import record_preset
from inspection_robot.interface import ACK_FAILED, ACK_SUCCESS
from inspection_robot.ros.node import NodeSettings, init_node
from inspection_robot.ros.worker import RequestWorker
from inspection_robot.msg import PresetScaleAck, PresetScaleCmd
from inspection_robot.inspection.ros_head import HeadingWatcher, RosHead
from inspection_robot.ros.data_root import data_root

NODE_NAME = "preset_scale"


class PresetScaleNode(object):
    def __init__(self, head, heading, preset_root, min_zoom, arm_default, arm_roots, data_root):
        self._head = head
        self._heading = heading
        self._preset_root = preset_root
        self._min_zoom = min_zoom
        self._arm_default = arm_default
        self._arm_roots = arm_roots
        self._data_root = data_root   # taken out of every refusal (files.hide_root)
        self._pub = rospy.Publisher("preset_scale_ack", PresetScaleAck, queue_size=10)
        self._worker = RequestWorker(NODE_NAME, self._serve,
                                     lambda msg: self._publish(msg, ACK_FAILED, "busy: request queue full"), 10)
        self._sub = rospy.Subscriber("preset_scale_cmd", PresetScaleCmd, self._worker.submit, queue_size=10)

    def _serve(self, msg):
        try:
            directory = self.record(msg)
        except (CommandError, PresetError, FindError, OSError) as err:
            rospy.logwarn("preset_scale: %s failed: %s" % (msg.preset_id, err))
            self._publish(msg, ACK_FAILED, str(err))
        except Exception as err:  # boundary: one bad request must not kill the node
            rospy.logerr("preset_scale: %s\n%s" % (err, traceback.format_exc()))
            self._publish(msg, ACK_FAILED, "internal error: %s" % err)
        else:
            self._publish(msg, ACK_SUCCESS, directory)

    def record(self, msg):
        """Record one preset; returns its directory."""
        check_preset_id(msg.preset_id)   # before anything is asked of the devices
        preset_id = msg.preset_id
        fields = msg.extra_data.split(",") if msg.extra_data else []
        arm_file = None
        if fields and fields[0] == "1":
            arm_file = confine_path(fields[1] if len(fields) > 1 and fields[1] else self._arm_default,
                                    self._arm_roots)
            if not os.path.isfile(arm_file):
                raise CommandError("arm trajectory file not found: %s" % shown(arm_file))
        pose = self._heading.latest()
        if pose is None:
            raise CommandError("no robot pose yet (nav_status)")
        pan, tilt = self._head.get_angles()
        state = {"pan_deg": pan, "tilt_deg": tilt, "zoom": self._head.get_zoom(),
                 "focus_position": self._head.get_focus(), "pose": pose}
        self._head.hide_osd()
        return record_preset(self._head, self._preset_root, preset_id, time.strftime("%Y%m%d_%H%M%S"), state,
                             infrared=msg.infrared, preset_type=msg.type, extra_data=msg.extra_data,
                             min_zoom=self._min_zoom, arm_trajectory=arm_file)

    def _publish(self, request, result, directory):
        if result != ACK_SUCCESS:
            directory = hide_root(directory, self._data_root)
        ack = PresetScaleAck(sender=NODE_NAME, receiver=request.sender, trans_id=request.trans_id, result=result,
                             directory=directory)
        ack.header.stamp = rospy.Time.now()
        self._pub.publish(ack)


def main():
    init_node(NODE_NAME)
    settings = NodeSettings("preset_scale")
    root = data_root()
    preset_root = settings.path("~preset_root", root)
    optics_cfg = settings.get("~camera_optics")
    optics = ZoomOptics(optics_cfg["zoom_hfov_deg"], optics_cfg["width"], optics_cfg["height"])
    arm_default = settings.path("~arm_default_trajectory", root)
    arm_roots = settings.path_list("~arm_trajectory_roots", root)
    service_timeout = float(settings.get("~service_timeout"))
    if service_timeout <= 0:
        raise ValueError("~service_timeout must be positive")
    os.makedirs(preset_root, exist_ok=True)
    PresetScaleNode(RosHead(NODE_NAME, service_timeout), HeadingWatcher(),
                    preset_root, optics.min_zoom, arm_default, arm_roots, root)
    rospy.spin()
