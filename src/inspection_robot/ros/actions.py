"""What an actionlib client still lacks to reach its server, named for a failure message.

ActionClient.wait_for_server is True only once a status message has come and the goal, cancel,
result and feedback topics are all connected to the server; its False says none of that. One
missing link (a subscription that never connected: compat_rospy.merge_publisher_updates) then
looks like a server that is not running. Public rospy API only: connection counts, not which
node each connection goes to.
"""


def missing_server_links(client):
    """The topics of ``client`` (an actionlib.ActionClient or SimpleActionClient) that are not up yet,
    in wait_for_server's order, e.g. ["result"]; [] when every one is connected."""
    client = getattr(client, "action_client", client)  # SimpleActionClient wraps an ActionClient
    missing = [] if client.last_status_msg else ["status (no message yet)"]
    for name, endpoint in (("goal", client.pub_goal), ("cancel", client.pub_cancel),
                           ("result", client.result_sub), ("feedback", client.feedback_sub)):
        if endpoint.get_num_connections() == 0:
            missing.append(name)
    return missing


def server_unavailable(name, client, waited_s):
    """The reason a goal was not sent: ``<name> server not available after <s> s: not connected: <topics>``."""
    missing = missing_server_links(client)
    return "%s server not available after %.2g s: %s" % (
        name, waited_s, "not connected: " + ", ".join(missing) if missing else "connected only now")
