"""compat_rospy: the rospy internals the fast paths rely on are there, and each fallback is the public API."""
import importlib.metadata

import pytest

from inspection_robot.ros import compat_rospy


def test_the_rospy_internals_are_those_the_fast_paths_expect():
    assert compat_rospy.MISSING == [], (
        "rospy %s changed internals that inspection_robot relies on: %s. The bridge and the handshake guard "
        "now run their public-API fallbacks (slower bursts, no back-pressure, unguarded accept): update "
        "ros/compat_rospy.py" % (importlib.metadata.version("rospy"), compat_rospy.MISSING))
    assert compat_rospy.describe() == "rospy internals as expected: every fast path on"


class FakePublisher(object):
    impl = None  # the fallbacks must not look inside

    def __init__(self):
        self.published = []

    def publish(self, msg):
        self.published.append(msg)


@pytest.fixture
def old_rospy(monkeypatch):
    """As if this rospy had none of the expected internals."""
    for flag in ("HANDSHAKE_GUARD", "FAST_PUBLISH", "DIRECT_WRITE", "QUEUE_DEPTH", "LATCHED_REPLAY"):
        monkeypatch.setattr(compat_rospy, flag, False)


def test_publish_batch_falls_back_to_publish_per_message(old_rospy):
    publisher = FakePublisher()
    compat_rospy.publish_batch(publisher, ["a", "b", "c"])
    assert publisher.published == ["a", "b", "c"]


def test_the_other_fallbacks_do_nothing_and_say_so(old_rospy):
    assert compat_rospy.write_direct(object(), b"x") is False
    assert compat_rospy.guard_inbound_handshakes(0.3) is False

    class Subscriber(object):
        impl = None
    compat_rospy.replay_latched(Subscriber(), lambda msg, args: None)


def test_queue_depth_is_zero_when_unreadable(old_rospy):
    class Publisher(object):
        class impl(object):
            connections = [type("Queued", (), {"_queue": [1, 2, 3]})()]
    assert compat_rospy.publisher_queue_depth(Publisher()) == 0


def test_queue_depth_reads_the_longest_queue():
    class Publisher(object):
        class impl(object):
            connections = [type("Queued", (), {"_queue": [1, 2, 3]})(), type("Queued", (), {"_queue": [1]})()]
    assert compat_rospy.publisher_queue_depth(Publisher()) == 3
