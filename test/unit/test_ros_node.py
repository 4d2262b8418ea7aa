"""The inbound-handshake guard: a connection that never sends a TCPROS header no longer blocks rospy's accept thread.
renice: every thread of the process, and those made later."""
import errno
import os
import socket
import subprocess
import sys
import threading
import time

import pytest
import rospy

from rosgraph.network import write_ros_handshake_header
from rospy.impl import tcpros_base

from inspection_robot.ros import node
from inspection_robot.settings import SettingsError


class Recorder(tcpros_base.TCPROSServer):
    """rospy's own TCPROSServer (its _tcp_server_callback), handing topic connections to a list."""

    def __init__(self):
        super(Recorder, self).__init__()
        self.topics = []
        self.topic_connection_handler = lambda sock, addr, header: self.topics.append(header["topic"])


def connect_pair():
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(1)
    client = socket.create_connection(listener.getsockname())
    server_side, _ = listener.accept()
    listener.close()
    return client, server_side


def serve_in_thread(server, sock):
    done = threading.Event()

    def run():
        server._tcp_server_callback(sock, ("127.0.0.1", 0))
        done.set()
    threading.Thread(target=run, daemon=True).start()
    return done


def test_a_silent_or_foreign_client_is_dropped_after_the_timeout(monkeypatch):
    monkeypatch.setattr(tcpros_base.TCPROSServer, "_tcp_server_callback", tcpros_base.TCPROSServer._tcp_server_callback)
    node.guard_inbound_handshakes(timeout_s=0.3)
    server = Recorder()
    for first_bytes in (b"", b"GET / HTTP/1.1\r\nHost: robot\r\n\r\n"):   # silent; a websocket client on a reused port
        client, server_side = connect_pair()
        client.sendall(first_bytes)
        started = time.monotonic()
        assert serve_in_thread(server, server_side).wait(5.0), "the handshake read was not bounded"
        assert time.monotonic() - started < 3.0
        assert client.recv(16) == b""          # dropped: closed by the server
        client.close()
    assert server.topics == []


def test_a_real_tcpros_client_is_still_served_and_its_socket_left_blocking(monkeypatch):
    monkeypatch.setattr(tcpros_base.TCPROSServer, "_tcp_server_callback", tcpros_base.TCPROSServer._tcp_server_callback)
    node.guard_inbound_handshakes(timeout_s=0.3)
    node.guard_inbound_handshakes(timeout_s=0.3)   # idempotent: one guard, not two
    server = Recorder()
    client, server_side = connect_pair()
    write_ros_handshake_header(client, {"topic": "/robot_status", "callerid": "/backend", "md5sum": "*", "type": "*"})
    assert serve_in_thread(server, server_side).wait(5.0)
    assert server.topics == ["/robot_status"]
    assert server_side.gettimeout() is None
    client.close()
    server_side.close()
    assert tcpros_base.TCPROSServer._tcp_server_callback.unguarded.__name__ == "_tcp_server_callback"


def test_renice_reaches_every_thread_and_the_ones_made_later():
    # in a child process: a niceness raised cannot be lowered again without privilege
    script = (
        "import os, threading\n"
        "from inspection_robot.ros.node import renice\n"
        "stop = threading.Event()\n"
        "early = threading.Thread(target=stop.wait); early.start()\n"
        "base = os.getpriority(os.PRIO_PROCESS, 0)\n"
        "target = min(19, base + 3)\n"
        "assert renice(target) is None\n"
        "late = threading.Thread(target=stop.wait); late.start()\n"
        "values = {os.getpriority(os.PRIO_PROCESS, int(t)) for t in os.listdir('/proc/self/task')}\n"
        "stop.set()\n"
        "print(sorted(values) == [target], len(os.listdir('/proc/self/task')))\n")
    out = subprocess.run([sys.executable, "-c", script], stdout=subprocess.PIPE, check=True, universal_newlines=True)
    assert out.stdout.split()[0] == "True"


def autogroup_nice_after(code, new_session, env=None, expected=None):
    """The autogroup niceness a child process reports after running ``code`` (Linux with autogroup).
    A busy kernel may refuse a change for a moment (EAGAIN without CAP_SYS_ADMIN) and renice then
    tries again in the background: the child waits up to 5 s for ``expected`` before it reports."""
    script = ("import sys, time\nfrom inspection_robot.ros import node\n" + code +
              "\nend = time.monotonic() + 5.0\n"
              "while sys.argv[1] not in ('None', open('/proc/self/autogroup').read().split()[-1])"
              " and time.monotonic() < end:\n"
              "    time.sleep(0.05)\n"
              "print(open('/proc/self/autogroup').read().split()[-1])\n")
    out = subprocess.run([sys.executable, "-c", script, str(expected)], stdout=subprocess.PIPE, check=True,
                         universal_newlines=True, start_new_session=new_session, env=dict(os.environ, **(env or {})))
    return out.stdout.split()


@pytest.mark.skipif(not os.path.exists("/proc/self/autogroup"), reason="kernel without autogroup scheduling")
def test_renice_reaches_the_session_a_node_leads_and_leaves_a_shell_s_alone():
    # roslaunch starts every node in its own session: with autogroup the CPU is shared between sessions
    # first, so a node's niceness counts against the other nodes only through its autogroup
    assert autogroup_nice_after("assert node.renice(7) is None", new_session=True, expected=7) == ["7"]
    base = open("/proc/self/autogroup").read().split()[-1]
    assert autogroup_nice_after("assert node.renice(7) is None", new_session=False) == [base]


@pytest.mark.skipif(not os.path.exists("/proc/self/autogroup"), reason="kernel without autogroup scheduling")
def test_the_environment_renices_a_node_and_a_bad_value_is_named_not_applied():
    code = "print(node.renice_from_environment())"
    assert autogroup_nice_after(code, True, {node.NICE_ENV: "6"}, expected=6) == ["None", "6"]
    out = autogroup_nice_after(code, True, {node.NICE_ENV: "fast"})
    assert " ".join(out[:-1]) == "INSPECTION_ROBOT_NICE='fast' is not a niceness (-20..19): ignored"
    assert out[-1] == "0"
    assert autogroup_nice_after(code, True, {node.NICE_ENV: "25"})[-1] == "0"
    assert autogroup_nice_after(code, True, {node.NICE_ENV: ""}) == ["None", "0"]


def test_an_autogroup_refusal_is_named_and_a_kernel_without_autogroup_passed_over(tmp_path):
    assert node.set_autogroup_niceness(3, str(tmp_path / "missing")) is None
    refused = node.set_autogroup_niceness(3, str(tmp_path))
    assert refused == "cannot set the session's autogroup niceness 3: Is a directory"


def test_a_change_the_kernel_refuses_for_now_is_tried_again(monkeypatch):
    answers = [OSError(errno.EAGAIN, "busy"), OSError(errno.EAGAIN, "busy"), None]
    monkeypatch.setattr(node, "_write_autogroup", lambda niceness, path: answers.pop(0))
    monkeypatch.setattr(node.random, "uniform", lambda lo, hi: 0.0)
    assert node.set_autogroup_niceness(5, "autogroup") is None
    assert answers == []
    monkeypatch.setattr(node, "_write_autogroup", lambda niceness, path: OSError(errno.EAGAIN, "busy"))
    refused = node.set_autogroup_niceness(5, "autogroup", retry_s=0.0)
    assert refused == "cannot set the session's autogroup niceness 5: busy"


def test_renice_refuses_an_impossible_niceness():
    with pytest.raises(ValueError):
        node.renice(42)


def test_a_slow_but_live_client_is_served_the_bound_is_per_read(monkeypatch):
    """A loaded subscriber whose header trickles in (each gap below the timeout, all of it above) is
    still served: the guard drops only a client silent for a whole timeout, and rospy's subscriber
    would not retry a dropped handshake (ros/node.py)."""
    monkeypatch.setattr(tcpros_base.TCPROSServer, "_tcp_server_callback", tcpros_base.TCPROSServer._tcp_server_callback)
    node.guard_inbound_handshakes(timeout_s=0.3)
    server = Recorder()
    client, server_side = connect_pair()
    sink, source = socket.socketpair()  # the header as rospy's own writer serialises it, sent in pieces
    write_ros_handshake_header(sink, {"topic": "/move_action/result", "callerid": "/charge_control", "md5sum": "*",
                                      "type": "*"})
    sink.close()
    data = b"".join(iter(lambda: source.recv(4096), b""))
    source.close()
    done = serve_in_thread(server, server_side)
    started = time.monotonic()
    for start in range(0, len(data), len(data) // 4 + 1):
        time.sleep(0.15)
        client.sendall(data[start:start + len(data) // 4 + 1])
    assert done.wait(5.0)
    assert time.monotonic() - started > 0.3, "the header took longer than one timeout in all"
    assert server.topics == ["/move_action/result"]
    client.close()
    server_side.close()


def test_node_settings_take_the_parameter_server_else_the_file(monkeypatch):
    server = {"~rate": 99.0, "~ros_base": {"odom_topic": "wheel/odom"}}
    monkeypatch.setattr(rospy, "has_param", lambda name: name in server)
    monkeypatch.setattr(rospy, "get_param", lambda name: server[name])
    reader = node.NodeSettings("robot_control")   # config/ of this source tree, no ROS package path needed
    assert reader.get("~rate") == 99.0 and reader.get("~cmd_timeout") == 0.5
    base = reader.get("~ros_base")
    assert base["odom_topic"] == "wheel/odom" and base["cmd_vel_topic"] == "cmd_vel"
    with pytest.raises(SettingsError, match="config/robot_control.yaml"):
        reader.get("~no_such_setting")
    with pytest.raises(ValueError):
        reader.get("rate")
