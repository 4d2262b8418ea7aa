"""The stand-in diff_drive_controller base: latency, limits, cmd timeout, odometry drift, e-stop, battery."""
import math

import pytest

from inspection_robot.sim.diff_drive import DiffDriveBase
from inspection_robot_testing.clock import FakeClock


def base(clock, **params):
    params.setdefault("odom_scale_error", 0.0)
    params.setdefault("odom_yaw_error", 0.0)
    return DiffDriveBase(clock, **params)


def run(clock, drive, seconds, vx, wz=0.0, period=0.02):
    """cmd_vel at 50 Hz for ``seconds``, as robot_control sends it."""
    for _ in range(int(round(seconds / period))):
        drive.command(vx, wz)
        clock.now += period


def test_command_takes_effect_after_the_latency():
    clock = FakeClock(10.0)
    drive = base(clock, latency=0.05, max_accel_x=100.0)
    drive.command(0.5, 0.0)
    clock.now += 0.049
    assert drive.odometry()[3] == 0.0
    clock.now += 0.011
    assert drive.odometry()[3] == pytest.approx(0.5)


def test_acceleration_and_velocity_limits():
    clock = FakeClock(10.0)
    drive = base(clock, latency=0.0, max_accel_x=1.0, max_velocity_x=0.8, max_accel_yaw=2.0, max_velocity_yaw=1.0)
    run(clock, drive, 0.4, 5.0, 5.0)
    _x, _y, _yaw, vx, wz = drive.odometry()
    assert vx == pytest.approx(0.4, abs=0.03) and wz == pytest.approx(0.8, abs=0.05)
    run(clock, drive, 1.0, 5.0, 5.0)
    assert drive.odometry()[3:] == pytest.approx((0.8, 1.0))


def test_cmd_timeout_brings_it_to_rest():
    clock = FakeClock(10.0)
    drive = base(clock, latency=0.0, max_accel_x=1.0, cmd_timeout=0.5)
    run(clock, drive, 1.0, 0.5)
    clock.now += 0.45                                   # 0.47 s after the last command
    assert drive.odometry()[3] == pytest.approx(0.5)   # still within cmd_timeout
    clock.now += 0.6
    assert drive.odometry()[3] == 0.0


def test_odometry_drifts_by_the_configured_scale():
    clock = FakeClock(10.0)
    drive = DiffDriveBase(clock, latency=0.0, max_accel_x=100.0, odom_scale_error=0.02, odom_yaw_error=0.0)
    run(clock, drive, 2.0, 0.5)
    x, _y, _yaw, vx, _wz = drive.odometry()
    assert vx == pytest.approx(0.51)
    assert x == pytest.approx(drive.true_pose[0] * 1.02, rel=1e-6)
    assert drive.true_pose[0] == pytest.approx(1.0, abs=0.02)


def test_turning_integrates_the_heading():
    clock = FakeClock(10.0)
    drive = base(clock, latency=0.0, max_accel_x=100.0, max_accel_yaw=100.0)
    run(clock, drive, 2 * math.pi / 0.5, 0.5, 0.5)   # a full circle of radius 1 m
    x, y, yaw, _vx, _wz = drive.odometry()
    assert (x, y) == pytest.approx((0.0, 0.0), abs=0.03)
    assert abs(yaw) < 0.03


def test_estop_cuts_the_motors_and_ignores_commands():
    clock = FakeClock(10.0)
    drive = base(clock, latency=0.0, max_accel_x=100.0, estop_decel=2.0)
    run(clock, drive, 0.2, 1.0)
    drive.set_estop(True)
    run(clock, drive, 0.25, 1.0)
    assert drive.odometry()[3] == pytest.approx(0.5, abs=0.03)
    run(clock, drive, 0.5, 1.0)
    assert drive.odometry()[3] == 0.0


def test_battery_drains_and_charges_with_the_relay():
    clock = FakeClock(10.0)
    drive = base(clock, battery_soc=50.0, battery_time_scale=100.0)
    clock.now += 60.0
    voltage, current, soc, charging = drive.battery()
    assert current == pytest.approx(-1.5) and not charging and soc < 50.0
    drive.set_relay(True)
    clock.now += 60.0
    voltage2, current, soc2, charging = drive.battery()
    assert current > 0 and charging and soc2 > soc and voltage2 > voltage


def test_bad_input_and_parameters_refused():
    clock = FakeClock(10.0)
    drive = base(clock)
    assert not drive.command(float("nan"), 0.0)
    with pytest.raises(ValueError, match="unknown diff drive parameter"):
        DiffDriveBase(clock, max_speed=1.0)
    with pytest.raises(ValueError, match="max_accel_x must be positive"):
        DiffDriveBase(clock, max_accel_x=0.0)
