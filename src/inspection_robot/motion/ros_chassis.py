"""RosChassis: ``~driver: ros``, a ChassisDriver for any base with a ROS driver (the ROS half).

Velocity goes out as geometry_msgs/Twist, odometry, battery and safety inputs come in on topics,
the charge relay goes through a std_srvs/SetBool service or a std_msgs/Bool topic. What the
inputs amount to (staleness, fault bits, units) is decided by the pure motion.base_inputs.BaseInputs;
this module only wires topics to it. Topic names are relative to robot_control's namespace.

Threading: subscriber callbacks store under the driver's own lock and call the safety listener
(robot_control re-reads ``state()`` under its lock) when a Bool safety input changes or odometry
comes back; staleness needs no event: robot_control reads ``state()`` every control cycle. The relay
service is called on one worker thread and waited for at most ``relay_timeout``.
"""
import threading

import rospy
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from sensor_msgs.msg import BatteryState
from std_msgs.msg import Bool
from std_srvs.srv import SetBool

from inspection_robot.angles import yaw_from_quaternion
from inspection_robot.interface import WHEEL_STRAIGHT
from inspection_robot.motion.chassis import ChassisDriver, ChassisError, ImuReading
from inspection_robot.motion.base_inputs import PARAM, SAFETY_INPUTS, BaseInputs, battery_from_message

CHECK_PERIOD_S = 0.1   # how often input problems are looked for, to log them (the robot stops regardless)


class RosChassis(ChassisDriver):
    """settings: motion.base_inputs.Settings; clock(): monotonic seconds; node: the name in log lines."""

    def __init__(self, settings, clock, node="robot_control"):
        self.settings = settings
        self._node = node
        self._lock = threading.Lock()
        self._inputs = BaseInputs(settings, clock)
        self._listener = lambda: None
        self._wheel_mode = WHEEL_STRAIGHT
        self._relay = False
        self._lamps = (False, False, False)
        self._odom_was_fresh = False
        self._relay_busy = threading.Lock()
        self._cmd_pub = rospy.Publisher(settings.cmd_vel_topic, Twist, queue_size=10)
        self._relay_pub = (rospy.Publisher(settings.charge_relay_topic, Bool, queue_size=1, latch=True)
                           if settings.charge_relay_topic else None)
        self._relay_srv = (rospy.ServiceProxy(settings.charge_relay_service, SetBool)
                           if settings.charge_relay_service else None)
        self._subs = [rospy.Subscriber(settings.odom_topic, Odometry, self._on_odom, queue_size=10,
                                       tcp_nodelay=True)]
        if settings.battery_topic:
            self._subs.append(rospy.Subscriber(settings.battery_topic, BatteryState, self._on_battery, queue_size=2))
        for name, (setting, _bit) in SAFETY_INPUTS.items():
            topic = getattr(settings, setting)
            if topic:
                self._subs.append(rospy.Subscriber(topic, Bool, self._on_switch, callback_args=name, queue_size=10,
                                                   tcp_nodelay=True))
        if settings.charge_relay_state_topic:
            self._subs.append(rospy.Subscriber(settings.charge_relay_state_topic, Bool, self._on_relay_state,
                                               queue_size=2))
        self._timer = rospy.Timer(rospy.Duration(CHECK_PERIOD_S), self._check)

    # --- inputs --------------------------------------------------------------------------------
    def _on_odom(self, msg):
        twist = msg.twist.twist
        orientation = msg.pose.pose.orientation
        with self._lock:
            fresh_before = self._inputs.odometry_fresh()
            ok = self._inputs.on_odometry(twist.linear.x, twist.angular.z,
                                          yaw=yaw_from_quaternion(orientation.x, orientation.y, orientation.z,
                                                                  orientation.w))
        if not ok:
            rospy.logwarn_throttle(2.0, "%s: %s/odom_topic %r: non-finite velocity ignored"
                                   % (self._node, PARAM, self.settings.odom_topic))
        elif not fresh_before:
            self._listener()

    def _on_battery(self, msg):
        battery = battery_from_message(msg.voltage, msg.current, msg.percentage, msg.power_supply_status,
                                       msg.power_supply_health, msg.temperature,
                                       self.settings.battery_critical_percent)
        with self._lock:
            self._inputs.on_battery(battery)

    def _on_switch(self, msg, name):
        with self._lock:
            changed = self._inputs.on_switch(name, msg.data)
        if changed:
            self._listener()

    def _on_relay_state(self, msg):
        with self._lock:
            changed = self._inputs.on_relay_state(msg.data)
        if changed:
            self._listener()

    def _check(self, _event):
        """Log each input problem once when it appears (the stop itself happens in state())."""
        with self._lock:
            new, cleared = self._inputs.reports()
        for problem in new:
            rospy.logerr("%s: driver ros: %s/%s (%s): %s; robot held stopped (drive fault, circuit_status b0)"
                         % (self._node, PARAM, problem.setting,
                            rospy.resolve_name(getattr(self.settings, problem.setting)), problem.text))
        for setting in cleared:
            rospy.loginfo("%s: driver ros: %s/%s %r reporting again"
                          % (self._node, PARAM, setting, getattr(self.settings, setting)))

    # --- ChassisDriver -------------------------------------------------------------------------
    def set_safety_listener(self, listener):
        self._listener = listener

    def send_velocity(self, velocity_x, velocity_yaw, wheel_mode):
        self._wheel_mode = wheel_mode
        msg = Twist()
        msg.linear.x = velocity_x
        msg.angular.z = velocity_yaw
        self._cmd_pub.publish(msg)

    def stop(self):
        self._cmd_pub.publish(Twist())

    def state(self):
        with self._lock:
            return self._inputs.state(self._wheel_mode, self._relay, self._lamps)

    def set_charge_relay(self, closed):
        closed = bool(closed)
        if self._relay_pub is not None:
            self._relay_pub.publish(Bool(data=closed))
        elif self._relay_srv is not None:
            self._call_relay_service(closed)
        else:
            raise ChassisError("charge relay not wired: set %s/charge_relay_service (std_srvs/SetBool) or "
                               "%s/charge_relay_topic (std_msgs/Bool)" % (PARAM, PARAM))
        self._relay = closed

    def _call_relay_service(self, closed):
        """Call the SetBool service on a worker thread, waiting at most relay_timeout (robot_control
        holds its lock meanwhile). A call still hanging from before refuses at once."""
        name = self.settings.charge_relay_service
        if not self._relay_busy.acquire(blocking=False):
            raise ChassisError("%s/charge_relay_service %r: the previous request is still unanswered" % (PARAM, name))
        result = {}

        def call():
            try:
                result["reply"] = self._relay_srv(data=closed)
            except (rospy.ServiceException, rospy.ROSException) as err:
                result["error"] = str(err)
            finally:
                self._relay_busy.release()
                done.set()
        done = threading.Event()
        threading.Thread(target=call, name="charge_relay", daemon=True).start()
        if not done.wait(self.settings.relay_timeout):
            raise ChassisError("%s/charge_relay_service %r: no answer within %.1f s"
                               % (PARAM, name, self.settings.relay_timeout))
        if "error" in result:
            raise ChassisError("%s/charge_relay_service %r: %s" % (PARAM, name, result["error"]))
        if not result["reply"].success:
            raise ChassisError("%s/charge_relay_service %r refused: %s" % (PARAM, name, result["reply"].message))

    def set_lamps(self, red, green, blue):
        self._lamps = (bool(red), bool(green), bool(blue))   # a ROS base has no lamp interface: state only

    def imu_calibrate(self):
        raise ChassisError("no IMU with driver ros (the base's odometry carries the heading)")

    def imu_reset(self):
        raise ChassisError("no IMU with driver ros (the base's odometry carries the heading)")

    def imu_reading(self):
        with self._lock:
            roll, pitch, yaw = self._inputs.attitude()
        return ImuReading(roll, pitch, yaw, False)

    def close(self):
        self.stop()
        self._timer.shutdown()
        for sub in self._subs:
            sub.unregister()
