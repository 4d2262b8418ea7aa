"""preset_scale: records a preset (INTERFACE.md section 4, "Preset recording").

Subscribes:  preset_scale_cmd (PresetScaleCmd); terrace_state (sensor_msgs/JointState, pan/tilt
             rad, standard convention); nav_status (NavStatus): the robot's map pose
Publishes:   preset_scale_ack (PresetScaleAck): result success|failed, directory = the new
             preset directory, or the reason on failure
Services:    camera_control (get_zoom_level, get_focus_position, set_osd_mode, set_zoom_level,
             capture_picture), infrared_control (capture_picture, save_temperature),
             terrace_control (get_angle, when terrace_state is silent): clients
Parameters:  ~preset_root (str, /var/lib/inspection_robot/presets): <preset_root>/<preset_id>/<YYYYMMDD_HHMMSS>/
             ~camera_optics (dict, config/camera_optics.yaml): the widest zoom of the ladder
             ~arm_default_trajectory (str, ~/.ros/inspection_robot/arm/default_orbit.csv),
             ~arm_trajectory_roots (list, [~/.ros/inspection_robot/arm]): extra_data "1[,file]"
             ~state_timeout (s, 1.0): terrace_state older than this is not trusted
             ~service_timeout (s, 10.0)
Requests are served one at a time by a worker thread; the zoom is restored after the pictures.
"""
import math
import os
import queue
import threading
import time
import traceback

import rospy
from sensor_msgs.msg import JointState

from inspection_robot.camera.optics import ZoomOptics
from inspection_robot.command import CommandError, confine_path
from inspection_robot.inspection.finder import FindError
from inspection_robot.inspection.preset import PresetError
from inspection_robot.inspection.recorder import record_preset
from inspection_robot.interface import ACK_FAILED, ACK_SUCCESS
from inspection_robot.msg import PresetScaleAck, PresetScaleCmd
from inspection_robot.nodes.inspection_ros import HeadingWatcher, RosHead

NODE_NAME = "preset_scale"


class PresetScaleNode(object):
    def __init__(self, head, heading, preset_root, min_zoom, arm_default, arm_roots, state_timeout):
        self._head = head
        self._heading = heading
        self._preset_root = preset_root
        self._min_zoom = min_zoom
        self._arm_default = arm_default
        self._arm_roots = arm_roots
        self._state_timeout = state_timeout
        self._ptz = None  # (monotonic time, pan deg, tilt deg)
        self._queue = queue.Queue(maxsize=10)
        self._pub = rospy.Publisher("preset_scale_ack", PresetScaleAck, queue_size=10)
        self._worker = threading.Thread(target=self._work, name="preset_scale_worker")
        self._worker.daemon = True
        self._worker.start()
        self._state_sub = rospy.Subscriber("terrace_state", JointState, self._on_state, queue_size=1)
        self._sub = rospy.Subscriber("preset_scale_cmd", PresetScaleCmd, self._on_cmd, queue_size=10)

    def _on_state(self, msg):
        try:
            pan = msg.position[list(msg.name).index("pan")]
            tilt = msg.position[list(msg.name).index("tilt")]
        except (ValueError, IndexError):
            rospy.logwarn_throttle(10.0, "preset_scale: terrace_state without pan/tilt joints")
            return
        self._ptz = (time.monotonic(), math.degrees(pan), math.degrees(tilt))

    def _on_cmd(self, msg):
        try:
            self._queue.put_nowait(msg)
        except queue.Full:
            self._publish(msg, ACK_FAILED, "busy: request queue full")

    def _work(self):
        while not rospy.is_shutdown():
            try:
                msg = self._queue.get(timeout=0.2)
            except queue.Empty:
                continue
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

    def _pan_tilt(self):
        ptz = self._ptz
        if ptz is not None and time.monotonic() - ptz[0] <= self._state_timeout:
            return ptz[1], ptz[2]
        return self._head.get_angles()

    def record(self, msg):
        """Record one preset; returns its directory."""
        preset_id = msg.preset_id
        if not preset_id or "/" in preset_id or preset_id.startswith(".") or len(preset_id) > 128:
            raise CommandError("invalid preset_id '%s'" % preset_id)
        fields = msg.extra_data.split(",") if msg.extra_data else []
        arm_file = None
        if fields and fields[0] == "1":
            arm_file = confine_path(fields[1] if len(fields) > 1 and fields[1] else self._arm_default,
                                    self._arm_roots)
            if not os.path.isfile(arm_file):
                raise CommandError("arm trajectory file not found: %s" % arm_file)
        pose = self._heading.latest()
        if pose is None:
            raise CommandError("no robot pose yet (nav_status)")
        pan, tilt = self._pan_tilt()
        state = {"pan_deg": pan, "tilt_deg": tilt, "zoom": self._head.get_zoom(),
                 "focus_position": self._head.get_focus(), "pose": pose}
        self._head.hide_osd()
        return record_preset(self._head, self._preset_root, preset_id, time.strftime("%Y%m%d_%H%M%S"), state,
                             infrared=msg.infrared, preset_type=msg.type, extra_data=msg.extra_data,
                             min_zoom=self._min_zoom, arm_trajectory=arm_file)

    def _publish(self, request, result, directory):
        ack = PresetScaleAck(sender=NODE_NAME, receiver=request.sender, trans_id=request.trans_id, result=result,
                             directory=directory)
        ack.header.stamp = rospy.Time.now()
        self._pub.publish(ack)


def main():
    rospy.init_node(NODE_NAME)
    preset_root = os.path.expanduser(rospy.get_param("~preset_root", "/var/lib/inspection_robot/presets"))
    optics_cfg = rospy.get_param("~camera_optics")
    optics = ZoomOptics(optics_cfg["zoom_hfov_deg"], optics_cfg["width"], optics_cfg["height"])
    arm_default = os.path.expanduser(rospy.get_param("~arm_default_trajectory",
                                                     "~/.ros/inspection_robot/arm/default_orbit.csv"))
    arm_roots = [os.path.expanduser(p) for p in rospy.get_param("~arm_trajectory_roots",
                                                                ["~/.ros/inspection_robot/arm"])]
    os.makedirs(preset_root, exist_ok=True)
    PresetScaleNode(RosHead(NODE_NAME, float(rospy.get_param("~service_timeout", 10.0))), HeadingWatcher(),
                    preset_root, optics.min_zoom, arm_default, arm_roots,
                    float(rospy.get_param("~state_timeout", 1.0)))
    rospy.spin()
