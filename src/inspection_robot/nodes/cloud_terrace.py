"""cloud_terrace: the Pelco-D pan/tilt head (INTERFACE.md section 4, "PTZ").

Services:    terrace_control (ControlService): every terrace command (inspection_robot.ptz.terrace)
Subscribes:  terrace_cmd (GeneralCmd), preset_rotate (PresetRotate),
             camera_zoom (std_msgs/Float64, latched; the minimum zoom until heard),
             control_status (ControlStatus): joystick-busy rule
Publishes:   terrace_ack (GeneralAck): replies to terrace_cmd, and the outcome of each preset_rotate
               (its trans_id, data "pan,tilt" target or the reason)
             terrace_state (sensor_msgs/JointState): names [pan, tilt], rad, standard convention
               (pan CCW +, tilt down +), at ~state_rate while the head answers
             diagnostics (diagnostic_msgs/DiagnosticArray, diagnostic_updater): hardware_id
               "pan_tilt_head", 1 Hz; "pan/tilt head" ERROR while the head is lost, and
               "terrace_state rate" (FrequencyStatus against ~state_rate)
Parameters:  config/cloud_terrace.yaml: every setting, its default and meaning (read through ros.node.NodeSettings),
             and config/camera_optics.yaml (~camera_optics); ~driver is required (sim is pelco on the pty of
             sim_pelco_head, whose link the launch passes as ~port; none: every command fails "head not fitted
             (driver: none)")
"""

import diagnostic_updater
import rospy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from inspection_robot.camera.optics import ZoomOptics
from inspection_robot.command import CommandError, failed, success
from inspection_robot.drivers import SIM, make_driver
from inspection_robot.msg import PresetRotate
from inspection_robot.interface import ACK_SUCCESS, BUSY
from inspection_robot.ros.diagnostics import DeviceDiagnostics
from inspection_robot.ros.data_root import data_root
from inspection_robot.ros.node import NodeSettings, init_node
from inspection_robot.ros.twin import CommandTwin
from inspection_robot.ros.worker import RequestWorker
from inspection_robot.ptz import pelco
from inspection_robot.ptz.driver import HeadError, NoHead, PelcoHead
from inspection_robot.ptz.terrace import Terrace, format_centi

NODE_NAME = "cloud_terrace"
HARDWARE_ID = "pan_tilt_head"
STATE_STALE_S = 1.0


class CloudTerrace(object):
    def __init__(self, head, terrace, optics, state_rate_hz, data_root):
        self._head = head
        self._terrace = terrace
        self._optics = optics
        self._zoom = optics.min_zoom
        self._last_state_time = None
        self.twin = CommandTwin(terrace.table(), "terrace_control", "terrace_cmd", "terrace_ack", NODE_NAME,
                                data_root=data_root)
        self._state_pub = rospy.Publisher("terrace_state", JointState, queue_size=10)
        self._diagnostics = DeviceDiagnostics("pan/tilt head", HARDWARE_ID)
        # terrace_state's rate: too low when the head answers slowly, ERROR when it stops answering.
        self._state_rate = diagnostic_updater.FrequencyStatus(
            diagnostic_updater.FrequencyStatusParam({"min": state_rate_hz, "max": state_rate_hz}, 0.5, 5),
            "terrace_state rate")
        self._diagnostics.add(self._state_rate)
        self._rotations = RequestWorker(NODE_NAME + ": preset_rotate",
                                        lambda msg: self.twin.publish_ack(self._rotate(msg), msg),
                                        lambda msg: self.twin.publish_ack(failed("preset_rotate: busy, queue full"),
                                                                          msg), 10)
        rospy.Subscriber("camera_zoom", Float64, self._on_zoom, queue_size=1)
        rospy.Subscriber("preset_rotate", PresetRotate, self._rotations.submit, queue_size=10)
        self._state_timer = rospy.Timer(rospy.Duration(1.0 / state_rate_hz), self._on_state_timer)
        self._diag_timer = rospy.Timer(rospy.Duration(1.0), self._on_diag_timer)

    def _on_zoom(self, msg):
        self._zoom = msg.data

    def _rotate(self, msg):
        if self.twin.busy_for(msg.sender):
            return failed(BUSY)
        try:
            target = self._terrace.pixel_target(self._optics, self._zoom, msg.width, msg.height,
                                                msg.delta_x, msg.delta_y)
        except CommandError as err:
            rospy.logwarn("%s: preset_rotate refused: %s" % (NODE_NAME, err))
            return failed("preset_rotate: %s" % err)
        reply = self.twin.handle(msg.sender, "set_angle", format_centi(*target))
        if reply.ack != ACK_SUCCESS:
            return failed("preset_rotate: %s" % reply.data)
        return success(format_centi(*target))

    def _on_state_timer(self, _event):
        try:
            pan, tilt = self._head.query_pan(), self._head.query_tilt()
        except HeadError as err:
            rospy.logwarn_throttle(5.0, "%s: no pan/tilt state from %s: %s" % (NODE_NAME, self._head.port, err))
            return
        self._last_state_time = rospy.get_time()
        msg = JointState(name=["pan", "tilt"], position=[pelco.centi_to_radians(pan), pelco.centi_to_radians(tilt)])
        msg.header.stamp = rospy.Time.now()
        self._state_pub.publish(msg)
        self._state_rate.tick()

    def _on_diag_timer(self, _event):
        fresh = self._last_state_time is not None and rospy.get_time() - self._last_state_time < STATE_STALE_S
        ok = self._head.connected and fresh
        message = "head answering" if ok else "head lost: %s" % (self._head.last_error or "no reply")
        self._diagnostics.publish(ok, message, sorted(self._head.stats.items()) +
                                  [("port", self._head.port), ("camera_zoom", "%g" % self._zoom)])


def main():
    init_node(NODE_NAME)
    settings = NodeSettings("cloud_terrace")
    port = settings.get("~port")
    backoff = settings.get("~reconnect_backoff")
    speeds = settings.get("~speeds")
    tilt_limits = (pelco.degrees_to_centi(settings.get("~tilt_min_deg")),
                   pelco.degrees_to_centi(settings.get("~tilt_max_deg")))
    tolerance = pelco.degrees_to_centi(settings.get("~reach_tolerance_deg"))
    move_timeout = float(settings.get("~move_timeout"))
    poll_period = float(settings.get("~poll_period"))
    state_rate = float(settings.get("~state_rate"))
    optics_param = settings.get("~camera_optics")
    optics = ZoomOptics(optics_param["zoom_hfov_deg"], optics_param["width"], optics_param["height"])
    reply_timeout = float(settings.get("~reply_timeout"))
    if not isinstance(backoff, list) or len(backoff) != 2 or not 0 < float(backoff[0]) <= float(backoff[1]):
        raise ValueError("~reconnect_backoff must be [first, max] seconds, 0 < first <= max, got %r" % (backoff,))
    if state_rate <= 0 or move_timeout <= 0 or poll_period <= 0 or reply_timeout <= 0:
        raise ValueError("~state_rate, ~move_timeout, ~poll_period and ~reply_timeout must be positive")

    def pelco_head():  # sim: the same Pelco-D driver, on the pty of sim_pelco_head (the launch starts it)
        return PelcoHead(port, baudrate=settings.get("~baudrate"), address=settings.get("~address"),
                         reply_timeout=reply_timeout, backoff=backoff,
                         logger=lambda text: rospy.loginfo("%s: %s" % (NODE_NAME, text)))

    head = make_driver("head", settings.get("~driver"), {"pelco": pelco_head, SIM: pelco_head},
                       settings.get("~driver_params"), NoHead)
    terrace = Terrace(head, speeds, tilt_limits, tolerance, move_timeout, poll_period)

    def stop_head():
        try:
            head.stop()
        except HeadError as err:
            rospy.logwarn("%s: could not stop the head on shutdown: %s" % (NODE_NAME, err))
        head.close()

    rospy.on_shutdown(stop_head)
    CloudTerrace(head, terrace, optics, state_rate, data_root())
    rospy.spin()
