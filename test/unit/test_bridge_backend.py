"""compat_rospy.write_direct on a real rospy QueuedConnection: sends only while its thread idles, in order.
RosBackend.publish's batching: the first message of a loop pass goes at once, the rest in one batch."""
import socket
import threading
import time

import pytest
from rospy.impl.tcpros_pubsub import QueuedConnection

from inspection_robot.ros import bridge_backend
from inspection_robot.ros.compat_rospy import write_direct


class FakeTransport(object):
    """What QueuedConnection uses of a TCPROSTransport, on one end of a socket pair."""

    def __init__(self, sock):
        self.socket = sock
        self.done = False
        self.stat_bytes = 0
        self.written = []  # writes the connection's thread made
        self.gate = threading.Event()
        self.gate.set()
        self._cleanup = None

    def set_cleanup_callback(self, fn):
        self._cleanup = fn

    def write_data(self, data):
        self.gate.wait(5)
        self.written.append(data)
        self.socket.sendall(data)
        self.stat_bytes += len(data)

    def close(self):
        self.done = True
        self._cleanup(self)


def wait_for(condition, timeout=5.0):
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "condition not met in time"
        time.sleep(0.001)


def thread_idle(connection):
    return bool(connection._cond_data_available._waiters)


def recv_exactly(sock, n):
    data = b""
    sock.settimeout(5)
    while len(data) < n:
        data += sock.recv(n - len(data))
    return data


@pytest.fixture
def idle():
    """A QueuedConnection on one end of a socket pair, its thread waiting for data; and the peer."""
    ours, peer = socket.socketpair()
    transport = FakeTransport(ours)
    connection = QueuedConnection(transport, 0)
    wait_for(lambda: thread_idle(connection))
    yield connection, transport, peer
    transport.gate.set()
    transport.close()


def test_idle_thread_the_caller_sends_itself(idle):
    connection, transport, peer = idle
    assert write_direct(connection, b"hello")
    assert recv_exactly(peer, 5) == b"hello"
    assert transport.written == [] and transport.stat_bytes == 5


def test_busy_thread_keeps_the_write_so_nothing_overtakes_it(idle):
    connection, transport, peer = idle
    transport.gate.clear()
    connection.write_data(b"first")
    wait_for(lambda: not connection._queue)  # the thread took it and is stuck in its write
    assert not write_direct(connection, b"second")  # queue empty, but the thread is not idle
    connection.write_data(b"second")
    transport.gate.set()
    assert recv_exactly(peer, 11) == b"firstsecond"


def test_what_a_full_socket_does_not_take_is_queued_for_the_thread_in_order(idle):
    connection, transport, peer = idle
    transport.socket.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4096)
    data = bytes(bytearray(i % 251 for i in range(60000)))
    assert write_direct(connection, data)  # never blocks: the rest goes to the thread
    assert recv_exactly(peer, len(data)) == data
    wait_for(lambda: transport.stat_bytes == len(data))
    (rest,) = transport.written  # the thread sent only the tail the socket refused
    assert 0 < len(rest) < len(data) and data.endswith(rest)
    wait_for(lambda: thread_idle(connection))
    assert write_direct(connection, b"next")
    assert recv_exactly(peer, 4) == b"next"


def test_too_large_or_closed_goes_the_usual_way(idle):
    connection, transport, peer = idle
    assert not write_direct(connection, b"x" * 70000)
    transport.done = True
    assert not write_direct(connection, b"x")
    assert not write_direct(object(), b"x")


class Handle(object):
    data_class = object


class Codec(object):
    def from_json(self, cls, values):
        return values["data"]


def test_a_lone_message_goes_at_once_a_burst_once_per_loop_pass(monkeypatch):
    writes, posted = [], []
    monkeypatch.setattr(bridge_backend, "publish_batch", lambda handle, messages: writes.append(list(messages)))
    backend = bridge_backend.RosBackend(None, Codec(), lambda fn, *args: posted.append((fn, args)), None)
    entry = bridge_backend._Topic(Handle(), "std_msgs/String", bridge_backend.EarlyMessageReplay(0.0))
    backend._publishers["/t"] = entry

    def next_pass():
        for fn, args in posted:
            fn(*args)
        posted.clear()
    backend.publish("/t", {"data": "alone"})
    assert writes == [["alone"]]            # an echo or a command: sent before the pass ends
    for i in range(4):                      # the rest of a burst read in the same pass
        backend.publish("/t", {"data": str(i)})
    assert writes == [["alone"]]
    next_pass()
    assert writes == [["alone"], ["0", "1", "2", "3"]]
    for i in range(4, 7):                   # the burst goes on: the whole pass in one write
        backend.publish("/t", {"data": str(i)})
    next_pass()
    assert writes[2:] == [["4", "5", "6"]]
    backend.publish("/t", {"data": "last"})  # right after a burst: waits for the end of its pass
    assert len(writes) == 3
    next_pass()
    assert writes[3:] == [["last"]]
    backend.publish("/t", {"data": "quiet"})  # after a pass with one message: at once again
    assert writes[4:] == [["quiet"]]
