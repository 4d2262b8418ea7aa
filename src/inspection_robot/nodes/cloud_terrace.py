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
Parameters:  ~driver (pelco | sim | none | "package.module:Class" with ~driver_params, required; sim is
               pelco on the pty of sim_pelco_head; none: every command fails "head not fitted (driver: none)"),
             ~port (pyserial URL or device, "/tmp/inspection_robot_pelco"), ~baudrate (9600),
             ~address (Pelco-D address, 1), ~reply_timeout (s, 0.3),
             ~reconnect_backoff ([first, max] s, [0.1, 2.0]),
             ~speeds ({high_speed: 63, mid_speed: 32, low_speed: 8}, Pelco-D speed bytes),
             ~tilt_min_deg (-90.0), ~tilt_max_deg (90.0), ~reach_tolerance_deg (0.01),
             ~move_timeout (s, 10.0), ~poll_period (s, 0.05), ~state_rate (Hz, 20.0),
             ~camera_optics (config/camera_optics.yaml: width, height, zoom_hfov_deg)
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
from inspection_robot.ros.node import init_node
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
    port = rospy.get_param("~port", "/tmp/inspection_robot_pelco")
    backoff = rospy.get_param("~reconnect_backoff", [0.1, 2.0])
    speeds = rospy.get_param("~speeds", {"high_speed": 63, "mid_speed": 32, "low_speed": 8})
    tilt_limits = (pelco.degrees_to_centi(rospy.get_param("~tilt_min_deg", -90.0)),
                   pelco.degrees_to_centi(rospy.get_param("~tilt_max_deg", 90.0)))
    tolerance = pelco.degrees_to_centi(rospy.get_param("~reach_tolerance_deg", 0.01))
    move_timeout = float(rospy.get_param("~move_timeout", 10.0))
    poll_period = float(rospy.get_param("~poll_period", 0.05))
    state_rate = float(rospy.get_param("~state_rate", 20.0))
    optics_param = rospy.get_param("~camera_optics")
    optics = ZoomOptics(optics_param["zoom_hfov_deg"], optics_param["width"], optics_param["height"])
    reply_timeout = float(rospy.get_param("~reply_timeout", 0.3))
    if not isinstance(backoff, list) or len(backoff) != 2 or not 0 < float(backoff[0]) <= float(backoff[1]):
        raise ValueError("~reconnect_backoff must be [first, max] seconds, 0 < first <= max, got %r" % (backoff,))
    if state_rate <= 0 or move_timeout <= 0 or poll_period <= 0 or reply_timeout <= 0:
        raise ValueError("~state_rate, ~move_timeout, ~poll_period and ~reply_timeout must be positive")

    def pelco_head():  # sim: the same Pelco-D driver, on the pty of sim_pelco_head (the launch starts it)
        return PelcoHead(port, baudrate=rospy.get_param("~baudrate", 9600), address=rospy.get_param("~address", 1),
                         reply_timeout=reply_timeout, backoff=backoff,
                         logger=lambda text: rospy.loginfo("%s: %s" % (NODE_NAME, text)))

    head = make_driver("head", rospy.get_param("~driver", ""), {"pelco": pelco_head, SIM: pelco_head},
                       rospy.get_param("~driver_params", {}), NoHead)
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
