"""Motion pure logic: arbitration matrix, velocity validation, safety latch, odometry, status bits, voice."""
import math

import pytest

from inspection_robot.command import CommandError
from inspection_robot.interface import (
    LIGHT_BUMPER, LIGHT_HARD_ESTOP, LIGHT_SOFT_ESTOP, MODE_JOY, MODE_SERVER, MODE_TASK, STOP_FRONT_COLLISION,
    STOP_LEFT_FALL, STOP_OBSTACLE, STOP_RIGHT_FALL, WHEEL_COLLISION_OFF, WHEEL_FALL_OFF, WHEEL_OBSTACLE_OFF,
    WHEEL_STEER, WHEEL_STEER_MODE, WHEEL_STRAIGHT, WHEEL_STRAIGHT_MODE, WHEEL_SWITCHING)
from inspection_robot.motion.arbitration import REFUSALS, ModeArbiter
from inspection_robot.motion.chassis import ChassisState
from inspection_robot.motion.odometry import Odometry
from inspection_robot.motion.safety import SafetyLatch
from inspection_robot.motion.status import control_status_fields
from inspection_robot.motion.velocity import VelocityLimits
from inspection_robot.motion.voice import status_sentence

SENDERS = ("joy_control", "server", "move_base", "intruder")


def arbiter_in(mode):
    arb = ModeArbiter()
    arb.mode = mode
    return arb


# (start mode, sender, data) -> mode after acquire
ACQUIRE = {
    (MODE_TASK, "joy_control", "joy"): MODE_JOY,
    (MODE_TASK, "server", "server"): MODE_SERVER,
    (MODE_SERVER, "joy_control", "joy"): MODE_JOY,
    (MODE_SERVER, "server", "server"): MODE_SERVER,
    (MODE_JOY, "joy_control", "joy"): MODE_JOY,
}


@pytest.mark.parametrize("mode", [MODE_TASK, MODE_SERVER, MODE_JOY])
@pytest.mark.parametrize("sender", SENDERS)
@pytest.mark.parametrize("data", ["joy", "server", "task", "", "JOY"])
def test_acquire_matrix(mode, sender, data):
    arb = arbiter_in(mode)
    decision = arb.request(sender, "acquire", data)
    expected = ACQUIRE.get((mode, sender, data), mode)
    assert arb.mode == expected
    assert decision.accepted == ((mode, sender, data) in ACQUIRE)
    assert decision.changed == (expected != mode)
    assert decision.reason


@pytest.mark.parametrize("mode", [MODE_TASK, MODE_SERVER, MODE_JOY])
@pytest.mark.parametrize("sender", SENDERS)
def test_release_matrix(mode, sender):
    arb = arbiter_in(mode)
    decision = arb.request(sender, "release", "")
    holder = {MODE_SERVER: "server", MODE_JOY: "joy_control"}.get(mode)
    assert decision.accepted == (sender == holder)
    assert arb.mode == (MODE_TASK if sender == holder else mode)


@pytest.mark.parametrize("mode", [MODE_TASK, MODE_SERVER, MODE_JOY])
@pytest.mark.parametrize("sender", SENDERS)
def test_move_matrix(mode, sender):
    holder = {MODE_TASK: "move_base", MODE_SERVER: "server", MODE_JOY: "joy_control"}[mode]
    assert arbiter_in(mode).may_move(sender) == (sender == holder)


def test_release_with_wrong_mode_data_and_unknown_cmd_are_refused():
    arb = arbiter_in(MODE_JOY)
    assert not arb.request("joy_control", "release", "server").accepted
    assert not arb.request("joy_control", "release", "x,y").accepted
    assert not arb.request("joy_control", "grab", "joy").accepted
    assert arb.mode == MODE_JOY
    assert arb.request("joy_control", "release", "joy").accepted and arb.mode == MODE_TASK


def test_force_task():
    arb = arbiter_in(MODE_SERVER)
    assert arb.force_task() and arb.mode == MODE_TASK
    assert not arb.force_task()


# --- velocity ---------------------------------------------------------------------------------
LIMITS = VelocityLimits(max_x=1.0, max_yaw=0.8, refuse_x=5.0, refuse_yaw=5.0)


def test_velocity_units_and_clamping():
    v = LIMITS.check(500, -250, WHEEL_STRAIGHT)
    assert (v.x, v.yaw, v.wheel_mode, v.clamped) == (0.5, -0.25, WHEEL_STRAIGHT, False)
    v = LIMITS.check(-3000, 2000, WHEEL_STRAIGHT)
    assert (v.x, v.yaw, v.clamped) == (-1.0, 0.8, True)


def test_steer_mode_ignores_velocity_x():
    v = LIMITS.check(500, 300, WHEEL_STEER)
    assert (v.x, v.yaw, v.wheel_mode) == (0.0, 0.3, WHEEL_STEER)


@pytest.mark.parametrize("vx,wz,wheel", [
    (float("nan"), 0, 0), (0, float("nan"), 0), (float("inf"), 0, 0), (0, float("-inf"), 0),
    (5001, 0, 0), (-1e12, 0, 0), (0, 5001, 0), (0, 0, 2), (0, 0, 255), ("abc", 0, 0)])
def test_velocity_refused(vx, wz, wheel):
    with pytest.raises(CommandError):
        LIMITS.check(vx, wz, wheel)


def test_limits_reject_bad_configuration():
    with pytest.raises(ValueError):
        VelocityLimits(max_x=0)
    with pytest.raises(ValueError):
        VelocityLimits(max_x=2.0, refuse_x=1.0)
    with pytest.raises(ValueError):
        VelocityLimits(max_yaw=float("nan"))


# --- safety -----------------------------------------------------------------------------------
def state(**kw):
    return ChassisState(**kw)


def test_soft_estop_latches_until_disable_stop():
    latch = SafetyLatch()
    assert not latch.blocks()
    latch.enable_stop()
    assert latch.reasons() == ["soft_estop"] and latch.light_bits() == LIGHT_SOFT_ESTOP
    latch.disable_stop()
    assert not latch.blocks()


def test_hard_estop_engages_soft_and_refuses_release_while_pressed():
    latch = SafetyLatch()
    latch.update_chassis(state(hard_estop=True))
    assert set(latch.reasons()) == {"soft_estop", "hard_estop"}
    assert latch.light_bits() == LIGHT_SOFT_ESTOP | LIGHT_HARD_ESTOP
    with pytest.raises(CommandError):
        latch.disable_stop()
    latch.update_chassis(state(hard_estop=False))
    assert latch.reasons() == ["soft_estop"]  # still latched after the button is released
    latch.disable_stop()
    assert not latch.blocks()


@pytest.mark.parametrize("field,switch,reason,bit", [
    ("bumper", "collision", "front_collision", STOP_FRONT_COLLISION),
    ("fall_left", "fallen", "left_fall", STOP_LEFT_FALL),
    ("fall_right", "fallen", "right_fall", STOP_RIGHT_FALL),
])
def test_chassis_inputs_stop_unless_switched_off(field, switch, reason, bit):
    latch = SafetyLatch()
    latch.update_chassis(state(**{field: True}))
    assert latch.reasons() == [reason] and latch.stop_status() == bit
    assert latch.set_switch(switch, False) is False
    assert not latch.blocks() and latch.stop_status() == 0
    assert latch.set_switch(switch) is True  # toggle
    assert latch.blocks()
    latch.update_chassis(state())
    assert not latch.blocks()


def test_obstacle_and_switch_bits():
    latch = SafetyLatch()
    latch.set_obstacle(True)
    assert latch.reasons() == ["obstacle"] and latch.stop_status() == STOP_OBSTACLE
    for name in ("collision", "fallen", "obstacle"):
        latch.set_switch(name, False)
    assert not latch.blocks()
    assert latch.wheel_off_bits() == WHEEL_COLLISION_OFF | WHEEL_FALL_OFF | WHEEL_OBSTACLE_OFF
    with pytest.raises(CommandError):
        latch.set_switch("gravity", False)


def test_bumper_light_bit_is_raw_even_when_switched_off():
    latch = SafetyLatch()
    latch.set_switch("collision", False)
    latch.update_chassis(state(bumper=True))
    assert latch.light_bits() == LIGHT_BUMPER and latch.stop_status() == 0


def test_drive_fault_from_motor_bits():
    latch = SafetyLatch()
    latch.update_chassis(state(motor_status=(1, 0, 0, 0, 0, 0, 0, 0)))
    assert latch.reasons() == ["drive_fault"]
    latch.update_chassis(state(motor_status=(0, 0, 0, 0, 0, 0, 0, 1)))
    assert latch.reasons() == ["drive_fault"]
    latch.update_chassis(state())
    assert not latch.blocks()


# --- odometry ---------------------------------------------------------------------------------
def test_odometry_straight_and_arc():
    odo = Odometry()
    for _ in range(100):
        odo.update(0.5, 0.0, 0.02)
    assert odo.x == pytest.approx(1.0) and odo.y == pytest.approx(0.0)
    odo = Odometry()
    for _ in range(1000):  # a half circle of radius 1 m: v = 0.5, w = 0.5 for 2 pi s
        odo.update(0.5, 0.5, 2 * math.pi / 1000)
    assert odo.x == pytest.approx(0.0, abs=1e-4) and odo.y == pytest.approx(2.0, abs=1e-4)
    assert abs(odo.yaw) == pytest.approx(math.pi, abs=1e-6)
    qx, qy, qz, qw = odo.quaternion()
    assert qz * qz + qw * qw == pytest.approx(1.0)


def test_odometry_ignores_bad_samples():
    odo = Odometry()
    odo.update(float("nan"), 0.0, 0.02)
    odo.update(1.0, 0.0, -1.0)
    odo.update(1.0, 0.0, 10.0)  # a stalled loop is capped at 0.5 s
    assert odo.x == pytest.approx(0.5)


# --- status -----------------------------------------------------------------------------------
def test_control_status_fields_units_and_bits():
    latch = SafetyLatch()
    latch.set_switch("obstacle", False)
    latch.update_chassis(state(bumper=True))
    temps = (25.04, None) + (30.0,) * 11
    fields = control_status_fields(MODE_JOY, latch, state(
        wheel_mode=WHEEL_STEER, charge_relay=True, lamps=(True, False, True), battery_voltage=52.37,
        battery_current=-1.26, battery_quantity=87, battery_status=0x20, circuit_status=0x82,
        motor_status=(1,), motor_info=(1 << 16,), temperatures_c=temps))
    assert fields["mode"] == MODE_JOY
    assert fields["wheel_status"] == WHEEL_STEER_MODE | WHEEL_OBSTACLE_OFF
    assert fields["light_status"] == 0x01 | 0x02 | 0x08 | LIGHT_BUMPER
    assert fields["stop_status"] == STOP_FRONT_COLLISION
    assert fields["circuit_status"] == 0x82
    assert (fields["battery_voltage"], fields["battery_current"], fields["battery_quantity"]) == (524, -13, 87)
    assert fields["motor_status"] == [1, 0, 0, 0, 0, 0, 0, 0]
    assert fields["motor_info"] == [1 << 16] + [0] * 7
    assert fields["temperature"][:3] == [250, -1000, 300] and len(fields["temperature"]) == 13
    switching = control_status_fields(MODE_TASK, SafetyLatch(), state(switching=True))
    assert switching["wheel_status"] == WHEEL_SWITCHING
    assert control_status_fields(MODE_TASK, SafetyLatch(), state())["wheel_status"] == WHEEL_STRAIGHT_MODE


def test_status_sentence():
    latch = SafetyLatch()
    fields = control_status_fields(MODE_SERVER, latch, state(
        battery_voltage=52.4, battery_quantity=87, temperatures_c=(26.0,) + (None,) * 12))
    words = status_sentence(fields, latch.reasons())
    assert words == ["status_report", "mode_server", "battery_quantity", "%87%", "battery_voltage", "[52]",
                     "volt", "battery_temperature", "(26)", "status_normal"]
    latch.enable_stop()
    fields = control_status_fields(MODE_TASK, latch, state(circuit_status=0x82))
    words = status_sentence(fields, latch.reasons())
    assert words[-3:] == ["alarm_soft_estop", "alarm_battery_critical", "alarm_joystick_lost"]
    assert "battery_temperature" not in words


@pytest.mark.parametrize("mode,sender,cmd,data,code", [
    (MODE_JOY, "server", "acquire", "server", "busy"),
    (MODE_TASK, "server", "acquire", "joy", "not_allowed"),
    (MODE_SERVER, "move_base", "release", "", "not_allowed"),
    (MODE_TASK, "server", "release", "", "not_held"),
    (MODE_JOY, "joy_control", "release", "server", "not_held"),
    (MODE_TASK, "server", "acquire", "task", "bad_request"),
    (MODE_TASK, "server", "grab", "server", "bad_request"),
    (MODE_TASK, "server", "release", "x", "bad_request"),
])
def test_every_refusal_starts_with_its_code(mode, sender, cmd, data, code):
    decision = arbiter_in(mode).request(sender, cmd, data)
    assert not decision.accepted and decision.reason.split(": ", 1)[0] == code
    assert code in REFUSALS


def test_mode_cmd_refusals_echo_a_long_name_capped():
    arb = ModeArbiter()
    reason = arb.request("server", "g" * 100000, "").reason
    assert reason == "bad_request: unknown mode_cmd '%s...' (acquire|release)" % ("g" * 40)
    reason = arb.request("server", "acquire", "d" * 500).reason
    assert reason == "bad_request: acquire data must be joy|server, got '%s...'" % ("d" * 40)
