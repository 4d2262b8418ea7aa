"""The simulated chassis: kinematics, acceleration limits, mode switch, battery, faults, IMU."""
import math

import pytest

from inspection_robot.interface import (BATTERY_CHARGING, BATTERY_DISCHARGING, BATTERY_UNDER_VOLTAGE,
                                        CIRCUIT_BATTERY_CRITICAL, CIRCUIT_JOY_COMM_LOST, CIRCUIT_STEPPER_COMM,
                                        MOTOR_INFO_DISCONNECTED, SERVO_DISCONNECTED, WHEEL_STEER, WHEEL_STRAIGHT)
from inspection_robot.motion.chassis import ChassisDriver, ChassisError
from inspection_robot.sim.chassis import FAULTS, SimChassis
from inspection_robot_testing.clock import FakeClock


@pytest.fixture
def clock():
    return FakeClock(100.0)


def sim(clock, **params):
    params.setdefault("encoder_scale_error", 0.0)
    return SimChassis(clock, start_pose=(5.0, 5.0, 0.0), **params)


def test_is_a_chassis_driver(clock):
    assert isinstance(sim(clock), ChassisDriver)


def test_acceleration_limit_and_ground_truth(clock):
    chassis = sim(clock, max_accel_x=0.5)
    chassis.send_velocity(1.0, 0.0, WHEEL_STRAIGHT)
    clock.advance(1.0)
    assert chassis.state().velocity_x == pytest.approx(0.5)
    clock.advance(2.0)
    assert chassis.state().velocity_x == pytest.approx(1.0)
    pose, (vx, _wz) = chassis.true_pose()
    assert pose[0] == pytest.approx(5.0 + 0.25 + 0.75 + 1.0, abs=1e-6)  # 1 s ramp + 1 s ramp-end + 1 s
    assert pose[1] == pytest.approx(5.0)


def test_stop_brakes_harder_than_acceleration(clock):
    chassis = sim(clock, max_accel_x=0.5, brake_decel=2.0)
    chassis.send_velocity(1.0, 0.0, WHEEL_STRAIGHT)
    clock.advance(3.0)
    chassis.stop()
    clock.advance(0.25)
    assert chassis.state().velocity_x == pytest.approx(0.5)
    clock.advance(0.5)
    assert chassis.state().velocity_x == 0.0


def test_straight_mode_limits_yaw_to_turn_radius(clock):
    chassis = sim(clock, min_turn_radius=1.0, max_accel_yaw=10.0, max_accel_x=10.0)
    chassis.send_velocity(0.5, 1.0, WHEEL_STRAIGHT)
    clock.advance(1.0)
    assert chassis.state().velocity_yaw == pytest.approx(0.5)
    chassis.send_velocity(0.0, 1.0, WHEEL_STRAIGHT)
    clock.advance(1.0)
    assert chassis.state().velocity_yaw == pytest.approx(0.0)


def test_switch_to_steer_stops_then_takes_time_then_spins(clock):
    chassis = sim(clock, switch_time=1.0, max_accel_x=1.0, max_accel_yaw=1.0)
    chassis.send_velocity(0.5, 0.0, WHEEL_STRAIGHT)
    clock.advance(1.0)
    chassis.send_velocity(0.0, 0.5, WHEEL_STEER)
    clock.advance(0.6)  # 0.5 s to come to rest, then switching
    state = chassis.state()
    assert state.switching and state.velocity_x == 0.0 and state.velocity_yaw == 0.0
    assert state.wheel_mode == WHEEL_STRAIGHT
    clock.advance(0.95)
    state = chassis.state()
    assert not state.switching and state.wheel_mode == WHEEL_STEER
    clock.advance(1.0)
    state = chassis.state()
    assert state.velocity_x == 0.0 and state.velocity_yaw == pytest.approx(0.5)
    yaw_before = chassis.true_pose()[0][2]
    clock.advance(1.0)
    assert chassis.true_pose()[0][2] - yaw_before == pytest.approx(0.5)
    assert chassis.true_pose()[0][:2] == pytest.approx((5.5, 5.0))  # ramp 0.125 + 0.25 cruise + 0.125 brake


def test_battery_drains_with_motion_and_charges_only_at_dock_with_relay(clock):
    chassis = sim(clock)
    soc0 = chassis._soc
    clock.advance(60.0)
    chassis.state()
    idle = soc0 - chassis._soc
    chassis.send_velocity(1.0, 0.0, WHEEL_STRAIGHT)
    clock.advance(60.0)
    chassis.state()
    moving = soc0 - idle - chassis._soc
    assert moving > 3 * idle > 0
    assert chassis.state().battery_status & BATTERY_DISCHARGING
    chassis.stop()
    chassis.set_charge_relay(True)
    clock.advance(10.0)
    assert not chassis.state().battery_status & BATTERY_CHARGING  # not at a dock
    chassis.inject("at_dock", True)
    clock.advance(10.0)
    state = chassis.state()
    assert state.battery_status & BATTERY_CHARGING and state.battery_current > 0
    assert state.charge_relay


def test_low_battery_fault(clock):
    chassis = sim(clock)
    chassis.inject("low_battery", True)
    state = chassis.state()
    assert state.battery_quantity == 8
    assert state.circuit_status & CIRCUIT_BATTERY_CRITICAL and state.battery_status & BATTERY_UNDER_VOLTAGE
    chassis.inject("low_battery", False)
    assert chassis.state().battery_quantity == 90


def test_faults_set_bits_and_notify(clock):
    chassis = sim(clock)
    calls = []
    chassis.set_safety_listener(lambda: calls.append(1))
    for name in FAULTS:
        chassis.inject(name, True)
    state = chassis.state()
    assert state.hard_estop and state.bumper and state.fall_left and state.fall_right
    assert state.motor_status[0] & SERVO_DISCONNECTED and state.motor_info[0] & MOTOR_INFO_DISCONNECTED
    assert state.circuit_status & CIRCUIT_JOY_COMM_LOST and state.circuit_status & CIRCUIT_STEPPER_COMM
    assert len(calls) == len(FAULTS)
    for name in FAULTS:
        chassis.inject(name, False)
    state = chassis.state()
    assert not (state.hard_estop or state.bumper or state.fall_left or state.fall_right)
    assert state.motor_status[0] == 0 and state.circuit_status == 0
    with pytest.raises(KeyError):
        chassis.inject("meteor", True)


def test_hard_estop_cuts_power(clock):
    chassis = sim(clock)
    chassis.send_velocity(1.0, 0.0, WHEEL_STRAIGHT)
    clock.advance(2.0)
    chassis.inject("hard_estop", True)
    chassis.send_velocity(1.0, 0.0, WHEEL_STRAIGHT)
    clock.advance(1.0)
    assert chassis.state().velocity_x == 0.0


def test_fault_table(clock):
    chassis = sim(clock)
    table = chassis.fault_table()
    assert table.dispatch("bumper", "1") == ("success", "bumper=1")
    assert table.dispatch("at_dock", "1").ack == "success"
    assert table.dispatch("query", "") == ("success", "at_dock,bumper")
    assert table.dispatch("bumper", "yes").ack == "failed"
    assert table.dispatch("meteor", "1") == ("failed", "unknown command 'meteor'")
    assert table.dispatch("set_pose", "1,2,0.5") == ("success", "1,2,0.5")
    assert chassis.true_pose()[0] == (1.0, 2.0, 0.5)
    assert table.dispatch("set_pose", "1,nan,0").ack == "failed"


def test_encoder_error_scales_measured_velocity(clock):
    chassis = SimChassis(clock, encoder_scale_error=0.02, max_accel_x=10.0)
    chassis.send_velocity(0.5, 0.0, WHEEL_STRAIGHT)
    clock.advance(1.0)
    assert chassis.state().velocity_x == pytest.approx(0.51)
    assert chassis.true_pose()[1][0] == pytest.approx(0.5)


def test_bad_commands_raise(clock):
    chassis = sim(clock)
    with pytest.raises(ChassisError):
        chassis.send_velocity(float("nan"), 0.0, WHEEL_STRAIGHT)
    with pytest.raises(ChassisError):
        chassis.send_velocity(0.0, 0.0, 7)
    with pytest.raises(ValueError):
        SimChassis(clock, warp_drive=1)


def test_imu_bias_calibration_and_reset(clock):
    chassis = sim(clock, gyro_bias=0.01)
    clock.advance(10.0)
    assert chassis.imu_reading().yaw == pytest.approx(0.1)
    assert not chassis.imu_reading().calibrated
    chassis.imu_calibrate()
    chassis.imu_reset()
    clock.advance(10.0)
    reading = chassis.imu_reading()
    assert reading.yaw == pytest.approx(0.0) and reading.calibrated
    chassis.send_velocity(0.5, 0.0, WHEEL_STRAIGHT)
    clock.advance(1.0)
    with pytest.raises(ChassisError):
        chassis.imu_calibrate()


def test_temperatures_rise_with_motion(clock):
    chassis = sim(clock)
    t0 = chassis.state().temperatures_c
    chassis.send_velocity(1.0, 0.0, WHEEL_STRAIGHT)
    clock.advance(300.0)
    t1 = chassis.state().temperatures_c
    assert t1[1] > t0[1] + 5.0
    assert all(t is not None and math.isfinite(t) for t in t1)


DOCK_SPEC = {"pose": [2.2, 5.0, 3.1416], "approach_pose": [3.7, 5.0, 3.1416], "tolerance_m": 0.03,
             "tolerance_yaw": 0.05}


def _world_chassis(clock, **params):
    world = {"robot": {"start_pose": [3.7, 5.0, 3.1416]}, "dock": DOCK_SPEC}
    return SimChassis.from_world(clock, world, battery_soc=50.0, **params)


def test_charges_only_docked_within_tolerance_with_relay_and_power(clock):
    chassis = _world_chassis(clock, battery_time_scale=100.0)
    assert chassis.true_pose()[0] == pytest.approx((3.7, 5.0, 3.1416)) and not chassis.docked()
    chassis.set_charge_relay(True)
    clock.advance(1.0)
    state = chassis.state()
    assert not state.battery_status & BATTERY_CHARGING and state.battery_current < 0, "relay on, 1.5 m off the dock"
    # drive 1.5 m forward onto the dock (heading pi: towards -x), stopping within tolerance
    chassis.fault_table().dispatch("set_pose", "2.22,5.0,3.1416")
    assert chassis.docked()
    soc = chassis._soc
    clock.advance(10.0)
    state = chassis.state()
    assert state.battery_status & BATTERY_CHARGING and state.battery_current > 0
    # (10 A - 1.5 A idle) for 10 s, 100 times faster, into 40 Ah
    assert chassis._soc - soc == pytest.approx(100.0 * 8.5 * 10.0 * 100.0 / 3600.0 / 40.0, rel=1e-3)
    chassis.set_charge_relay(False)
    clock.advance(1.0)
    assert not chassis.state().battery_status & BATTERY_CHARGING
    chassis.set_charge_relay(True)
    chassis.inject("charger_off", True)
    clock.advance(1.0)
    assert not chassis.state().battery_status & BATTERY_CHARGING, "dock without power"
    chassis.inject("charger_off", False)
    for pose in ("2.26,5.0,3.1416", "2.2,5.0,3.0"):  # 6 cm off, 8 degrees off
        chassis.fault_table().dispatch("set_pose", pose)
        clock.advance(1.0)
        assert not chassis.docked() and not chassis.state().battery_status & BATTERY_CHARGING, pose


def test_drain_from_idling_driving_and_turning_scales_with_time_scale(clock):
    def drain(scale, command):
        chassis = _world_chassis(clock, battery_time_scale=scale, switch_time=0.0)
        if command:
            chassis.send_velocity(*command)
        clock.advance(2.0)  # ramp up
        soc = chassis.state() and chassis._soc
        clock.advance(10.0)
        chassis.state()
        return soc - chassis._soc
    idle = drain(1.0, None)
    assert idle == pytest.approx(100.0 * 1.5 * 10.0 / 3600.0 / 40.0, rel=1e-3)
    assert drain(60.0, None) == pytest.approx(60.0 * idle, rel=1e-3)
    driving = drain(1.0, (0.5, 0.0, WHEEL_STRAIGHT))
    assert driving == pytest.approx(idle * (1.5 + 12.0 * 0.5) / 1.5, rel=1e-3)
    turning = drain(1.0, (0.0, 0.5, WHEEL_STEER))
    assert turning == pytest.approx(idle * (1.5 + 6.0 * 0.5) / 1.5, rel=1e-3)


def test_set_soc_and_bad_dock_or_scale(clock):
    chassis = _world_chassis(clock)
    table = chassis.fault_table()
    assert table.dispatch("set_soc", "12.5").ack == "success" and chassis.state().battery_quantity == 12
    assert table.dispatch("set_soc", "101").data == "state of charge out of range [0.0, 100.0]: 101.0"
    assert table.dispatch("set_soc", "x").ack == "failed"
    with pytest.raises(ValueError, match="battery_time_scale"):
        _world_chassis(clock, battery_time_scale=0.0)
    with pytest.raises(ValueError, match="dock.approach_pose"):
        SimChassis.from_world(clock, {"dock": {"pose": [1, 2, 0], "approach_pose": [1, 2]}})
    assert SimChassis.from_world(clock, {}).dock is None
