"""ros.actions: a failed wait_for_server names the action topics that are not connected."""
from inspection_robot.ros.actions import missing_server_links, server_unavailable


class Endpoint(object):
    def __init__(self, connections):
        self.connections = connections

    def get_num_connections(self):
        return self.connections


class Client(object):
    """The attributes actionlib.ActionClient.wait_for_server reads."""

    def __init__(self, status=True, goal=1, cancel=1, result=1, feedback=1):
        self.last_status_msg = object() if status else None
        self.pub_goal, self.pub_cancel = Endpoint(goal), Endpoint(cancel)
        self.result_sub, self.feedback_sub = Endpoint(result), Endpoint(feedback)


class SimpleClient(object):
    def __init__(self, client):
        self.action_client = client


def test_the_missing_result_subscription_is_named():
    client = Client(result=0)
    assert missing_server_links(client) == ["result"]
    assert server_unavailable("move_action", client, 0.05) == \
        "move_action server not available after 0.05 s: not connected: result"


def test_no_server_at_all_lists_every_link_and_a_simple_client_is_looked_through():
    client = SimpleClient(Client(status=False, goal=0, cancel=0, result=0, feedback=0))
    assert missing_server_links(client) == ["status (no message yet)", "goal", "cancel", "result", "feedback"]
    assert server_unavailable("find_scale_action", client, 5.0).startswith(
        "find_scale_action server not available after 5 s: not connected: status (no message yet), goal")


def test_a_server_that_came_up_after_the_wait_says_so():
    assert server_unavailable("move_action", Client(), 0.05) == \
        "move_action server not available after 0.05 s: connected only now"
