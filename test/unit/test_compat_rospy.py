"""compat_rospy: the rospy internals the repairs rely on are there, and each fallback is the public API."""
import importlib.metadata
import threading

import pytest
from rospy.impl import registration

from inspection_robot.ros import compat_rospy


def test_the_rospy_internals_are_those_the_repairs_expect():
    assert compat_rospy.MISSING == [], (
        "rospy %s changed internals that inspection_robot relies on: %s. The bridge and the handshake guard "
        "now run their public-API fallbacks (unguarded accept, no update merge, no latched replay): update "
        "ros/compat_rospy.py" % (importlib.metadata.version("rospy"), compat_rospy.MISSING))
    assert compat_rospy.describe() == "rospy internals as expected: every repair on"


@pytest.fixture
def old_rospy(monkeypatch):
    """As if this rospy had none of the expected internals."""
    for flag in ("UPDATE_MERGE", "HANDSHAKE_GUARD", "LATCHED_REPLAY", "CALLER_ID", "IDLE_CONNECTION"):
        monkeypatch.setattr(compat_rospy, flag, False)


def test_the_fallbacks_do_nothing_and_say_so(old_rospy):
    assert compat_rospy.guard_inbound_handshakes(0.3) is False
    assert compat_rospy.merge_publisher_updates() is False

    class Subscriber(object):
        impl = None
    compat_rospy.replay_latched(Subscriber(), lambda msg, args: None)
    assert compat_rospy.caller_id(received("/obstacle_detector")) is None   # unknown: owners refuse it
    proxy, _ends = connected_proxy()
    assert compat_rospy.idle_service_connection_closed(proxy) is False     # not known: the call finds out
    assert compat_rospy.service_proxy_uri(proxy) is None


def received(callerid):
    """A message as rospy's TCPROSTransport.receive_once hands it to a callback: the connection's
    header (a dict of the publisher's handshake fields) set on it."""
    from inspection_robot.msg import ObstacleStatus
    msg = ObstacleStatus(sender="obstacle_detector", obstacle=False)
    msg._connection_header = {"callerid": callerid, "topic": "/obstacle_status", "latching": "1",
                              "type": "inspection_robot/ObstacleStatus"}
    return msg


def test_caller_id_is_the_publishing_node_not_the_sender_field():
    bridge = "/robot_7/rosbridge_websocket/tcpros"
    assert compat_rospy.caller_id(received(bridge)) == bridge
    from inspection_robot.msg import ObstacleStatus
    assert compat_rospy.caller_id(ObstacleStatus(sender="obstacle_detector")) is None   # not received: no header


class RecordingHandler(object):
    """The node handler RegManager's thread asks to connect; records what it is asked."""

    def __init__(self):
        self.done = False
        self.connects = []
        self.asked = threading.Condition()

    def _connect_topic(self, topic, uri):
        with self.asked:
            self.connects.append((topic, uri))
            self.asked.notify_all()
        return 1, "", 0


SENTINEL = ("/sentinel", "http://sentinel:1/")


def connects_after_the_race():
    """What a real RegManager connects to when the master's publisherUpdate [pub] and the subscriber's
    older registerSubscriber reply [] are both queued, in that order, before its thread runs (it is busy).
    Its thread takes the newest update first: a sentinel queued before them all is connected last, so
    once it is, every connect thread of theirs has started, and they are joined (no wait for a
    connect that never comes)."""
    handler = RecordingHandler()
    manager = registration.RegManager(handler)
    manager.publisher_update(SENTINEL[0], [SENTINEL[1]])
    manager.publisher_update("/move_action/result", ["http://vm:36127/"])  # the master's publisherUpdate
    manager.publisher_update("/move_action/status", ["http://vm:36127/"])
    manager.publisher_update("/move_action/result", [])  # registerSubscriber's reply, queued late
    thread = threading.Thread(target=manager.run, daemon=True)
    thread.start()
    with handler.asked:  # the connects come from RegManager's own short-lived threads
        assert handler.asked.wait_for(lambda: SENTINEL in handler.connects, timeout=20.0), handler.connects
    handler.done = True
    for started in threading.enumerate():
        if getattr(started, "_target", None) == manager._connect_topic_thread:
            started.join(5.0)
    thread.join(5.0)
    return sorted(c for c in handler.connects if c != SENTINEL)


@pytest.fixture
def restore_publisher_update(monkeypatch):
    monkeypatch.setattr(registration.RegManager, "publisher_update", registration.RegManager.publisher_update)


def test_rospy_alone_drops_the_newer_publisher_list(restore_publisher_update):
    """The race merge_publisher_updates repairs; when this fails, rospy fixed it and the repair can go."""
    if getattr(registration.RegManager.publisher_update, "merges", False):
        pytest.skip("the repair is already applied in this process")
    assert connects_after_the_race() == [("/move_action/status", "http://vm:36127/")]


def test_merged_updates_keep_every_publisher_of_a_topic(restore_publisher_update):
    assert compat_rospy.merge_publisher_updates() is True
    assert compat_rospy.merge_publisher_updates() is True  # idempotent
    assert connects_after_the_race() == [("/move_action/result", "http://vm:36127/"),
                                         ("/move_action/status", "http://vm:36127/")]


def test_merged_updates_keep_one_entry_per_topic_newest_list_first(restore_publisher_update):
    compat_rospy.merge_publisher_updates()
    manager = registration.RegManager(RecordingHandler())
    manager.publisher_update("/a", ["http://one:1/", "http://two:2/"])
    manager.publisher_update("/b", ["http://one:1/"])
    manager.publisher_update("/a", ["http://three:3/", "http://two:2/"])
    assert manager.updates == [("/b", ["http://one:1/"]),
                               ("/a", ["http://three:3/", "http://two:2/", "http://one:1/"])]


def connected_proxy():
    """A persistent ServiceProxy holding a connection as after its first call: (proxy, (its end, the node's end))."""
    import socket

    import rospy
    from rospy.impl.tcpros_base import TCPROSTransport

    from inspection_robot.srv import ControlService
    proxy = rospy.ServiceProxy("/file_control", ControlService, persistent=True)
    ours, nodes = socket.socketpair()
    proxy.transport = TCPROSTransport(proxy.protocol, proxy.resolved_name)
    proxy.transport.socket = ours
    proxy.uri = "rosrpc://127.0.0.1:40000"
    return proxy, (ours, nodes)


def test_an_idle_service_connection_is_seen_closed_when_its_node_closes_it():
    proxy, (ours, nodes) = connected_proxy()
    assert compat_rospy.idle_service_connection_closed(proxy) is False
    assert compat_rospy.service_proxy_uri(proxy) == "rosrpc://127.0.0.1:40000"
    nodes.close()                              # the node died or restarted
    assert compat_rospy.idle_service_connection_closed(proxy) is True
    ours.close()
    proxy.transport.close()
    assert compat_rospy.idle_service_connection_closed(proxy) is True     # closed here: done
    proxy.transport = None
    assert compat_rospy.idle_service_connection_closed(proxy) is False    # none held: the next call connects
