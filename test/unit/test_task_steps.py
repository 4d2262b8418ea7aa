"""task.ros_steps.wait_for_server: a step waits for an action server that is starting or respawning,
stays interruptible meanwhile, and fails naming the missing links only after its timeout.

The waits run on a simulated clock (each wait advances it by its timeout, as actionlib's wait does
while the server is down), so the counts do not depend on how busy the machine is."""
import types

import pytest

from inspection_robot.task import ros_steps
from inspection_robot.task.patrol import OUTCOME_FAILED, OUTCOME_INTERRUPTED
from inspection_robot_testing.clock import FakeClock


class Endpoint(object):
    def get_num_connections(self):
        return 0


class LateServer(object):
    """An actionlib client whose server comes up at its ``up_at``-th wait (never when None); each wait
    takes its timeout, as actionlib's does while the server is down."""

    def __init__(self, up_at, clock):
        self.up_at = up_at
        self.clock = clock
        self.waits = 0
        self.last_status_msg = None
        self.pub_goal = self.pub_cancel = self.result_sub = self.feedback_sub = Endpoint()

    def wait_for_server(self, timeout):
        self.waits += 1
        if self.up_at is not None and self.waits >= self.up_at:
            return True
        self.clock.now += timeout.to_sec()
        return False


@pytest.fixture
def clock(monkeypatch):
    simulated = FakeClock(1000.0)
    monkeypatch.setattr(ros_steps, "time", types.SimpleNamespace(monotonic=simulated.monotonic))
    return simulated


def test_a_server_that_comes_up_late_is_waited_for(clock):
    client = LateServer(up_at=12, clock=clock)   # 1.1 s of waits: longer than one poll, far shorter than the timeout
    assert ros_steps.wait_for_server(client, "move_action", lambda: False, 60.0) is None
    assert client.waits == 12


def test_a_pause_or_cancel_ends_the_wait_at_once(clock):
    client = LateServer(up_at=None, clock=clock)
    asked = []

    def interrupted():
        asked.append(1)
        return len(asked) >= 3

    assert ros_steps.wait_for_server(client, "find_scale_action", interrupted, 60.0) == \
        (OUTCOME_INTERRUPTED, "cancelled by task_manager")
    assert client.waits == 3
    assert clock.now - 1000.0 == pytest.approx(0.3)


def test_no_server_within_the_timeout_fails_the_step_naming_what_is_missing(clock):
    client = LateServer(up_at=None, clock=clock)
    outcome, reason = ros_steps.wait_for_server(client, "move_action", lambda: False, 0.3)
    assert outcome == OUTCOME_FAILED
    assert reason == ("move_action server not available after 0.3 s: not connected: status (no message yet), "
                      "goal, cancel, result, feedback")
    assert client.waits >= 3   # 0.1 s polls until the deadline
