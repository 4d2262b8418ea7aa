"""A task_action goal handle (actionlib ServerGoalHandle of GeneralAction) as task.service.TaskService
uses it: the request, accept, feedback, the end task.action.goal_end chose, and a refusal."""
from inspection_robot.msg import GeneralFeedback, GeneralResult
from inspection_robot.task.action import END_CANCELED, END_SUCCEEDED


class ActionGoal(object):
    """``request``: the GeneralGoal (type, data, sender), read when the goal is handled; ``id``: its goal
    id, which a cancel request names."""

    def __init__(self, handle):
        self._handle = handle
        self.id = handle.get_goal_id().id

    @property
    def request(self):
        return self._handle.get_goal()

    def accept(self):
        self._handle.set_accepted()

    def feedback(self, event_code, data):
        self._handle.publish_feedback(GeneralFeedback(event_code=event_code, data=data))

    def end(self, end, ret_code, data, text):
        ends = {END_SUCCEEDED: self._handle.set_succeeded, END_CANCELED: self._handle.set_canceled}
        ends.get(end, self._handle.set_aborted)(GeneralResult(ret_code=ret_code, data=data), text)

    def refuse(self, ret_code, data, text):
        self._handle.set_rejected(GeneralResult(ret_code=ret_code, data=data), text)
