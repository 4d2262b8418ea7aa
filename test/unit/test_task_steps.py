"""task.ros_steps.wait_for_server: a step waits for an action server that is starting or respawning,
stays interruptible meanwhile, and fails naming the missing links only after its timeout."""
import time

from inspection_robot.task import ros_steps
from inspection_robot.task.patrol import OUTCOME_FAILED, OUTCOME_INTERRUPTED


class Endpoint(object):
    def get_num_connections(self):
        return 0


class LateServer(object):
    """An actionlib client whose server comes up at its ``up_at``-th wait (never when None); each wait
    takes its timeout, as actionlib's does while the server is down."""

    def __init__(self, up_at):
        self.up_at = up_at
        self.waits = 0
        self.last_status_msg = None
        self.pub_goal = self.pub_cancel = self.result_sub = self.feedback_sub = Endpoint()

    def wait_for_server(self, timeout):
        self.waits += 1
        if self.up_at is not None and self.waits >= self.up_at:
            return True
        time.sleep(timeout.to_sec())
        return False


def test_a_server_that_comes_up_late_is_waited_for():
    client = LateServer(up_at=12)   # 1.1 s of waits: longer than one poll, far shorter than the timeout
    assert ros_steps.wait_for_server(client, "move_action", lambda: False, 60.0) is None
    assert client.waits == 12


def test_a_pause_or_cancel_ends_the_wait_at_once():
    client = LateServer(up_at=None)
    asked = []

    def interrupted():
        asked.append(1)
        return len(asked) >= 3

    started = time.monotonic()
    assert ros_steps.wait_for_server(client, "find_scale_action", interrupted, 60.0) == \
        (OUTCOME_INTERRUPTED, "cancelled by task_manager")
    assert client.waits == 3
    assert time.monotonic() - started < 5.0


def test_no_server_within_the_timeout_fails_the_step_naming_what_is_missing():
    client = LateServer(up_at=None)
    outcome, reason = ros_steps.wait_for_server(client, "move_action", lambda: False, 0.3)
    assert outcome == OUTCOME_FAILED
    assert reason == ("move_action server not available after 0.3 s: not connected: status (no message yet), "
                      "goal, cancel, result, feedback")
    assert client.waits >= 3
