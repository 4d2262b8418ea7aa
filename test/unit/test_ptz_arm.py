"""Arm trajectory files, the simulated arm and the arm command logic (no roscore)."""
import os
import threading

import pytest

from inspection_robot.arm import trajectory
from inspection_robot.arm.controller import ArmController
from inspection_robot.arm.driver import ArmError, Limits
from inspection_robot.sim.arm import SimArm

LIMITS = Limits(((-600, 600), (-600, 600), (-200, 800)), ((-180, 180), (-90, 90), (-180, 180)))


def test_trajectory_round_trip_and_reverse(tmp_path):
    samples = [trajectory.Sample(0.0, (1.0, 2.0, 3.0), (4.0, 5.0, 6.0)),
               trajectory.Sample(0.5, (10.0, 2.0, 3.0), (4.0, 5.0, -6.5))]
    path = str(tmp_path / "sub" / "a.csv")
    trajectory.save(path, samples, 20.0)
    with open(path) as f:
        assert f.read().splitlines()[:3] == [trajectory.MAGIC, "# rate_hz=20", trajectory.COLUMNS]
    assert trajectory.load(path) == samples
    back = trajectory.reversed_samples(samples)
    assert [s.t for s in back] == [0.0, 0.5] and back[0].position == (10.0, 2.0, 3.0)


@pytest.mark.parametrize("text,reason", [
    ("", "not an arm trajectory"),
    ("# other\n", "not an arm trajectory"),
    (trajectory.MAGIC + "\n0,1,2,3,4,5,6\n", "missing column header"),
    (trajectory.MAGIC + "\n" + trajectory.COLUMNS + "\n", "no samples"),
    (trajectory.MAGIC + "\n" + trajectory.COLUMNS + "\n0,1,2\n", "expected 7 values"),
    (trajectory.MAGIC + "\n" + trajectory.COLUMNS + "\n0,1,2,x,4,5,6\n", "not a number"),
    (trajectory.MAGIC + "\n" + trajectory.COLUMNS + "\n0,1,2,nan,4,5,6\n", "non-finite"),
    (trajectory.MAGIC + "\n" + trajectory.COLUMNS + "\n1,1,2,3,4,5,6\n0.5,1,2,3,4,5,6\n", "non-decreasing"),
])
def test_bad_trajectories_name_the_problem(text, reason):
    with pytest.raises(trajectory.TrajectoryError, match=reason):
        trajectory.loads(text)


def test_sim_arm_jogs_at_speed_clamps_and_faults():
    now = [0.0]
    arm = SimArm(LIMITS, linear_speed_mm_s=100.0, angular_speed_deg_s=10.0, clock=lambda: now[0])
    arm.jog(linear=(1, 0, -1), angular=(0, 1, 0))
    now[0] = 1.0
    assert arm.position() == (100.0, 0.0, -100.0)
    assert arm.orientation() == (0.0, 10.0, 0.0)
    now[0] = 20.0
    assert arm.position() == (600.0, 0.0, -200.0)     # workspace limits
    assert arm.orientation() == (0.0, 90.0, 0.0)      # joint-like limit
    arm.command_pose((0.0, 0.0, 0.0), None)
    assert arm.moving()
    now[0] = 40.0
    assert arm.position() == (0.0, 0.0, 0.0)
    arm.fault = "overcurrent"
    with pytest.raises(ArmError, match="overcurrent"):
        arm.position()


def make_controller(tmp_path, reports=None):
    arm = SimArm(LIMITS, linear_speed_mm_s=2000.0, angular_speed_deg_s=900.0)
    report = (reports.append if reports is not None else None)
    return arm, ArmController(arm, [str(tmp_path)], str(tmp_path / "default.csv"), record_rate_hz=50.0,
                              move_timeout=2.0, report=report)


def test_controller_absolute_poses_and_bad_input(tmp_path):
    _arm, controller = make_controller(tmp_path)
    table = controller.table()
    assert table.dispatch("set_position", "100,-50.5,300").ack == "success"
    assert table.dispatch("get_position", "").data == "100.00,-50.50,300.00"
    for cmd, data, reason in (("set_position", "601,0,0", "x out of range"), ("set_orientation", "0,0", "3 comma"),
                              ("move", "+,+", "3 comma"), ("move", "1,0,0", "x must be one of"),
                              ("stop_move", "-,0,0", "x must be one of"),
                              ("record_orbit", "/etc/x.csv", "outside the allowed roots"),
                              ("play_orbit", "a.csv,*", "direction")):
        reply = table.dispatch(cmd, data)
        assert reply.ack == "failed" and reason in reply.data, (cmd, reply)
    assert table.dispatch("get_position", "").data == "100.00,-50.50,300.00"


def test_controller_record_and_play_reports_the_end(tmp_path):
    reports = []
    done = threading.Event()
    arm, controller = make_controller(tmp_path, reports)
    controller._report = lambda reply: (reports.append(reply), done.set())
    table = controller.table()
    assert table.dispatch("record_orbit", "").data == str(tmp_path / "default.csv")
    assert table.dispatch("set_position", "200,0,100").ack == "success"
    reply = table.dispatch("stop_orbit", "")
    assert reply.ack == "success" and reply.data.startswith(str(tmp_path / "default.csv") + ",")
    assert table.dispatch("reset", "").ack == "success"
    assert table.dispatch("play_orbit", ",+").ack == "success"
    assert done.wait(5.0)
    assert reports[-1].ack == "success" and "finished" in reports[-1].data
    assert arm.position() == pytest.approx((200.0, 0.0, 100.0), abs=0.5)
    assert os.path.exists(str(tmp_path / "default.csv"))
