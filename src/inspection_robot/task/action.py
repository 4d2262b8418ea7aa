"""task_action (GeneralAction): a patrol submitted and followed as an action. Pure mapping, no ROS.

Goal ``type`` "patrol", ``data`` the task JSON of ``submit``. Feedback carries the task's progress
(the task_status fields of that task, see Patrol.task_progress), result the final outcome. The
node's goal handle (task/ros_goal.py) turns ``goal_end`` into set_succeeded / set_aborted / set_canceled.
Decisions (docs/interface.md, "Patrol as an action (task_action)"):

- a refused task (any submit check, a wrong goal type, busy) rejects the goal: ret_code "3";
- cancelling the goal cancels the task; a task cancelled any other way (cancel command,
  return_home) ends its goal too, preempted with ret_code "2";
- a routine goal pre-empted by a special task stays active; its feedback says ``suspended``;
- the goals live in task_manager's memory only: after a restart the client's goal is lost
  (actionlib), while the task itself resumes and is reported on task_status.
"""
import json

from inspection_robot.command import CommandError
from inspection_robot.task.states import (STATE_CANCELLED, STATE_DONE, STATE_FAILED, STATE_PAUSED, STATE_RUNNING,
                                          STATE_SUSPENDED)

TASK_GOAL_TYPE = "patrol"

FEEDBACK_RUNNING = "0"
FEEDBACK_PAUSED = "1"
FEEDBACK_SUSPENDED = "2"
FEEDBACK_CODES = {STATE_RUNNING: FEEDBACK_RUNNING, STATE_PAUSED: FEEDBACK_PAUSED, STATE_SUSPENDED: FEEDBACK_SUSPENDED}

RESULT_DONE = "0"
RESULT_FAILED = "1"
RESULT_CANCELLED = "2"
RESULT_REFUSED = "3"

# the actionlib terminal state the node sets for each result
END_SUCCEEDED = "succeeded"
END_ABORTED = "aborted"
END_CANCELED = "canceled"
END_BY_STATE = {STATE_DONE: (END_SUCCEEDED, RESULT_DONE), STATE_FAILED: (END_ABORTED, RESULT_FAILED),
                STATE_CANCELLED: (END_CANCELED, RESULT_CANCELLED)}

# the keys of a feedback's data, in the order task_status has them
FEEDBACK_KEYS = ("task_id", "priority", "state", "holds", "stop", "stops", "stop_name", "preset", "presets", "done",
                 "total", "last_result", "eta_s", "reason")


def check_goal_type(goal_type):
    if goal_type != TASK_GOAL_TYPE:
        raise CommandError("goal type must be '%s', got '%s'" % (TASK_GOAL_TYPE, goal_type[:40]))


def goal_feedback(progress):
    """(event_code, data JSON) of one task's progress dict (Patrol.task_progress)."""
    data = dict((key, progress.get(key)) for key in FEEDBACK_KEYS)
    return FEEDBACK_CODES.get(progress.get("state"), FEEDBACK_RUNNING), json.dumps(data, sort_keys=True)


def goal_end(summary, report_path):
    """(end, ret_code, data JSON) of a finished task; ``summary``: task.report.summary of its row."""
    end, ret_code = END_BY_STATE.get(summary["state"], (END_ABORTED, RESULT_FAILED))
    data = {"task_id": summary["task_id"], "state": summary["state"], "reason": summary["reason"],
            "counts": summary["counts"], "duration_s": summary["duration_s"], "report": report_path}
    return end, ret_code, json.dumps(data, sort_keys=True)


def goal_refused(reason):
    """(ret_code, data JSON) of a goal refused at submission."""
    return RESULT_REFUSED, json.dumps({"reason": reason})
