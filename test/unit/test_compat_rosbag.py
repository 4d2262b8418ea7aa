"""compat_rosbag: rosbag's connection list is where it is expected, and the public fallback lists the same."""
import importlib.metadata
import os

import rosbag

from inspection_robot.ros import compat_rosbag

FIXTURE = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "fixtures", "replay_run.bag")


def test_the_rosbag_internals_are_those_bag_report_expects():
    assert compat_rosbag.MISSING == [], (
        "rosbag %s changed internals that bag_report relies on: %s. It now lists connections through "
        "read_messages' connection_filter: update ros/compat_rosbag.py"
        % (importlib.metadata.version("rosbag"), compat_rosbag.MISSING))


def test_the_fallback_lists_the_same_connections(monkeypatch):
    with rosbag.Bag(FIXTURE) as bag:
        fast = compat_rosbag.connections(bag)
        monkeypatch.setattr(compat_rosbag, "CONNECTIONS", False)
        public = compat_rosbag.connections(bag)
    assert len(fast) > 5 and public == fast
    assert all(conn.md5sum and conn.msg_def for conn in fast)
