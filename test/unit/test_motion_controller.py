"""MotionController against the simulated chassis with a fake clock: the behaviour of robot_control."""
import pytest

from inspection_robot.interface import (LIGHT_CHARGE_RELAY, LIGHT_SOFT_ESTOP, MODE_JOY, MODE_SERVER, MODE_TASK,
                                        STOP_OBSTACLE, WHEEL_COLLISION_OFF, WHEEL_STEER, WHEEL_STRAIGHT)
from inspection_robot.motion.controller import MAX_PENDING, OFFLINE_RECHECK, MotionController
from inspection_robot.motion.velocity import VelocityLimits
from inspection_robot.sim.chassis import SimChassis
from inspection_robot_testing.clock import FakeClock


class Recorder(object):
    """Wraps the sim's command listener: every velocity command that reaches the driver."""

    def __init__(self, chassis):
        self.commands = []
        chassis.add_command_listener(lambda vx, wz, mode: self.commands.append((vx, wz, mode)))

    @property
    def last(self):
        return self.commands[-1]


@pytest.fixture
def rig():
    clock = FakeClock()
    chassis = SimChassis(clock, encoder_scale_error=0.0, max_accel_x=10.0, max_accel_yaw=10.0, switch_time=0.2)
    logs, spoken = [], []
    ctl = MotionController(chassis, VelocityLimits(1.0, 1.0, 5.0, 5.0), 0.5, clock,
                           log=lambda level, text: logs.append((level, text)), speak=spoken.append)
    rec = Recorder(chassis)

    def run(seconds, period=0.02):
        for _ in range(int(round(seconds / period))):
            clock.now += period
            ctl.tick()
    return ctl, chassis, clock, rec, run, logs, spoken


def test_boots_in_task_mode_and_obeys_move_base(rig):
    ctl, chassis, _clock, rec, run, _logs, _ = rig
    assert ctl.mode == MODE_TASK
    assert ctl.on_move_cmd("move_base", 500, 0, 0).ack == "success"
    assert rec.last == (0.5, 0.0, WHEEL_STRAIGHT)
    run(0.2)
    assert chassis.state().velocity_x == pytest.approx(0.5)
    assert ctl.on_move_cmd("server", 300, 0, 0).ack == "failed"
    assert ctl.on_move_cmd("joy_control", 300, 0, 0).ack == "failed"
    assert rec.last == (0.5, 0.0, WHEEL_STRAIGHT)


def test_cmd_timeout_stops_once_then_zeros(rig):
    ctl, chassis, _clock, rec, run, _logs, _ = rig
    ctl.on_move_cmd("move_base", 500, 0, 0)
    run(0.48)
    assert ctl.target is not None
    run(0.1)
    assert ctl.target is None and rec.last[:2] == (0.0, 0.0)
    run(0.5)
    assert chassis.state().velocity_x == 0.0


def test_mode_change_stops_and_only_holder_moves(rig):
    ctl, _chassis, _clock, rec, _run, _logs, _ = rig
    ctl.on_move_cmd("move_base", 500, 0, 0)
    assert ctl.on_mode_cmd("server", "acquire", "server").changed
    assert ctl.target is None and rec.last[:2] == (0.0, 0.0)
    assert ctl.on_move_cmd("move_base", 500, 0, 0).ack == "failed"
    assert ctl.on_move_cmd("server", 400, 100, 0).ack == "success"
    ctl.on_mode_cmd("joy_control", "acquire", "joy")
    assert ctl.mode == MODE_JOY and ctl.target is None
    assert not ctl.on_mode_cmd("server", "acquire", "server").accepted
    assert ctl.mode == MODE_JOY
    assert ctl.on_move_cmd("joy_control", 200, 0, 0).ack == "success"
    ctl.on_mode_cmd("joy_control", "release", "")
    assert ctl.mode == MODE_TASK


def test_refused_move_from_holder_stops(rig):
    ctl, _chassis, _clock, rec, _run, logs, _ = rig
    ctl.on_move_cmd("move_base", 500, 0, 0)
    for bad in ((float("nan"), 0, 0), (float("inf"), 0, 0), (1e9, 0, 0), (0, 0, 9)):
        reply = ctl.on_move_cmd("move_base", *bad)
        assert reply.ack == "failed" and "refused" in reply.data
        assert ctl.target is None and rec.last[:2] == (0.0, 0.0)
        ctl.on_move_cmd("move_base", 500, 0, 0)


def test_clamped_to_limits(rig):
    ctl, _chassis, _clock, rec, _run, _logs, _ = rig
    assert ctl.on_move_cmd("move_base", 3000, -4000, 0) == ("success", "clamped")
    assert rec.last == (1.0, -1.0, WHEEL_STRAIGHT)


@pytest.mark.parametrize("fault,switch", [("bumper", "collision"), ("fall_left", "fallen"),
                                          ("fall_right", "fallen"), ("motor_disconnect", None)])
def test_chassis_safety_inputs_stop_at_once_and_refuse(rig, fault, switch):
    ctl, chassis, _clock, rec, run, _logs, _ = rig
    ctl.on_move_cmd("move_base", 500, 0, 0)
    run(0.1)
    n = len(rec.commands)
    with ctl.locked():
        chassis.inject(fault, True)
    assert rec.commands[n:] and rec.commands[n][:2] == (0.0, 0.0)  # in the injecting call, not the next cycle
    assert ctl.on_move_cmd("move_base", 500, 0, 0).ack == "failed"
    if switch:
        ctl.on_control_cmd("server", "disable_" + switch, "")
        assert ctl.on_move_cmd("move_base", 500, 0, 0).ack == "success"
        ctl.on_control_cmd("server", "enable_" + switch, "")
        assert ctl.target is None and rec.last[:2] == (0.0, 0.0)
    chassis.inject(fault, False)
    run(0.02)
    assert ctl.target is None  # no resumption without a new command
    assert ctl.on_move_cmd("move_base", 500, 0, 0).ack == "success"


def test_obstacle_stops_unless_disabled(rig):
    ctl, _chassis, _clock, rec, _run, _logs, _ = rig
    ctl.on_move_cmd("move_base", 500, 0, 0)
    ctl.on_obstacle(True)
    assert rec.last[:2] == (0.0, 0.0) and ctl.status()["stop_status"] == STOP_OBSTACLE
    assert ctl.on_move_cmd("move_base", 500, 0, 0).ack == "failed"
    ctl.on_obstacle(False)
    assert ctl.on_move_cmd("move_base", 500, 0, 0).ack == "success"
    ctl.on_control_cmd("server", "disable_obstacle", "")
    ctl.on_obstacle(True)
    assert ctl.target is not None and ctl.status()["stop_status"] == 0


def test_soft_and_hard_estop(rig):
    ctl, chassis, _clock, rec, run, _logs, _ = rig
    ctl.on_move_cmd("move_base", 500, 0, 0)
    assert ctl.on_control_cmd("server", "enable_stop", "").ack == "success"
    assert rec.last[:2] == (0.0, 0.0) and ctl.status()["light_status"] & LIGHT_SOFT_ESTOP
    assert ctl.on_move_cmd("move_base", 500, 0, 0).ack == "failed"
    assert ctl.on_control_cmd("server", "disable_stop", "").ack == "success"
    assert ctl.on_move_cmd("move_base", 500, 0, 0).ack == "success"
    chassis.inject("hard_estop", True)
    assert rec.last[:2] == (0.0, 0.0)
    assert ctl.on_control_cmd("server", "disable_stop", "") == ("failed", "hard e-stop still pressed: "
                                                                          "release the button first")
    chassis.inject("hard_estop", False)
    run(0.04)
    assert ctl.on_move_cmd("move_base", 500, 0, 0).ack == "failed"  # latched until disable_stop
    assert ctl.on_control_cmd("server", "disable_stop", "").ack == "success"
    assert ctl.on_move_cmd("move_base", 500, 0, 0).ack == "success"


def test_offline_in_server_mode_stops_and_returns_to_task(rig):
    ctl, _chassis, _clock, rec, _run, _logs, _ = rig
    ctl.on_offline(False)
    ctl.on_mode_cmd("server", "acquire", "server")
    ctl.on_move_cmd("server", 500, 0, 0)
    ctl.on_offline(True)
    assert ctl.mode == MODE_TASK and ctl.target is None and rec.last[:2] == (0.0, 0.0)


def test_offline_in_joy_mode_keeps_joy(rig):
    ctl, _chassis, _clock, _rec, _run, _logs, _ = rig
    ctl.on_mode_cmd("joy_control", "acquire", "joy")
    ctl.on_move_cmd("joy_control", 500, 0, 0)
    ctl.on_offline(True)
    assert ctl.mode == MODE_JOY and ctl.target is not None


def test_joystick_link_loss_in_joy_mode(rig):
    ctl, chassis, _clock, rec, _run, _logs, _ = rig
    ctl.on_mode_cmd("joy_control", "acquire", "joy")
    ctl.on_move_cmd("joy_control", 500, 0, 0)
    chassis.inject("joystick_link_lost", True)
    assert ctl.mode == MODE_TASK and rec.last[:2] == (0.0, 0.0)


def test_switches_charge_and_unknown_control_cmd(rig):
    ctl, chassis, _clock, _rec, _run, _logs, _ = rig
    assert ctl.on_control_cmd("server", "switch_collision", "") == ("success", "collision disabled")
    assert ctl.status()["wheel_status"] & WHEEL_COLLISION_OFF
    assert ctl.on_control_cmd("server", "switch_collision", "") == ("success", "collision enabled")
    assert ctl.on_control_cmd("server", "enable_charge", "").ack == "success"
    assert ctl.status()["light_status"] & LIGHT_CHARGE_RELAY and chassis.state().charge_relay
    ctl.on_control_cmd("server", "disable_charge", "")
    assert not ctl.status()["light_status"] & LIGHT_CHARGE_RELAY
    assert ctl.on_control_cmd("server", "fly", "") == ("failed", "unknown command 'fly'")


def test_query_status_speaks(rig):
    ctl, _chassis, _clock, _rec, _run, _logs, spoken = rig
    reply = ctl.on_control_cmd("server", "query_status", "")
    assert reply.ack == "success" and spoken and spoken[0][0] == "status_report"
    assert spoken[0][-1] == "status_normal"


def test_imu_commands(rig):
    ctl, _chassis, clock, _rec, run, _logs, _ = rig
    assert ctl.on_imu_cmd("calibrate", "") == ("success", "calibrated")
    assert ctl.on_imu_cmd("reset", "") == ("success", "reset")
    assert ctl.on_imu_cmd("query", "") == ("success", "0.00,0.00,0.00,1")
    assert ctl.on_imu_cmd("query", "x").ack == "failed"
    assert ctl.on_imu_cmd("spin", "").ack == "failed"
    ctl.on_move_cmd("move_base", 500, 0, 0)
    run(0.1)
    assert "robot moving" in ctl.on_imu_cmd("calibrate", "").data


def test_odometry_follows_measured_motion(rig):
    ctl, chassis, _clock, _rec, run, _logs, _ = rig
    for _ in range(50):
        ctl.on_move_cmd("move_base", 500, 0, 0)
        run(0.02)
    true_x = chassis.true_pose()[0][0]
    assert ctl.odometry.x == pytest.approx(true_x, abs=0.02) and ctl.odometry.x > 0.4


def test_steer_mode_switch_shows_in_status(rig):
    ctl, _chassis, _clock, _rec, run, _logs, _ = rig
    ctl.on_move_cmd("move_base", 0, 300, WHEEL_STEER)
    run(0.06)
    assert ctl.status()["wheel_status"] & 0x04
    for _ in range(20):
        ctl.on_move_cmd("move_base", 0, 300, WHEEL_STEER)
        run(0.02)
    assert ctl.status()["wheel_status"] & 0x07 == 0x02


def test_lamps_follow_safety(rig):
    ctl, chassis, _clock, _rec, run, _logs, _ = rig
    run(0.02)
    assert chassis.state().lamps == (False, True, False)
    ctl.on_control_cmd("server", "enable_stop", "")
    run(0.02)
    assert chassis.state().lamps == (True, False, False)


def test_server_cannot_acquire_while_backend_offline(rig):
    ctl, _chassis, _clock, _rec, _run, logs, _ = rig
    ctl.on_offline(True)
    assert not ctl.on_mode_cmd("server", "acquire", "server").accepted
    assert ctl.mode == MODE_TASK and "backend offline" in logs[-1][1]
    assert ctl.on_mode_cmd("joy_control", "acquire", "joy").changed
    ctl.on_offline(False)
    ctl.on_mode_cmd("joy_control", "release", "")
    assert ctl.on_mode_cmd("server", "acquire", "server").changed


def test_mode_reply_says_what_was_granted_and_why_not(rig):
    ctl, chassis, _clock, _rec, run, _logs, _ = rig
    granted = ctl.mode_reply(ctl.on_mode_cmd("server", "acquire", "server"))
    assert granted == ("success", "server")
    ctl.on_mode_cmd("joy_control", "acquire", "joy")
    assert ctl.mode_reply(ctl.on_mode_cmd("server", "acquire", "server")) == (
        "failed", "busy: acquire server refused: joy mode has priority")
    assert ctl.mode_reply(ctl.on_mode_cmd("server", "release", "")).data.startswith("not_allowed: ")
    assert ctl.mode_reply(ctl.on_mode_cmd("joy_control", "release", "")) == ("success", "task")
    ctl.on_offline(True)
    assert ctl.mode_reply(ctl.on_mode_cmd("server", "acquire", "server")).data.startswith("offline: ")
    ctl.on_offline(False)
    chassis.inject("hard_estop", True)
    run(0.1)
    assert ctl.mode_reply(ctl.on_mode_cmd("server", "acquire", "server")) == (
        "success", "server; motion blocked: soft_estop,hard_estop")  # the hard e-stop latches the soft one
    assert ctl.mode_reply(None).ack == "failed"


def test_acquire_while_offline_waits_for_the_next_robot_status(rig):
    """A client that saw robot_status online may reach robot_control before that status does, even
    behind older offline statuses still queued: its acquire is granted on the first online status,
    refused only when none came within OFFLINE_RECHECK."""
    ctl, _chassis, _clock, _rec, run, _logs, _ = rig
    answers = []
    ctl.on_offline(True)
    assert ctl.on_mode_cmd("server", "acquire", "server", answers.append) is None
    assert answers == [] and ctl.mode == MODE_TASK
    ctl.on_offline(False)  # the status the client had seen
    assert [a.accepted for a in answers] == [True] and ctl.mode == MODE_SERVER
    ctl.on_mode_cmd("server", "release", "")
    ctl.on_offline(True)
    ctl.on_mode_cmd("server", "acquire", "server", answers.append)
    ctl.on_offline(True)  # an older status still queued, or really offline: not decided yet
    assert len(answers) == 1 and ctl.mode == MODE_TASK
    run(OFFLINE_RECHECK - 0.1)
    ctl.on_offline(True)
    assert len(answers) == 1
    run(0.2)  # offline all along: refused after OFFLINE_RECHECK
    assert answers[-1].reason.startswith("offline") and ctl.mode == MODE_TASK
    ctl.on_mode_cmd("server", "acquire", "server", answers.append)
    run(OFFLINE_RECHECK - 0.1)
    assert len(answers) == 2
    run(0.2)  # no status at all (status_control down): refused after OFFLINE_RECHECK
    assert len(answers) == 3 and not answers[-1].accepted and ctl.mode == MODE_TASK
    for _ in range(MAX_PENDING):
        assert ctl.on_mode_cmd("server", "acquire", "server", answers.append) is None
    assert not ctl.on_mode_cmd("server", "acquire", "server", answers.append).accepted  # bounded
    assert ctl.on_mode_cmd("joy_control", "acquire", "joy", answers.append).changed  # others decided at once


def test_acquire_is_granted_on_the_backends_own_heartbeat_only(rig):
    """Backend A (session 1111) holds mode 1 and leaves; backend B (session 2222) acquires while the
    robot is still online on A's last heartbeat. B is not granted on A's heartbeat (its expiry would
    take the robot back 3 s later): it waits for a robot_status naming its session, and is refused
    when none comes. Once granted, only offline_warn takes the mode back."""
    ctl, _chassis, _clock, _rec, run, logs, _ = rig
    answers = []
    ctl.on_offline(False, 1111)
    assert ctl.on_mode_cmd("server", "acquire", "server", answers.append, trans_id=1111).changed
    assert ctl.on_mode_cmd("server", "release", "").changed
    ctl.on_mode_cmd("server", "acquire", "server", answers.append, trans_id=2222)
    ctl.on_offline(False, 1111)                          # A's heartbeat still: B waits
    assert answers == [] and ctl.mode == MODE_TASK
    ctl.on_offline(False, 2222)                          # B's own heartbeat arrived
    assert [a.accepted for a in answers] == [True] and ctl.mode == MODE_SERVER
    ctl.on_offline(False, 1111)                          # someone beating under A's number: no change
    run(1.0)
    assert ctl.mode == MODE_SERVER
    ctl.on_mode_cmd("server", "release", "")
    ctl.on_mode_cmd("server", "acquire", "server", answers.append, trans_id=3333)   # C, never beats
    ctl.on_offline(False, 2222)
    run(OFFLINE_RECHECK + 0.1)
    assert not answers[-1].accepted and ctl.mode == MODE_TASK
    assert answers[-1].reason == ("offline: acquire server refused: no heartbeat of session 3333 yet "
                                  "(robot_status names session 2222)")
    assert not ctl.on_mode_cmd("server", "acquire", "server", trans_id=3333).accepted   # no answer later: at once
    ctl.on_offline(False, 0)                             # an unnumbered heartbeat: any acquire, as before
    assert ctl.on_mode_cmd("server", "acquire", "server", trans_id=5).changed
    ctl.on_offline(True, 0)
    assert ctl.mode == MODE_TASK and "backend offline in mode 1" in logs[-1][1]


def obstacle_rig(timeout=3.0):
    clock = FakeClock()
    chassis = SimChassis(clock, encoder_scale_error=0.0, max_accel_x=10.0, max_accel_yaw=10.0)
    logs = []
    ctl = MotionController(chassis, VelocityLimits(), 0.5, clock, log=lambda level, text: logs.append((level, text)),
                           obstacle_timeout=timeout)

    def run(seconds, period=0.02):
        for _ in range(int(round(seconds / period))):
            clock.now += period
            ctl.tick()
    return ctl, run, logs


def test_a_stale_clear_does_not_hold_an_obstacle_is_assumed():
    ctl, run, logs = obstacle_rig(3.0)
    ctl.on_obstacle(False)
    for _ in range(5):            # re-asserted every second: fresh
        assert ctl.on_move_cmd("move_base", 300, 0, 0).ack == "success"
        run(1.0)
        ctl.on_obstacle(False)
    assert ctl.status()["stop_status"] == 0
    ctl.on_move_cmd("move_base", 300, 0, 0)
    run(3.1)                      # the detector went silent after a clear
    assert ctl.obstacle_stale and ctl.status()["stop_status"] & STOP_OBSTACLE
    assert ctl.target is None
    assert ctl.on_move_cmd("move_base", 300, 0, 0).data == "motion refused: obstacle"
    assert [t for level, t in logs if "silent" in t] == [
        "obstacle_status silent for 3.0 s (> obstacle_timeout 3.0 s): obstacle assumed until obstacle_detector "
        "reports again"]
    run(5.0)                      # said once, not every cycle
    assert len([t for _level, t in logs if "silent" in t]) == 1
    ctl.on_obstacle(False)        # the detector is back
    assert not ctl.obstacle_stale and ctl.status()["stop_status"] == 0
    assert ctl.on_move_cmd("move_base", 300, 0, 0).ack == "success"


def test_a_stale_obstacle_stays_an_obstacle_and_no_report_yet_is_not_stale():
    ctl, run, _logs = obstacle_rig(1.0)
    run(5.0)                      # no detector has reported yet: the rig moves as before
    assert ctl.on_move_cmd("move_base", 300, 0, 0).ack == "success"
    ctl.on_obstacle(True)
    run(2.0)
    assert ctl.obstacle_stale and ctl.status()["stop_status"] & STOP_OBSTACLE
    with pytest.raises(ValueError):
        obstacle_rig(0.0)


def test_no_chassis_runs_its_control_cycle_quietly():
    from inspection_robot.motion.chassis import NoChassis
    clock = FakeClock()
    logs = []
    ctl = MotionController(NoChassis(), VelocityLimits(), 0.5, clock, log=lambda level, text: logs.append(text))
    for _ in range(100):
        clock.now += 0.02
        ctl.tick()            # lamps, zero velocity: nothing raises
    reply = ctl.on_move_cmd("move_base", 300, 0, 0)
    assert reply == ("failed", "chassis: chassis not fitted (driver: none); robot stopped")
    assert ctl.target is None
