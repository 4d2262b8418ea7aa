"""task_action: the feedback a goal gets from the patrol's progress, its result when the task ends,
and a refused goal; with the real state machine and store on a fake clock."""
import json

import pytest

from inspection_robot.command import CommandError
from inspection_robot.task.action import (END_ABORTED, END_CANCELED, END_SUCCEEDED, FEEDBACK_KEYS, check_goal_type,
                                          goal_end, goal_feedback, goal_refused)
from inspection_robot.task.patrol import OUTCOME_FAILED
from inspection_robot.task.report import summary
from test_task_patrol import env, run_step, task  # noqa: F401 (env is a fixture)


def feedback(patrol, task_id):
    code, data = goal_feedback(patrol.task_progress(task_id))
    return code, json.loads(data)


def ended(store, task_id):
    return goal_end(summary(store.task(task_id), store.readings(task_id=task_id), ()), "/r/%s/report.html" % task_id)


def test_feedback_follows_the_task_stop_by_stop_with_the_task_status_fields(env):  # noqa: F811
    store, clock, patrol, _ = env
    patrol.submit(task("t1"), clock())
    code, data = feedback(patrol, "t1")
    assert code == "0" and list(sorted(data)) == sorted(FEEDBACK_KEYS)
    assert (data["state"], data["stop"], data["stops"], data["preset"], data["presets"], data["done"],
            data["total"], data["last_result"]) == ("running", 1, 2, 1, 2, 0, 4, None)
    assert data["eta_s"] == 2 * 20.0 + 4 * 10.0
    status = patrol.status()
    assert all(data[k] == status[k] for k in FEEDBACK_KEYS)   # the same fields as task_status
    run_step(patrol, clock)
    run_step(patrol, clock, value=0.9)
    code, data = feedback(patrol, "t1")
    assert (data["stop"], data["preset"], data["done"]) == (1, 2, 1)
    assert data["last_result"]["readings"][0]["alarm"] == "alarm"
    patrol.pause("")
    code, data = feedback(patrol, "t1")
    assert (code, data["state"], data["holds"]) == ("1", "paused", ["operator"])


def test_a_preempted_routine_goal_stays_active_and_says_who_preempted_it(env):  # noqa: F811
    store, clock, patrol, _ = env
    patrol.submit(task("routine"), clock())
    run_step(patrol, clock)
    run_step(patrol, clock)
    patrol.submit(task("urgent", stops=1, priority="special"), clock())
    code, data = feedback(patrol, "routine")
    assert (code, data["state"], data["reason"]) == ("2", "suspended", "pre-empted by special task 'urgent'")
    assert (data["stop"], data["preset"], data["done"]) == (1, 2, 1)
    # its ETA waits for the special task too (1 drive, 2 presets), then its own 2 drives (back to
    # its stop, then the next) and 3 presets, at the 3 s per step measured so far
    assert feedback(patrol, "urgent")[1]["eta_s"] == 3 * 3.0
    assert data["eta_s"] == 3 * 3.0 + 5 * 3.0
    assert feedback(patrol, "urgent")[0] == "0"
    for _ in range(3):
        run_step(patrol, clock)
    assert patrol.task_progress("urgent") is None
    assert feedback(patrol, "routine")[1]["state"] == "running"


def test_results_map_each_end_state_with_counts_and_report(env):  # noqa: F811
    store, clock, patrol, _ = env
    patrol.submit(task("good", stops=1), clock())
    for _ in range(3):
        run_step(patrol, clock, value=0.9)
    end, ret_code, data = ended(store, "good")
    assert (end, ret_code) == (END_SUCCEEDED, "0")
    assert json.loads(data) == {"task_id": "good", "state": "done", "reason": "",
                                "counts": {"readings": 3, "read": 3, "uncertain": 0, "needs_review": 0, "failed": 0,
                                           "alarms": 1, "checks": 0, "warnings": 0, "trends": 0},
                                "duration_s": 9.0, "report": "/r/good/report.html"}
    patrol.submit(task("bad", stops=1, retries=0), clock())
    run_step(patrol, clock, OUTCOME_FAILED)
    end, ret_code, data = ended(store, "bad")
    assert (end, ret_code, json.loads(data)["reason"]) == (END_ABORTED, "1", "every preset failed")
    patrol.submit(task("gone", stops=1), clock())
    patrol.cancel("gone", clock(), "cancelled by the action client")
    end, ret_code, data = ended(store, "gone")
    assert (end, ret_code, json.loads(data)["reason"]) == (END_CANCELED, "2", "cancelled by the action client")


def test_refused_goals():
    with pytest.raises(CommandError, match="goal type must be 'patrol', got 'move'"):
        check_goal_type("move")
    check_goal_type("patrol")
    assert goal_refused("stop 1: presets must be a non-empty list") == (
        "3", '{"reason": "stop 1: presets must be a non-empty list"}')
