"""motion.owners: a safety input counts only from its owner's caller id, resolved in the node's namespace."""
import threading

import pytest

from inspection_robot.motion.owners import DEFAULT_OWNERS, OwnerCheck, resolve_node_name


def test_owners_resolve_relative_to_the_namespace():
    assert resolve_node_name("/", "obstacle_detector") == "/obstacle_detector"
    assert resolve_node_name("/robot_7/", "obstacle_detector") == "/robot_7/obstacle_detector"
    assert resolve_node_name("/robot_7", "obstacle_detector") == "/robot_7/obstacle_detector"
    assert resolve_node_name("/robot_7/", "/obstacle_detector") == "/obstacle_detector"
    for bad in ("", "/", "~private", "two words", None, 7):
        with pytest.raises(ValueError):
            resolve_node_name("/", bad)


def test_only_the_owner_counts_not_the_sender_string():
    check = OwnerCheck("/robot_7/")
    assert check.allows("obstacle_status", "/robot_7/obstacle_detector")
    assert check.allows("robot_status", "/robot_7/status_control")
    assert check.allows("joy_control", "/robot_7/joy_control")
    assert check.allows("move_base", "/robot_7/move_base")
    # the bridge's publisher for every websocket client, another robot's detector, a node outside the namespace
    for caller in ("/robot_7/rosbridge_websocket/tcpros", "/robot_8/obstacle_detector", "/obstacle_detector",
                   "/robot_7/obstacle_detector_x", None):
        assert not check.allows("obstacle_status", caller)
    assert check.refused() == {"obstacle_status": 5}
    assert not check.allows("joy_control", "/robot_7/rosbridge_websocket/tcpros")
    assert check.total_refused() == 6


def test_a_sender_nobody_owns_is_anyones():
    check = OwnerCheck("/")
    assert check.owner("server") is None
    assert check.allows("server", "/rosbridge_websocket/tcpros")
    assert check.allows("", None)
    assert check.refused() == {}


def test_the_refusal_names_the_caller_and_the_owner():
    check = OwnerCheck("/")
    check.allows("obstacle_status", "/rosbridge_websocket/tcpros")
    assert check.refusal("obstacle_status", "/rosbridge_websocket/tcpros") == (
        "obstacle_status from /rosbridge_websocket/tcpros ignored: only /obstacle_detector may send it")
    check.allows("joy_control", None)
    assert check.refusal("joy_control", None) == (
        "sender 'joy_control' from an unknown caller ignored: only /joy_control may send it")
    assert check.refused() == {"obstacle_status": 1, "joy_control": 1}


def test_a_test_rig_names_its_own_node_and_keeps_the_other_defaults():
    check = OwnerCheck("/", {"obstacle_status": "test_motion_control"})
    assert check.allows("obstacle_status", "/test_motion_control")
    assert not check.allows("obstacle_status", "/obstacle_detector")
    assert check.owner("robot_status") == "/status_control"
    assert set(check.owners) == set(DEFAULT_OWNERS)
    with pytest.raises(ValueError, match="unknown owner key 'obstacle'"):
        OwnerCheck("/", {"obstacle": "x"})
    with pytest.raises(ValueError):
        OwnerCheck("/", {"robot_status": ""})


def test_refusals_from_many_threads_are_all_counted():
    check = OwnerCheck("/")

    def spoof():
        for _ in range(1000):
            check.allows("robot_status", "/intruder")
    threads = [threading.Thread(target=spoof) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert check.refused() == {"robot_status": 4000}
