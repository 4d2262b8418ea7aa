#!/usr/bin/env python3
"""rostest: robot_control with ``driver: ros`` against sim_diff_drive, a stand-in diff_drive_controller base.

Backend-mode drive moves the base and its odometry reaches robot_odom; the charge relay switches
through the SetBool service; the base's e-stop and a stalled or killed odometry publisher stop the
robot and raise the fault; a robot_control whose odometry topic never publishes names the setting
and never moves. Latency move_cmd -> cmd_vel -> base odometry -> robot_odom is measured from rest
(arrival times at this test node, one clock) and logged.
"""
import time
import unittest

import rosnode
import rospy
import rostest
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Log
from std_srvs.srv import SetBool

from inspection_robot.interface import (BATTERY_CHARGING, BATTERY_LINE_FAULT, CIRCUIT_STEPPER_COMM,
                                        LIGHT_CHARGE_RELAY, LIGHT_HARD_ESTOP, MODE_SERVER, STOP_FRONT_COLLISION)
from inspection_robot.msg import ControlStatus, GeneralAck, GeneralCmd, MoveCmd
from rostest_helpers import Latest, wait_for, wait_subscribed

SPEED = 300  # move_cmd velocity_x, 0.001 m/s


def percentile(values, fraction):
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(fraction * (len(ordered) - 1))))]


class Robot(object):
    """One robot_control (in namespace ``ns``) as the backend sees it."""

    def __init__(self, ns):
        self.ns = ns
        self.status = Latest(ns + "control_status", ControlStatus, queue_size=1000)
        self.mode_ack = Latest(ns + "mode_ack", GeneralAck, queue_size=100)
        self.control_ack = Latest(ns + "control_ack", GeneralAck, queue_size=100)
        self.cmd_vel = Latest(ns + "cmd_vel", Twist, queue_size=2000)
        self.robot_odom = Latest(ns + "robot_odom", Odometry, queue_size=2000)
        self.mode_pub = rospy.Publisher(ns + "mode_cmd", GeneralCmd, queue_size=10)
        self.move_pub = rospy.Publisher(ns + "move_cmd", MoveCmd, queue_size=10)
        self.control_pub = rospy.Publisher(ns + "control_cmd", GeneralCmd, queue_size=10)
        self.trans_id = 0

    def connect(self):
        for pub in (self.mode_pub, self.move_pub, self.control_pub):
            wait_subscribed(pub, 20.0)
        for sub in (self.status, self.mode_ack, self.control_ack, self.cmd_vel, self.robot_odom):
            sub.wait_connected(20.0)

    def next_id(self):
        self.trans_id += 1
        return self.trans_id

    def acquire(self):
        tid = self.next_id()
        self.mode_pub.publish(GeneralCmd(sender="server", trans_id=tid, cmd="acquire", data="server"))
        return self.mode_ack.wait(lambda m: m.trans_id == tid, 5.0, self.ns + "mode_ack of acquire")

    def control(self, cmd, expect="success"):
        tid = self.next_id()
        self.control_pub.publish(GeneralCmd(sender="server", trans_id=tid, cmd=cmd, data=""))
        ack = self.control_ack.wait(lambda m: m.trans_id == tid, 5.0, "control_ack of " + cmd)
        if expect is not None and ack.ack != expect:
            raise AssertionError("%s: %s %s" % (cmd, ack.ack, ack.data))
        return ack

    def move(self, vx=SPEED):
        self.move_pub.publish(MoveCmd(sender="server", velocity_x=vx, velocity_yaw=0, wheel_control=0))

    def moving_commands_since(self, t0):
        return [m for t, m in list(self.cmd_vel.messages) if t >= t0 and (m.linear.x or m.angular.z)]

    def moving_after_the_stop(self, t0):
        """Moving commands after the first zero one received since ``t0``: robot_control may send a
        few before it sees the cause, none after (one TCPROS connection keeps their order; how soon
        it stops is the soak's measure, at the driver, not a wall-clock window on a loaded machine)."""
        since = [m for t, m in list(self.cmd_vel.messages) if t >= t0]
        first_zero = next((i for i, m in enumerate(since) if not (m.linear.x or m.angular.z)), 0)  # none: all count
        return [m for m in since[first_zero:] if m.linear.x or m.angular.z]


class RosBaseTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_ros_base_driver")
        cls.robot = Robot("/")
        cls.silent = Robot("/silent/")
        cls.odom = Latest("/odom", Odometry, queue_size=2000)
        cls.rosout = Latest("/rosout", Log, queue_size=5000)
        cls.robot.connect()
        cls.silent.connect()
        cls.odom.wait_connected(20.0)
        cls.services = {}
        for name in ("press_estop", "press_bumper", "stall_odometry", "stall_battery"):
            rospy.wait_for_service("/sim_diff_drive/" + name, 20.0)
            cls.services[name] = rospy.ServiceProxy("/sim_diff_drive/" + name, SetBool)
        # the base's inputs all arrived: the drive fault of the start-up has cleared
        cls.robot.status.wait(lambda m: not m.circuit_status & CIRCUIT_STEPPER_COMM, 10.0, "base reporting")
        ack = cls.robot.acquire()
        if ack.ack != "success":
            raise AssertionError("acquire server: %s" % ack.data)

    def setUp(self):
        self.robot.status.wait(lambda m: m.mode == MODE_SERVER, 5.0, "server mode")

    def hook(self, name, on):
        self.assertTrue(self.services[name](data=on).success)

    def release(self, hook):
        """Release a simulated stop input and clear robot_control's latched stop (idempotent)."""
        self.hook(hook, False)
        self.robot.control("disable_stop", expect=None)

    def base_at_rest(self):
        self.odom.wait(lambda m: m.twist.twist.linear.x == 0.0, 5.0, "base at rest")

    def drive(self, seconds, until=None):
        """move_cmd at 20 Hz (a backend's rate) for ``seconds`` or until ``until()`` is truthy."""
        t_end = time.monotonic() + seconds
        while time.monotonic() < t_end:
            self.robot.move()
            if until is not None and until():
                return True
            rospy.sleep(0.05)   # pacing a command stream, not synchronisation
        return False

    def error_logged(self, *fragments, since=0.0, node="/robot_control"):
        return next((m for t, m in list(self.rosout.messages) if t >= since and m.level >= Log.ERROR
                     and m.name == node and all(f in m.msg for f in fragments)), None)

    # --- drive --------------------------------------------------------------------------------
    def test_a_drive_moves_the_base_and_odometry_flows(self):
        """Backend drive: the base moves at the commanded speed, robot_odom integrates its odometry;
        latency measured from rest over several starts."""
        latencies = {"move_cmd->cmd_vel": [], "move_cmd->base odom": [], "move_cmd->robot_odom": []}
        x_start = self.robot.robot_odom.last.pose.pose.position.x
        for _trial in range(8):
            self.base_at_rest()
            t0 = time.monotonic()
            self.robot.move()

            def first(sub, predicate):
                return next((t for t, m in list(sub.messages) if t >= t0 and predicate(m)), None)
            t_cmd = wait_for(lambda: first(self.robot.cmd_vel, lambda m: m.linear.x > 0), 2.0, "cmd_vel")
            t_odom = wait_for(lambda: first(self.odom, lambda m: m.twist.twist.linear.x > 0), 2.0, "odom moving")
            t_robot = wait_for(lambda: first(self.robot.robot_odom, lambda m: m.twist.twist.linear.x > 0), 2.0,
                               "robot_odom moving")
            latencies["move_cmd->cmd_vel"].append(t_cmd - t0)
            latencies["move_cmd->base odom"].append(t_odom - t0)
            latencies["move_cmd->robot_odom"].append(t_robot - t0)
            self.assertTrue(self.drive(1.5, lambda: self.robot.robot_odom.last.twist.twist.linear.x > 0.29),
                            "robot_odom never reached the commanded 0.3 m/s")
        for name, values in latencies.items():
            line = ("latency %s: p50 %.1f ms, max %.1f ms (n = %d)"
                    % (name, percentile(values, 0.5) * 1000, max(values) * 1000, len(values)))
            rospy.loginfo(line)
            print(line)
        # the base's steady speed: the drive above ends once robot_odom passes 0.29 m/s, which can come
        # before the base reports its full speed (a fresh-clone run saw 0.288): keep commanding until
        # it does (a condition; 10 s is a bound for a base that never gets there)
        self.drive(10.0, lambda: self.odom.last.twist.twist.linear.x >= 0.298)
        odom = max(m.twist.twist.linear.x for t, m in list(self.odom.messages) if t >= t0)
        self.assertAlmostEqual(odom, 0.303, delta=0.005)  # 0.3 m/s read 1 % long by the base's odometry
        self.base_at_rest()
        self.assertGreater(self.robot.robot_odom.last.pose.pose.position.x - x_start, 1.0)
        self.assertLess(percentile(latencies["move_cmd->robot_odom"], 0.5), 0.2)

    def test_b_charge_relay_through_the_service(self):
        self.robot.control("enable_charge")
        self.robot.status.wait(lambda m: m.light_status & LIGHT_CHARGE_RELAY, 3.0, "relay closed (light b0)")
        self.robot.status.wait(lambda m: m.battery_status & BATTERY_CHARGING and m.battery_current > 0, 5.0,
                               "charging current")
        self.robot.control("disable_charge")
        self.robot.status.wait(lambda m: not m.light_status & LIGHT_CHARGE_RELAY, 3.0, "relay open")
        self.robot.status.wait(lambda m: m.battery_current < 0, 5.0, "discharging again")

    def test_c_estop_and_bumper_stop(self):
        self.assertTrue(self.drive(3.0, lambda: self.odom.last.twist.twist.linear.x > 0.2), "not moving")
        t0 = time.monotonic()
        self.hook("press_estop", True)
        self.addCleanup(self.release, "press_estop")  # a failure here leaves the next tests a base that moves
        self.robot.status.wait(lambda m: m.light_status & LIGHT_HARD_ESTOP, 2.0, "hard e-stop reported")
        wait_for(lambda: any(t >= t0 and not m.linear.x for t, m in list(self.robot.cmd_vel.messages)), 2.0,
                 "zero cmd_vel after the e-stop")
        self.drive(0.5)
        self.assertEqual(self.robot.moving_after_the_stop(t0), [])
        self.base_at_rest()
        self.hook("press_estop", False)
        self.robot.status.wait(lambda m: not m.light_status & LIGHT_HARD_ESTOP, 2.0, "e-stop released")
        self.robot.control("disable_stop")
        self.assertTrue(self.drive(3.0, lambda: self.odom.last.twist.twist.linear.x > 0.2), "moves again")
        t0 = time.monotonic()
        self.hook("press_bumper", True)
        self.addCleanup(self.release, "press_bumper")
        self.robot.status.wait(lambda m: m.stop_status & STOP_FRONT_COLLISION, 2.0, "bumper stop")
        self.drive(0.5)
        self.assertEqual(self.robot.moving_after_the_stop(t0), [])
        self.hook("press_bumper", False)
        self.base_at_rest()

    def test_d_stalled_odometry_stops_and_raises_the_fault(self):
        self.assertTrue(self.drive(3.0, lambda: self.odom.last.twist.twist.linear.x > 0.2), "not moving")
        t0 = time.monotonic()
        self.hook("stall_odometry", True)
        self.robot.status.wait(lambda m: m.circuit_status & CIRCUIT_STEPPER_COMM, 2.0, "drive fault (circuit b0)")
        t_stop = wait_for(lambda: next((t for t, m in list(self.robot.cmd_vel.messages)
                                        if t >= t0 and not m.linear.x), None), 2.0, "zero cmd_vel")
        line = "stalled odometry -> zero cmd_vel: %.0f ms (odom_timeout 500 ms)" % ((t_stop - t0) * 1000)
        rospy.loginfo(line)
        print(line)
        self.assertLess(t_stop - t0, 0.5 + 0.2)
        wait_for(lambda: self.error_logged("ros_base/odom_topic (/odom)", "stale", "ros_base/odom_timeout",
                                           since=t0), 3.0, "error naming ros_base/odom_topic")
        self.drive(0.6)
        self.assertEqual(self.robot.moving_after_the_stop(t0), [])
        self.hook("stall_odometry", False)
        self.robot.status.wait(lambda m: not m.circuit_status & CIRCUIT_STEPPER_COMM, 2.0, "fault cleared")
        self.base_at_rest()
        self.assertTrue(self.drive(3.0, lambda: self.odom.last.twist.twist.linear.x > 0.2), "a new move_cmd moves")
        t0 = time.monotonic()
        self.hook("stall_battery", True)
        self.robot.status.wait(lambda m: m.circuit_status & CIRCUIT_STEPPER_COMM
                               and m.battery_status & BATTERY_LINE_FAULT, 8.0, "battery stale fault")
        self.drive(0.5)
        self.assertEqual(self.robot.moving_commands_since(time.monotonic() - 0.4), [])
        self.hook("stall_battery", False)
        self.robot.status.wait(lambda m: not m.circuit_status & CIRCUIT_STEPPER_COMM, 3.0, "battery fault cleared")
        self.assertTrue(self.error_logged("ros_base/battery_topic", "stale", since=t0))

    def test_e_silent_odometry_at_start_names_the_setting_and_never_moves(self):
        wait_for(lambda: self.error_logged("ros_base/odom_topic (/silent/odom)", "since start",
                                           node="/silent/robot_control"), 10.0,
                 "start-up error naming ros_base/odom_topic")
        status = self.silent.status.wait(lambda m: m.circuit_status & CIRCUIT_STEPPER_COMM, 3.0, "drive fault")
        self.assertGreater(status.battery_voltage, 400)   # the battery topic it was given does report
        ack = self.silent.acquire()
        self.assertEqual(ack.ack, "success", ack.data)
        self.assertIn("motion blocked: drive_fault", ack.data)
        t0 = time.monotonic()
        for _ in range(20):
            self.silent.move()
            rospy.sleep(0.05)   # pacing a command stream
        wait_for(lambda: any(t >= t0 for t, _m in list(self.silent.cmd_vel.messages)), 2.0, "silent cmd_vel")
        self.assertEqual(self.silent.moving_commands_since(0.0), [])
        ack = self.silent.control("enable_charge", expect="failed")
        self.assertIn("charge relay not wired: set ros_base/charge_relay_service", ack.data)

    def test_z_killed_base_stops_and_raises_the_fault(self):
        self.assertTrue(self.drive(3.0, lambda: self.odom.last.twist.twist.linear.x > 0.2), "not moving")
        t0 = time.monotonic()
        rosnode.kill_nodes(["/sim_diff_drive"])
        self.robot.status.wait(lambda m: m.circuit_status & CIRCUIT_STEPPER_COMM, 3.0, "drive fault after the kill")
        wait_for(lambda: self.error_logged("ros_base/odom_topic", "stale", since=t0), 3.0, "error after the kill")
        self.drive(0.5)
        self.assertEqual(self.robot.moving_after_the_stop(t0), [])
        self.assertEqual(self.robot.status.last.mode, MODE_SERVER)   # a drive fault stops, it does not release


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_ros_base_driver", RosBaseTest)
