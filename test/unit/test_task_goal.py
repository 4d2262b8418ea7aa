"""task/ros_goal.py: TaskService's goal calls become the actionlib goal handle's, each end its terminal state."""
from inspection_robot.msg import GeneralGoal
from inspection_robot.task.ros_goal import ActionGoal
from inspection_robot.task.action import END_ABORTED, END_CANCELED, END_SUCCEEDED


class Handle(object):
    """An actionlib ServerGoalHandle recording the calls it gets."""

    class GoalId(object):
        id = "g1"

    def __init__(self):
        self.calls = []

    def get_goal_id(self):
        return Handle.GoalId()

    def get_goal(self):
        return GeneralGoal(sender="backend", type="patrol", data="{}")

    def __getattr__(self, name):
        return lambda *args: self.calls.append((name,) + args)


def test_each_end_sets_its_terminal_state_with_the_result():
    for end, method in ((END_SUCCEEDED, "set_succeeded"), (END_CANCELED, "set_canceled"),
                        (END_ABORTED, "set_aborted")):
        handle = Handle()
        ActionGoal(handle).end(end, "1", '{"state": "x"}', "why")
        [(name, result, text)] = handle.calls
        assert (name, result.ret_code, result.data, text) == (method, "1", '{"state": "x"}', "why")


def test_request_accept_feedback_and_refusal():
    handle = Handle()
    goal = ActionGoal(handle)
    assert (goal.id, goal.request.type, goal.request.sender) == ("g1", "patrol", "backend")
    goal.accept()
    goal.feedback("2", "{}")
    goal.refuse("3", '{"reason": "busy"}', "busy")
    assert [c[0] for c in handle.calls] == ["set_accepted", "publish_feedback", "set_rejected"]
    assert (handle.calls[1][1].event_code, handle.calls[2][1].ret_code, handle.calls[2][2]) == ("2", "3", "busy")
