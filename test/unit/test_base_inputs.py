"""The pure half of driver ros: settings, staleness -> fault bits, battery units, safety inputs, relay."""
import math
import os

import pytest
import yaml

from inspection_robot.interface import (BATTERY_CHARGING, BATTERY_DISCHARGING, BATTERY_HIGH_TEMP,
                                        BATTERY_LINE_FAULT, BATTERY_UNDER_VOLTAGE, CIRCUIT_BATTERY_CRITICAL,
                                        CIRCUIT_COLLISION_LINE, CIRCUIT_STEPPER_COMM, LIGHT_CHARGE_RELAY,
                                        MODE_SERVER, TEMP_BATTERY, WHEEL_STRAIGHT)
from inspection_robot.motion import base_inputs
from inspection_robot.motion.chassis import ChassisDriver, ChassisError, NoChassis
from inspection_robot.motion.controller import MotionController
from inspection_robot.motion.base_inputs import BaseInputs, SettingsError, battery_from_message, parse_settings
from inspection_robot.motion.status import control_status_fields
from inspection_robot.motion.safety import SafetyLatch
from inspection_robot.motion.velocity import VelocityLimits
from inspection_robot_testing.clock import FakeClock

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@pytest.fixture
def clock():
    return FakeClock(100.0)


def inputs(clock, **settings):
    return BaseInputs(parse_settings(settings), clock)


def state(base):
    return base.state(WHEEL_STRAIGHT, False, (False, False, False))


def battery(percentage=0.8, status=2, health=1, voltage=48.34, current=-2.46, temperature=31.0):
    return battery_from_message(voltage, current, percentage, status, health, temperature, 10.0)


# --- settings ---------------------------------------------------------------------------------
def test_config_file_holds_every_setting_with_its_default():
    with open(os.path.join(ROOT, "config", "robot_control.yaml")) as f:
        config = yaml.safe_load(f)["ros_base"]
    assert list(config) == list(base_inputs.SETTINGS)
    assert parse_settings(config) == parse_settings({})


@pytest.mark.parametrize("values, fragment", [
    ({"odom_timeuot": 1.0}, "unknown setting(s) odom_timeuot"),
    ({"odom_timeout": 0}, "ros_base/odom_timeout must be a positive number"),
    ({"battery_timeout": float("nan")}, "ros_base/battery_timeout"),
    ({"relay_timeout": True}, "ros_base/relay_timeout"),
    ({"battery_critical_percent": 150}, "at most 100"),
    ({"odom_topic": ""}, "ros_base/odom_topic must name a topic"),
    ({"cmd_vel_topic": 5}, "ros_base/cmd_vel_topic must be a ROS name"),
    ({"estop_topic": "my estop"}, "ros_base/estop_topic"),
    ({"charge_relay_service": "relay", "charge_relay_topic": "relay_cmd"}, "both set"),
])
def test_bad_settings_name_the_setting(values, fragment):
    with pytest.raises(SettingsError) as err:
        parse_settings(values)
    assert fragment in str(err.value)


def test_settings_must_be_a_dict():
    with pytest.raises(SettingsError, match="ros_base must be a dict"):
        parse_settings("cmd_vel")


def test_battery_constants_match_the_message():
    from sensor_msgs.msg import BatteryState
    assert base_inputs.POWER_SUPPLY_STATUS_CHARGING == BatteryState.POWER_SUPPLY_STATUS_CHARGING
    assert base_inputs.POWER_SUPPLY_STATUS_DISCHARGING == BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
    assert base_inputs.POWER_SUPPLY_HEALTH_OVERHEAT == BatteryState.POWER_SUPPLY_HEALTH_OVERHEAT
    assert base_inputs.POWER_SUPPLY_HEALTH_DEAD == BatteryState.POWER_SUPPLY_HEALTH_DEAD
    assert base_inputs.POWER_SUPPLY_HEALTH_OVERVOLTAGE == BatteryState.POWER_SUPPLY_HEALTH_OVERVOLTAGE
    assert base_inputs.POWER_SUPPLY_HEALTH_COLD == BatteryState.POWER_SUPPLY_HEALTH_COLD


# --- staleness --------------------------------------------------------------------------------
def test_nothing_received_is_a_drive_fault_that_stops(clock):
    base = inputs(clock)
    s = state(base)
    assert s.circuit_status & CIRCUIT_STEPPER_COMM
    assert s.battery_status & BATTERY_LINE_FAULT
    latch = SafetyLatch()
    latch.update_chassis(s)
    assert latch.reasons() == ["drive_fault"]
    assert [p.setting for p in base.problems()] == ["odom_topic", "battery_topic"]


def test_start_up_is_quiet_until_startup_timeout_then_names_the_setting(clock):
    base = inputs(clock, startup_timeout=3.0)
    assert base.reports() == ([], [])
    clock.now += 3.5
    new, cleared = base.reports()
    assert [p.setting for p in new] == ["odom_topic", "battery_topic"]
    assert "no nav_msgs/Odometry received on 'odom' since start 3.5 s ago" in new[0].text
    assert cleared == []
    assert base.reports() == ([], [])   # once


def test_fresh_odometry_gives_the_velocity_and_stale_odometry_stops(clock):
    base = inputs(clock, battery_topic="", odom_timeout=0.5)
    base.on_odometry(0.42, -0.1)
    s = state(base)
    assert (s.velocity_x, s.velocity_yaw) == (0.42, -0.1)
    assert s.circuit_status == 0
    clock.now += 0.5
    assert state(base).circuit_status == 0
    clock.now += 0.01
    s = state(base)
    assert s.circuit_status & CIRCUIT_STEPPER_COMM
    assert (s.velocity_x, s.velocity_yaw) == (0.0, 0.0)
    new, _ = base.reports()
    assert new[0].setting == "odom_topic"
    assert "stale: last 0.51 s ago (ros_base/odom_timeout 0.50 s)" in new[0].text
    base.on_odometry(0.0, 0.0)
    assert base.reports() == ([], ["odom_topic"])
    assert state(base).circuit_status == 0


def test_non_finite_odometry_is_ignored(clock):
    base = inputs(clock, battery_topic="")
    assert not base.on_odometry(float("nan"), 0.0)
    assert state(base).circuit_status & CIRCUIT_STEPPER_COMM


def test_stale_battery_stops_and_marks_the_battery_line(clock):
    base = inputs(clock, battery_timeout=5.0)
    base.on_odometry(0.0, 0.0)
    base.on_battery(battery())
    assert state(base).circuit_status == 0
    clock.now += 5.1
    base.on_odometry(0.0, 0.0)
    s = state(base)
    assert s.circuit_status == CIRCUIT_STEPPER_COMM
    assert s.battery_status & BATTERY_LINE_FAULT
    assert s.battery_voltage == pytest.approx(48.34)   # the last value stays visible


# --- battery units ----------------------------------------------------------------------------
def test_battery_state_in_spec_units(clock):
    base = inputs(clock)
    base.on_odometry(0.0, 0.0)
    base.on_battery(battery())
    fields = control_status_fields(0, SafetyLatch(), state(base))
    assert fields["battery_voltage"] == 483       # 0.1 V
    assert fields["battery_current"] == -25       # 0.1 A, - = discharging
    assert fields["battery_quantity"] == 80       # %
    assert fields["battery_status"] == BATTERY_DISCHARGING
    assert fields["temperature"][TEMP_BATTERY] == 310   # 0.1 degC
    assert fields["circuit_status"] == 0


def test_battery_flags_and_unknowns():
    charging = battery(percentage=0.05, status=1, health=2)
    assert charging.status_bits == BATTERY_CHARGING | BATTERY_HIGH_TEMP | BATTERY_UNDER_VOLTAGE
    unknown = battery_from_message(float("nan"), float("nan"), float("nan"), 0, 0, float("nan"), 10.0)
    assert unknown == base_inputs.Battery(0.0, 0.0, None, 0, None)


def test_critical_battery_sets_circuit_b7_but_does_not_stop(clock):
    base = inputs(clock)
    base.on_odometry(0.0, 0.0)
    base.on_battery(battery(percentage=0.05))
    s = state(base)
    assert s.circuit_status == CIRCUIT_BATTERY_CRITICAL
    latch = SafetyLatch()
    latch.update_chassis(s)
    assert latch.reasons() == []


# --- safety inputs and relay ------------------------------------------------------------------
def test_wired_safety_input_must_report_before_motion(clock):
    base = inputs(clock, battery_topic="", estop_topic="estop", bumper_topic="bumper")
    base.on_odometry(0.0, 0.0)
    s = state(base)
    assert s.circuit_status == CIRCUIT_STEPPER_COMM | CIRCUIT_COLLISION_LINE
    assert {p.setting for p in base.problems()} == {"estop_topic", "bumper_topic"}
    assert base.on_switch("hard_estop", False) and base.on_switch("bumper", True)
    assert not base.on_switch("bumper", True)
    s = state(base)
    assert s.circuit_status == 0 and s.bumper and not s.hard_estop
    assert base.on_switch("hard_estop", True)
    assert state(base).hard_estop


def test_unwired_safety_inputs_are_inactive(clock):
    base = inputs(clock, battery_topic="")
    base.on_odometry(0.0, 0.0)
    s = state(base)
    assert not (s.hard_estop or s.bumper or s.fall_left or s.fall_right)
    assert s.circuit_status == 0


def test_relay_reported_by_the_base_wins_over_the_command(clock):
    base = inputs(clock, battery_topic="", charge_relay_state_topic="relay_state")
    assert base.state(WHEEL_STRAIGHT, True, (False,) * 3).charge_relay
    base.on_relay_state(False)
    assert not base.state(WHEEL_STRAIGHT, True, (False,) * 3).charge_relay


# --- with the controller ----------------------------------------------------------------------
class InputsDriver(ChassisDriver):
    """The ROS driver's logic without ROS: BaseInputs behind the ChassisDriver calls."""

    def __init__(self, base):
        self.base = base
        self.sent = []
        self.relay = False

    def set_safety_listener(self, listener):
        self.listener = listener

    def send_velocity(self, velocity_x, velocity_yaw, wheel_mode):
        self.sent.append((velocity_x, velocity_yaw))

    def stop(self):
        self.sent.append("stop")

    def state(self):
        return self.base.state(WHEEL_STRAIGHT, self.relay, (False,) * 3)

    def set_charge_relay(self, closed):
        self.relay = closed

    def set_lamps(self, red, green, blue):
        pass


def test_stale_odometry_stops_the_controller_within_one_cycle(clock):
    base = inputs(clock, battery_topic="", odom_timeout=0.5)
    driver = InputsDriver(base)
    ctl = MotionController(driver, VelocityLimits(1.0, 1.0, 5.0, 5.0), 10.0, clock)
    assert ctl.on_mode_cmd("server", "acquire", "server").accepted
    ctl.tick()                           # the control cycle reads the driver's state
    reply = ctl.on_move_cmd("server", 500, 0, 0)
    assert reply.ack == "failed" and "drive_fault" in reply.data   # no odometry yet: never moves
    assert all(cmd == "stop" or cmd == (0.0, 0.0) for cmd in driver.sent)
    base.on_odometry(0.0, 0.0)
    driver.listener()                    # odometry back: the ROS driver tells robot_control at once
    assert ctl.on_move_cmd("server", 500, 0, 0).ack == "success"
    for _ in range(20):
        clock.now += 0.02
        base.on_odometry(0.5, 0.0)
        ctl.tick()
    assert driver.sent[-1] == (0.5, 0.0)
    clock.now += 0.52                    # the base falls silent
    ctl.tick()
    assert driver.sent[-2:] == ["stop", (0.0, 0.0)]
    assert ctl.target is None and ctl.mode == MODE_SERVER
    assert ctl.status()["circuit_status"] & CIRCUIT_STEPPER_COMM


def test_charge_relay_failure_is_a_failed_ack_not_a_crash(clock):
    ctl = MotionController(NoChassis(), VelocityLimits(1.0, 1.0, 5.0, 5.0), 0.5, clock)
    reply = ctl.on_control_cmd("server", "enable_charge", "")
    assert reply.ack == "failed"
    assert reply.data == "charge relay: chassis not fitted (driver: none)"
    base = inputs(clock, battery_topic="")
    ctl = MotionController(InputsDriver(base), VelocityLimits(1.0, 1.0, 5.0, 5.0), 0.5, clock)
    assert ctl.on_control_cmd("server", "enable_charge", "").ack == "success"
    assert ctl.status()["light_status"] & LIGHT_CHARGE_RELAY


def test_imu_reset_refused_by_the_driver_is_a_failed_ack(clock):
    class NoImu(InputsDriver):
        def imu_reset(self):
            raise ChassisError("no IMU with driver ros")
    ctl = MotionController(NoImu(inputs(clock, battery_topic="")), VelocityLimits(1.0, 1.0, 5.0, 5.0), 0.5, clock)
    reply = ctl.on_imu_cmd("reset", "")
    assert (reply.ack, reply.data) == ("failed", "no IMU with driver ros")


def test_yaw_of_quaternion_reaches_the_attitude(clock):
    base = inputs(clock, battery_topic="")
    base.on_odometry(0.0, 0.0, yaw=math.pi / 2)
    assert base.attitude() == (0.0, 0.0, math.pi / 2)
