"""robot_control: mode arbitration, motion and safety (INTERFACE.md section 4, "Mode and motion").

Drives the chassis through a motion.chassis.ChassisDriver. With ``~driver: sim`` the simulated
chassis (sim.chassis.SimChassis) runs inside this process: robot_control then also offers the
simulator's fault-injection service and ground truth (one process keeps the driver call
in-process, as a vendor driver library would be; see docs/interface.md).

Subscribes:  mode_cmd (GeneralCmd): acquire joy|server, release
             move_cmd (MoveCmd): velocity_x 0.001 m/s, velocity_yaw 0.001 rad/s, wheel_control 0|1
             control_cmd (GeneralCmd): enable_/disable_/switch_collision|fallen|obstacle,
                 enable_/disable_charge, enable_stop, disable_stop, query_status
             obstacle_status (ObstacleStatus), robot_status (RobotStatus: offline_warn, and trans_id: the
                 heartbeat session; acquire server is granted on that session's heartbeat only)
             Safety inputs count only from their owners' caller ids (motion.owners, ~owners):
             obstacle_status from obstacle_detector, robot_status from status_control, mode_cmd and
             move_cmd with sender joy_control / move_base from that node; others are dropped (counted,
             throttled warning; a mode_cmd is answered not_allowed)
             imu_cmd (GeneralCmd): calibrate|reset|query
Publishes:   control_status (ControlStatus) at ~status_rate and at once when a discrete field changes
             control_ack (GeneralAck) the result of each control_cmd (project extension)
             mode_ack (GeneralAck) the result of each mode_cmd, trans_id echoed (project extension):
                 success + mode now in force, or failed + "busy|offline|not_allowed|not_held|bad_request: ..."
             robot_odom (nav_msgs/Odometry, odom -> base_link) and TF odom -> base_link at ~rate
                 (on /tf; motion.launch remaps it to the relative tf so a robot namespace holds it)
             imu_ack (GeneralAck), voice_cmd (VoiceCmd) for query_status
             sim only: sim/true_pose (geometry_msgs/PoseWithCovarianceStamped, frame map) at ~rate,
                 sim/chassis_cmd (geometry_msgs/TwistStamped) every command reaching the driver
Services:    imu_control (ControlService): twin of imu_cmd/imu_ack
             sim only: sim/inject_fault (ControlService): cmd = fault (hard_estop, bumper, fall_left,
                 fall_right, motor_disconnect, joystick_link_lost, stepper_comm, low_battery) or
                 condition (at_dock, charger_off), data 1|0; query; set_pose "x,y,yaw"; set_soc "%"
Parameters:  config/robot_control.yaml: every setting, its default and meaning (read through ros.node.NodeSettings);
             ~driver is required (see inspection_robot.drivers; ~ros_base with driver ros:
             motion.base_inputs.SETTINGS); ~owners ({obstacle_status|robot_status|joy_control|move_base: node name}
             over the defaults (motion.owners.DEFAULT_OWNERS), relative to the namespace; test rigs only);
             ~sim_world (config/sim_world.yaml, loaded by the launch file in simulation): the simulated robot starts
             at world.robot.start_pose ([x, y, yaw] in map) and charges on world.dock
"""
import time
import traceback

import rospy
import tf2_ros
from geometry_msgs.msg import PoseWithCovarianceStamped, TransformStamped, TwistStamped
from nav_msgs.msg import Odometry

from inspection_robot.angles import quaternion_from_yaw
from inspection_robot.drivers import SIM, make_driver
from inspection_robot.interface import ACK_FAILED, ACK_SUCCESS, VOICE_LANGUAGES
from inspection_robot.motion.arbitration import REFUSAL_NOT_ALLOWED
from inspection_robot.motion.chassis import ChassisError, NoChassis
from inspection_robot.motion.controller import MotionController
from inspection_robot.motion.owners import OBSTACLE_STATUS, ROBOT_STATUS
from inspection_robot.motion.base_inputs import PARAM as ROS_BASE_PARAM
from inspection_robot.motion.base_inputs import parse_settings
from inspection_robot.motion.velocity import VelocityLimits
from inspection_robot.msg import ControlStatus, GeneralAck, GeneralCmd, MoveCmd, ObstacleStatus, RobotStatus, VoiceCmd
from inspection_robot.motion.ros_chassis import RosChassis
from inspection_robot.ros.data_root import data_root
from inspection_robot.ros.language import voice_language
from inspection_robot.ros.node import NodeSettings, init_node
from inspection_robot.motion.ros_owner_gate import OwnerGate
from inspection_robot.ros.twin import CommandTwin, control_response
from inspection_robot.srv import ControlService

NODE_NAME = "robot_control"
# Fields whose change publishes control_status at once; analog ones (battery, temperatures) go at the fixed rate.
DISCRETE_FIELDS = ("mode", "wheel_status", "light_status", "stop_status", "circuit_status", "battery_status",
                   "motor_status", "motor_info")
ODOM_POSE_COVARIANCE = (0.01, 0.01, 1e6, 1e6, 1e6, 0.02)
ODOM_TWIST_COVARIANCE = (0.001, 0.001, 1e6, 1e6, 1e6, 0.002)
# The owner-table key of a message on an input topic: the topic itself, or the sender it claims.
OWNER_KEY = {
    OBSTACLE_STATUS: lambda msg: OBSTACLE_STATUS,
    ROBOT_STATUS: lambda msg: ROBOT_STATUS,
    "mode_cmd": lambda msg: msg.sender,
    "move_cmd": lambda msg: msg.sender,
}


def _diagonal(values):
    cov = [0.0] * 36
    for i, v in enumerate(values):
        cov[i * 7] = v
    return cov


class _ImuTable(object):
    """Adapter: CommandTwin dispatches imu commands through the controller (under its lock)."""

    def __init__(self, controller):
        self._controller = controller

    def dispatch(self, cmd, data):
        return self._controller.on_imu_cmd(cmd, data)


class RobotControl(object):
    def __init__(self, controller, owners, rate_hz, status_rate_hz, odom_frame, base_frame, publish_tf,
                 voice_language, data_root, sim=None):
        self._ctl = controller
        self._owners = owners
        self._sim = sim
        self._odom_frame = odom_frame
        self._base_frame = base_frame
        self._voice_language = voice_language
        self._last_discrete = None
        self._status_pub = rospy.Publisher("control_status", ControlStatus, queue_size=50)
        self._odom_pub = rospy.Publisher("robot_odom", Odometry, queue_size=10)
        self._control_ack_pub = rospy.Publisher("control_ack", GeneralAck, queue_size=20)
        self._mode_ack_pub = rospy.Publisher("mode_ack", GeneralAck, queue_size=50)
        self._voice_pub = rospy.Publisher("voice_cmd", VoiceCmd, queue_size=10)
        self._tf = tf2_ros.TransformBroadcaster() if publish_tf else None
        if sim is not None:
            self._true_pose_pub = rospy.Publisher("sim/true_pose", PoseWithCovarianceStamped, queue_size=10)
            self._chassis_cmd_pub = rospy.Publisher("sim/chassis_cmd", TwistStamped, queue_size=100)
            sim.add_command_listener(self._on_driver_command)
            self._fault_table = sim.fault_table()
            rospy.Service("sim/inject_fault", ControlService, self._on_inject_fault)
        controller.set_speaker(self._speak)
        self._imu_twin = CommandTwin(_ImuTable(controller), "imu_control", "imu_cmd", "imu_ack", NODE_NAME,
                                     busy_when_joystick=False, data_root=data_root)
        # Every input, by topic: (message type, queue size, handler). A handler applies its stop in the
        # callback, before returning; _dispatch is the one boundary around all of them.
        self._inputs = {
            "mode_cmd": (GeneralCmd, 50, self._on_mode_cmd),
            "move_cmd": (MoveCmd, 10, self._on_move_cmd),
            "control_cmd": (GeneralCmd, 50, self._on_control_cmd),
            "obstacle_status": (ObstacleStatus, 10, self._on_obstacle),
            "robot_status": (RobotStatus, 1, self._on_robot_status),
        }
        for topic, (msg_type, queue_size, _handler) in self._inputs.items():
            rospy.Subscriber(topic, msg_type, self._dispatch, callback_args=topic, queue_size=queue_size)
        self._timer = rospy.Timer(rospy.Duration(1.0 / rate_hz), self._on_tick)
        self._status_timer = rospy.Timer(rospy.Duration(1.0 / status_rate_hz), self._on_status_timer)

    def _dispatch(self, msg, topic):
        try:
            if not self._from_owner(msg, topic):
                return
            self._inputs[topic][2](msg)
        except Exception as err:  # boundary: one bad input must not kill the node; stop to be safe
            rospy.logerr("%s: %s raised: %s\n%s" % (NODE_NAME, topic, err, traceback.format_exc()))
            self._emergency_stop()

    def _from_owner(self, msg, topic):
        """A safety input from a node that does not own it changes nothing: warned (throttled per
        input), counted, and a mode_cmd answered not_allowed so its sender is not left waiting."""
        key_of = OWNER_KEY.get(topic)
        refusal = key_of and self._owners.refusal(topic, key_of(msg), msg)
        if not refusal:
            return True
        if topic == "mode_cmd":
            ack = GeneralAck(sender=NODE_NAME, receiver=msg.sender, trans_id=msg.trans_id, ack=ACK_FAILED,
                             data="%s: %s" % (REFUSAL_NOT_ALLOWED, refusal))
            ack.header.stamp = rospy.Time.now()
            self._mode_ack_pub.publish(ack)
        return False

    # --- inputs (handlers of self._inputs) -----------------------------------------------------
    def _on_mode_cmd(self, msg):
        def answer(decision):
            reply = self._ctl.mode_reply(decision)
            ack = GeneralAck(sender=NODE_NAME, receiver=msg.sender, trans_id=msg.trans_id, ack=reply.ack,
                             data=reply.data)
            ack.header.stamp = rospy.Time.now()
            self._mode_ack_pub.publish(ack)
            self._publish_status_if_changed()
        decision = self._ctl.on_mode_cmd(msg.sender, msg.cmd, msg.data, answer, trans_id=msg.trans_id)
        if decision is not None:
            answer(decision)

    def _on_move_cmd(self, msg):
        reply = self._ctl.on_move_cmd(msg.sender, msg.velocity_x, msg.velocity_yaw, msg.wheel_control)
        if reply.ack != ACK_SUCCESS:
            rospy.logwarn_throttle(2.0, "%s: move_cmd from %r not obeyed: %s" % (NODE_NAME, msg.sender, reply.data))

    def _on_control_cmd(self, msg):
        reply = self._ctl.on_control_cmd(msg.sender, msg.cmd, msg.data)
        ack = GeneralAck(sender=NODE_NAME, receiver=msg.sender, trans_id=msg.trans_id, ack=reply.ack, data=reply.data)
        ack.header.stamp = rospy.Time.now()
        self._control_ack_pub.publish(ack)
        self._publish_status_if_changed()

    def _on_obstacle(self, msg):
        self._ctl.on_obstacle(msg.obstacle)
        self._publish_status_if_changed()

    def _on_robot_status(self, msg):
        self._ctl.on_offline(msg.offline_warn != 0, msg.trans_id)

    def _on_inject_fault(self, req):
        with self._ctl.locked():
            reply = self._fault_table.dispatch(req.cmd, req.data)
        rospy.loginfo("%s: sim/inject_fault %s(%r): %s %s" % (NODE_NAME, req.cmd, req.data, reply.ack, reply.data))
        self._publish_status_if_changed()
        return control_response(req, reply)

    def _emergency_stop(self):
        try:
            self._ctl.shutdown()
        except Exception as err:  # boundary: nothing more we can do than report it
            rospy.logerr_throttle(1.0, "%s: driver stop failed: %s\n%s" % (NODE_NAME, err, traceback.format_exc()))

    # --- outputs -----------------------------------------------------------------------------
    def _on_tick(self, _event):
        try:
            self._ctl.tick()
        except ChassisError as err:  # the board refused: one clear line, no traceback (nothing to debug here)
            rospy.logerr_throttle(10.0, "%s: control cycle: chassis: %s; robot stopped" % (NODE_NAME, err))
            self._emergency_stop()
            return
        except Exception as err:  # boundary: log, stop, keep the loop alive
            rospy.logerr_throttle(1.0, "%s: control cycle failed: %s\n%s" % (NODE_NAME, err, traceback.format_exc()))
            self._emergency_stop()
            return
        stamp = rospy.Time.now()
        self._publish_odometry(stamp)
        if self._sim is not None:
            self._publish_true_pose(stamp)
        self._publish_status_if_changed()

    def _on_status_timer(self, _event):
        self._publish_status(self._ctl.status())

    def _publish_status_if_changed(self):
        fields = self._ctl.status()
        if tuple(_as_tuple(fields[n]) for n in DISCRETE_FIELDS) != self._last_discrete:
            self._publish_status(fields)

    def _publish_status(self, fields):
        self._last_discrete = tuple(_as_tuple(fields[n]) for n in DISCRETE_FIELDS)
        msg = ControlStatus(sender=NODE_NAME, **fields)
        msg.header.stamp = rospy.Time.now()
        self._status_pub.publish(msg)

    def _publish_odometry(self, stamp):
        odo = self._ctl.odometry
        qx, qy, qz, qw = odo.quaternion()
        msg = Odometry()
        msg.header.stamp = stamp
        msg.header.frame_id = self._odom_frame
        msg.child_frame_id = self._base_frame
        msg.pose.pose.position.x = odo.x
        msg.pose.pose.position.y = odo.y
        msg.pose.pose.orientation.z = qz
        msg.pose.pose.orientation.w = qw
        msg.pose.covariance = _diagonal(ODOM_POSE_COVARIANCE)
        msg.twist.twist.linear.x = odo.velocity_x
        msg.twist.twist.angular.z = odo.velocity_yaw
        msg.twist.covariance = _diagonal(ODOM_TWIST_COVARIANCE)
        self._odom_pub.publish(msg)
        if self._tf is not None:
            tf = TransformStamped()
            tf.header = msg.header
            tf.child_frame_id = self._base_frame
            tf.transform.translation.x = odo.x
            tf.transform.translation.y = odo.y
            tf.transform.rotation.z = qz
            tf.transform.rotation.w = qw
            self._tf.sendTransform(tf)

    def _publish_true_pose(self, stamp):
        with self._ctl.locked():
            (x, y, yaw), _velocity = self._sim.true_pose()
        msg = PoseWithCovarianceStamped()
        msg.header.stamp = stamp
        msg.header.frame_id = "map"
        msg.pose.pose.position.x = x
        msg.pose.pose.position.y = y
        _, _, msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = quaternion_from_yaw(yaw)
        self._true_pose_pub.publish(msg)

    def _on_driver_command(self, velocity_x, velocity_yaw, _wheel_mode):
        msg = TwistStamped()
        msg.header.stamp = rospy.Time.now()
        msg.header.frame_id = self._base_frame
        msg.twist.linear.x = velocity_x
        msg.twist.angular.z = velocity_yaw
        self._chassis_cmd_pub.publish(msg)

    def _speak(self, words):
        msg = VoiceCmd(sender=NODE_NAME, language=self._voice_language, data=list(words))
        msg.header.stamp = rospy.Time.now()
        self._voice_pub.publish(msg)

    def shutdown(self):
        self._timer.shutdown()
        self._ctl.shutdown()


def _as_tuple(value):
    return tuple(value) if isinstance(value, (list, tuple, bytes)) else value


def _log(level, text):
    (rospy.logwarn if level == "warn" else rospy.loginfo)("%s: %s" % (NODE_NAME, text))


def main():
    init_node(NODE_NAME)
    settings = NodeSettings("robot_control")
    driver_spec = settings.get("~driver")
    rate_hz = float(settings.get("~rate"))
    status_rate_hz = float(settings.get("~status_rate"))
    cmd_timeout = float(settings.get("~cmd_timeout"))
    obstacle_timeout = float(settings.get("~obstacle_timeout"))
    owners = OwnerGate.from_param(NODE_NAME)
    limits = VelocityLimits(float(settings.get("~max_velocity_x")),
                            float(settings.get("~max_velocity_yaw")),
                            float(settings.get("~refuse_velocity_x")),
                            float(settings.get("~refuse_velocity_yaw")))
    language = voice_language(str(settings.get("~voice_language") or ""))   # "": the site's
    if rate_hz <= 0 or status_rate_hz <= 0:
        raise ValueError("~rate and ~status_rate must be positive")
    if obstacle_timeout < 0:
        raise ValueError("~obstacle_timeout must be >= 0 (0 = never stale), got %r" % obstacle_timeout)
    if language not in VOICE_LANGUAGES:
        raise ValueError("~voice_language must be one of %s" % (VOICE_LANGUAGES,))

    def simulator():
        from inspection_robot.sim.chassis import SimChassis
        return SimChassis.from_world(time.monotonic, rospy.get_param("~sim_world/world", {}),
                                     **settings.get("~sim"))

    def ros_base():
        return RosChassis(parse_settings(settings.get("~" + ROS_BASE_PARAM)), time.monotonic, NODE_NAME)

    driver = make_driver("chassis", driver_spec, {SIM: simulator, "ros": ros_base},
                         settings.get("~driver_params"), NoChassis)
    sim = driver if driver_spec == SIM else None
    controller = MotionController(driver, limits, cmd_timeout, time.monotonic, log=_log,
                                  obstacle_timeout=obstacle_timeout or None)
    node = RobotControl(controller, owners, rate_hz, status_rate_hz, str(settings.get("~odom_frame")),
                        str(settings.get("~base_frame")), bool(settings.get("~publish_tf")),
                        language, data_root(), sim=sim)
    rospy.on_shutdown(node.shutdown)
    rospy.loginfo("%s: driver %s, %.0f Hz, cmd_timeout %.2f s, safety inputs from %s" % (
        NODE_NAME, driver_spec, rate_hz, cmd_timeout, owners.describe()))
    rospy.spin()
