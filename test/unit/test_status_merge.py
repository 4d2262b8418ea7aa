"""status_control's heartbeat and robot_status merge, without ROS."""
import math

import pytest

from inspection_robot.status.merge import (NO_SESSION, STALE_CONTROL_STATUS, STALE_NAV_STATUS, STALE_ODOMETRY,
                                           Heartbeat, PublishGate, StatusMerger, fit_array, heartbeat_text_problem)

STALE = {"control": 1.0, "nav": 2.0, "odom": 1.0}


def control(**overrides):
    fields = dict(mode=1, wheel_status=1, light_status=4, stop_status=0, circuit_status=0, other_status=[],
                  battery_voltage=480, battery_current=-12, battery_quantity=87, battery_status=32,
                  motor_status=[0] * 8, motor_info=[0] * 8, temperature=[250] * 13)
    fields.update(overrides)
    return fields


def test_heartbeat_offline_until_first_beat_then_after_timeout():
    hb = Heartbeat(3.0)
    assert hb.offline(0.0)
    hb.beat(10.0)
    assert not hb.offline(12.9)
    assert hb.offline(13.1)
    hb.beat(13.2)
    assert not hb.offline(13.3)


def test_heartbeat_session_names_the_latest_beat_while_online_and_none_offline():
    """A backend that reconnects beats under a new session number: robot_status names it from its
    first beat on, so the backend can tell its own heartbeat from the previous backend's."""
    hb = Heartbeat(3.0)
    assert hb.session(0.0) == NO_SESSION
    hb.beat(10.0, "server", 1111)        # backend A
    assert hb.session(10.5) == ("server", 1111)
    hb.beat(12.0, "server", 2222)        # backend B, A gone: B's session at once
    assert hb.session(12.1) == ("server", 2222)
    assert not hb.offline(14.9)          # A's last beat (10.0) expired at 13.0: B's keeps it online
    assert hb.session(15.1) == NO_SESSION and hb.offline(15.1)


def test_heartbeat_under_another_backends_name_keeps_online_and_nothing_more():
    """Any server_status keeps the robot online (the spec's rule); a spoofed or malformed one only
    changes whose session robot_status names, never echoes bad text, and a flood is one beat."""
    hb = Heartbeat(3.0)
    hb.beat(0.0, "server", 1111)
    hb.beat(0.5, "server", 1111)         # someone else under A's session: indistinguishable, still online
    assert hb.session(1.0) == ("server", 1111)
    hb.beat(1.0, "bad\x00name" + "x" * 300, 2 ** 32)   # control characters, too long, not uint32
    assert hb.session(1.0) == ("", 0)
    for i in range(10000):                           # a flood: the latest beat is all that is kept
        hb.beat(2.0 + i * 1e-5, "server", 7)
    assert hb.session(2.2) == ("server", 7) and not hb.offline(5.0) and hb.offline(5.2)


def test_publish_gate_sends_field_changes_at_once_and_session_changes_at_most_once_a_period():
    gate = PublishGate(0.1)
    status = {"offline_warn": 0}
    assert gate.due(0.0, status, ("server", 1))
    gate.sent(0.0, status, ("server", 1))
    assert not gate.due(0.01, status, ("server", 1))           # nothing new
    assert not gate.due(0.05, status, ("server", 2))           # a session change within the period waits
    assert gate.due(0.05, {"offline_warn": 1}, ("server", 2))  # a field change never waits
    gate.sent(0.05, {"offline_warn": 1}, ("server", 2))
    sent = 0
    now = 0.05
    for i in range(1000):                                      # two sessions beating in turn, 1 kHz
        now += 0.001
        session = ("server", 1 + i % 2)
        if gate.due(now, {"offline_warn": 1}, session):
            gate.sent(now, {"offline_warn": 1}, session)
            sent += 1
    assert 9 <= sent <= 11                                    # 1 s of flood: at most one per 0.1 s
    with pytest.raises(ValueError):
        PublishGate(0)


def test_heartbeat_rejects_bad_timeout():
    with pytest.raises(ValueError):
        Heartbeat(0)


def test_merge_copies_control_fields_in_order():
    merger = StatusMerger(Heartbeat(3.0), STALE)
    assert merger.update_control(0.0, control()) == []
    merger.update_nav(0.0, 4, [1.5, -2.0], 4.0)
    merger.update_odometry(0.0, 0.5, -0.1)
    merger.heartbeat.beat(0.0)
    status = merger.robot_status(0.5)
    assert status["offline_warn"] == 0 and status["mode"] == 1
    assert status["battery_voltage"] == 480 and status["battery_status"] == 32
    assert status["position"] == [1.5, -2.0]
    assert status["orientation"] == pytest.approx(4.0 - 2 * math.pi)
    assert status["nav_status"] == 4
    assert (status["velocity_x"], status["velocity_yaw"]) == (0.5, -0.1)
    assert status["other_status"] == [0]


def test_short_arrays_are_padded_and_reported():
    merger = StatusMerger(Heartbeat(3.0), STALE)
    problems = merger.update_control(0.0, control(motor_status=[1, 2], temperature=[100] * 20))
    assert len(problems) == 2
    status = merger.robot_status(0.0)
    assert status["motor_status"] == [1, 2, 0, 0, 0, 0, 0, 0]
    assert status["temperature"] == [100] * 13


def test_stale_inputs_are_flagged_not_repeated_silently():
    merger = StatusMerger(Heartbeat(3.0), STALE)
    assert merger.robot_status(0.0)["other_status"][0] == STALE_CONTROL_STATUS | STALE_NAV_STATUS | STALE_ODOMETRY
    merger.update_control(0.0, control())
    merger.update_nav(0.0, 0, [0.0, 0.0], 0.0)
    merger.update_odometry(0.0, 0.0, 0.0)
    assert merger.robot_status(0.9)["other_status"][0] == 0
    assert merger.robot_status(1.5)["other_status"][0] == STALE_CONTROL_STATUS | STALE_ODOMETRY


def test_invalid_nav_pose_keeps_last_valid():
    merger = StatusMerger(Heartbeat(3.0), STALE)
    merger.update_nav(0.0, 0, [1.0, 2.0], 0.5)
    assert merger.update_nav(0.1, 0, [float("nan"), 2.0], 0.5)
    assert merger.update_nav(0.2, 0, [], 0.5)
    assert merger.robot_status(0.2)["position"] == [1.0, 2.0]


def test_sensor_bits_and_helpers():
    merger = StatusMerger(Heartbeat(3.0), STALE)
    merger.set_sensor_bit(2, True)
    merger.set_sensor_bit(1, True)
    merger.set_sensor_bit(1, False)
    assert merger.robot_status(0.0)["sensor_status"] == 2
    assert fit_array("temperature", [])[0] == -1000
    assert heartbeat_text_problem("server", "", "alive") is None
    assert heartbeat_text_problem("\x00\x01junk")
    assert heartbeat_text_problem("x" * 1000)
