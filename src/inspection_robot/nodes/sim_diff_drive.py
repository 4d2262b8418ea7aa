"""sim_diff_drive: a stand-in base that behaves like ros_control's diff_drive_controller (sim.diff_drive).

robot_control's ``~driver: ros`` is tested against it: velocity in, odometry / battery / safety
inputs out, a charge relay service, all on the standard message types a real base's driver uses.

Subscribes:  cmd_vel (geometry_msgs/Twist): applied after ~latency, limited, zeroed ~cmd_timeout
                 after the last one (diff_drive_controller's cmd_vel_timeout)
Publishes:   odom (nav_msgs/Odometry, frame odom -> base_link, twist in base_link) at ~odom_rate
             battery_state (sensor_msgs/BatteryState) at ~battery_rate
             estop, bumper (std_msgs/Bool, latched): true while pressed
             charge_relay_state (std_msgs/Bool, latched): true while the relay is closed
Services:    set_charge_relay (std_srvs/SetBool): close (true) / open the charge relay
             test hooks (std_srvs/SetBool): ~press_estop, ~press_bumper, ~stall_odometry and
                 ~stall_battery (true: stop publishing that topic, as a hung or dead driver would)
Parameters:  config/sim_diff_drive.yaml: every setting, its default and meaning (read through ros.node.NodeSettings)
"""
import threading
import time

import rospy
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from sensor_msgs.msg import BatteryState
from std_msgs.msg import Bool
from std_srvs.srv import SetBool, SetBoolResponse

from inspection_robot.angles import quaternion_from_yaw
from inspection_robot.ros.node import NodeSettings, init_node
from inspection_robot.sim.diff_drive import DiffDriveBase

NODE_NAME = "sim_diff_drive"


class SimDiffDriveNode(object):
    def __init__(self, base, odom_rate_hz, battery_rate_hz):
        self._base = base
        self._lock = threading.Lock()
        self._stalled = {"odometry": False, "battery": False}
        self._odom_pub = rospy.Publisher("odom", Odometry, queue_size=10, tcp_nodelay=True)
        self._battery_pub = rospy.Publisher("battery_state", BatteryState, queue_size=2)
        self._estop_pub = rospy.Publisher("estop", Bool, queue_size=1, latch=True)
        self._bumper_pub = rospy.Publisher("bumper", Bool, queue_size=1, latch=True)
        self._relay_pub = rospy.Publisher("charge_relay_state", Bool, queue_size=1, latch=True)
        self._estop_pub.publish(Bool(data=False))
        self._bumper_pub.publish(Bool(data=False))
        self._relay_pub.publish(Bool(data=False))
        rospy.Subscriber("cmd_vel", Twist, self._on_cmd_vel, queue_size=10, tcp_nodelay=True)
        rospy.Service("set_charge_relay", SetBool, self._on_relay)
        rospy.Service("~press_estop", SetBool, self._on_estop)
        rospy.Service("~press_bumper", SetBool, self._on_bumper)
        rospy.Service("~stall_odometry", SetBool, lambda req: self._stall("odometry", req.data))
        rospy.Service("~stall_battery", SetBool, lambda req: self._stall("battery", req.data))
        self._odom_timer = rospy.Timer(rospy.Duration(1.0 / odom_rate_hz), self._publish_odometry)
        self._battery_timer = rospy.Timer(rospy.Duration(1.0 / battery_rate_hz), self._publish_battery)

    def _on_cmd_vel(self, msg):
        with self._lock:
            ok = self._base.command(msg.linear.x, msg.angular.z)
        if not ok:
            rospy.logwarn_throttle(2.0, "%s: non-finite cmd_vel ignored" % NODE_NAME)

    def _on_relay(self, req):
        with self._lock:
            self._base.set_relay(req.data)
        self._relay_pub.publish(Bool(data=req.data))
        rospy.loginfo("%s: charge relay %s" % (NODE_NAME, "closed" if req.data else "open"))
        return SetBoolResponse(success=True, message="relay %s" % ("closed" if req.data else "open"))

    def _on_estop(self, req):
        with self._lock:
            self._base.set_estop(req.data)
        self._estop_pub.publish(Bool(data=req.data))
        return SetBoolResponse(success=True, message="")

    def _on_bumper(self, req):
        with self._lock:
            self._base.bumper = bool(req.data)
        self._bumper_pub.publish(Bool(data=req.data))
        return SetBoolResponse(success=True, message="")

    def _stall(self, what, stalled):
        with self._lock:
            self._stalled[what] = bool(stalled)
        rospy.loginfo("%s: %s %s" % (NODE_NAME, what, "stalled" if stalled else "publishing"))
        return SetBoolResponse(success=True, message="")

    def _publish_odometry(self, _event):
        with self._lock:
            if self._stalled["odometry"]:
                return
            x, y, yaw, vx, wz = self._base.odometry()
        msg = Odometry()
        msg.header.stamp = rospy.Time.now()
        msg.header.frame_id = "odom"
        msg.child_frame_id = "base_link"
        msg.pose.pose.position.x = x
        msg.pose.pose.position.y = y
        _, _, msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = quaternion_from_yaw(yaw)
        msg.twist.twist.linear.x = vx
        msg.twist.twist.angular.z = wz
        self._odom_pub.publish(msg)

    def _publish_battery(self, _event):
        with self._lock:
            if self._stalled["battery"]:
                return
            voltage, current, soc, charging = self._base.battery()
        msg = BatteryState(voltage=voltage, current=current, percentage=soc / 100.0, present=True,
                           temperature=float("nan"), charge=float("nan"), capacity=float("nan"),
                           design_capacity=float("nan"),
                           power_supply_status=(BatteryState.POWER_SUPPLY_STATUS_CHARGING if charging
                                                else BatteryState.POWER_SUPPLY_STATUS_DISCHARGING),
                           power_supply_health=BatteryState.POWER_SUPPLY_HEALTH_GOOD,
                           power_supply_technology=BatteryState.POWER_SUPPLY_TECHNOLOGY_LION)
        msg.header.stamp = rospy.Time.now()
        self._battery_pub.publish(msg)


def main():
    init_node(NODE_NAME)
    settings = NodeSettings("sim_diff_drive")
    odom_rate_hz = float(settings.get("~odom_rate"))
    battery_rate_hz = float(settings.get("~battery_rate"))
    if odom_rate_hz <= 0 or battery_rate_hz <= 0:
        raise ValueError("~odom_rate and ~battery_rate must be positive")
    base = DiffDriveBase(time.monotonic, **settings.get("~base"))
    SimDiffDriveNode(base, odom_rate_hz, battery_rate_hz)
    rospy.loginfo("%s: odometry %.0f Hz, battery %.1f Hz, latency %.3f s"
                  % (NODE_NAME, odom_rate_hz, battery_rate_hz, base.params["latency"]))
    rospy.spin()
