"""The ETA falls during a drive (#31.5): task.drive_progress reads move_action feedback, and the
patrol's eta_s counts only the part of the running drive not yet driven."""
import json

import pytest

from inspection_robot.task.drive_progress import DriveProgress
from inspection_robot.task.patrol import STEP_INSPECT, STEP_MOVE, Patrol
from inspection_robot.task.store import ResultStore
from test_task_patrol import CONFIG, task


def test_the_fraction_driven_follows_the_remaining_path():
    drive = DriveProgress()
    assert drive.feed("2", json.dumps({"remaining": 3.0})) is None   # no plan yet: unknown
    assert drive.feed("0", "") is None
    assert drive.feed("1", json.dumps({"path_length": 10.0, "planning_time": 0.1})) == 0.0
    assert drive.feed("2", json.dumps({"remaining": 7.5, "phase": "follow"})) == pytest.approx(0.25)
    assert drive.feed("2", json.dumps({"remaining": 12.0})) == 0.0     # clamped
    assert drive.feed("2", json.dumps({"remaining": 0.0})) == 1.0
    assert drive.feed("3", json.dumps({"reason": "off track, replanning"})) is None
    assert drive.feed("1", json.dumps({"path_length": 4.0})) == 0.0    # a replan: from its own length
    assert drive.feed("2", json.dumps({"remaining": 1.0})) == pytest.approx(0.75)


@pytest.mark.parametrize("data", ["not json", "[1]", json.dumps({"remaining": "far"}),
                                  json.dumps({"remaining": float("nan")}), json.dumps({"remaining": True})])
def test_feedback_it_cannot_read_changes_nothing(data):
    drive = DriveProgress()
    drive.feed("1", json.dumps({"path_length": 10.0}))
    assert drive.feed("2", data) is None
    assert drive.feed("2", json.dumps({"remaining": 5.0})) == pytest.approx(0.5)


def test_eta_falls_while_a_drive_advances(tmp_path):
    patrol = Patrol(ResultStore(str(tmp_path / "results.sqlite")), CONFIG, 1000.0)
    patrol.set_mode(0)
    patrol.submit(task("t1"), 1000.0)
    drive = patrol.next_step(1000.0)
    assert drive.kind == STEP_MOVE
    full = patrol.status()["eta_s"]
    assert full == 2 * 20.0 + 4 * 10.0
    patrol.drive_progress(drive, 0.25)
    assert patrol.status()["eta_s"] == full - 0.25 * 20.0
    patrol.drive_progress(drive, 0.75)
    assert patrol.status()["eta_s"] == full - 0.75 * 20.0
    patrol.drive_progress(drive, 7.0)   # clamped to the whole drive
    assert patrol.status()["eta_s"] == full - 20.0
    patrol.step_done(drive, "ok", "", 1000.0, 1020.0)
    inspect = patrol.next_step(1020.0)
    assert inspect.kind == STEP_INSPECT
    before = patrol.status()["eta_s"]
    patrol.drive_progress(inspect, 0.5)   # not a drive: ignored
    patrol.drive_progress(drive, 0.5)     # a drive that ended: ignored
    assert patrol.status()["eta_s"] == before
