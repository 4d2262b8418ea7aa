"""server: bounded send queue; a live tornado server with the fake backend (TLS, size limit, keep-alive)."""
import asyncio
import base64
import concurrent.futures
import os
import shutil
import socket
import subprocess
import ssl
import threading
import time

import pytest
import tornado.ioloop

from bridge_fakes import FakeBackend
from inspection_robot.bridge.client import CLOSED, RawClient
from inspection_robot.bridge.protocol import Session, SessionConfig
from inspection_robot.bridge.server import BridgeServer, LoopPoster, SendQueue, make_ssl_context, ws_frame


def test_send_queue_drops_oldest_topic_messages_and_honours_per_topic_limits():
    q = SendQueue(3)
    for i in range(5):
        assert q.put([str(i)], "/a")
    assert len(q) == 3 and q.dropped == 2
    q.put(["reply"], droppable=False)
    assert q.pop() == ["reply"]
    assert [q.pop(), q.pop(), q.pop(), q.pop()] == [["2"], ["3"], ["4"], None]
    q = SendQueue(100)
    for i in range(5):
        q.put(["a%d" % i], "/a", limit=2)
        q.put(["b%d" % i], "/b")
    got = []
    while len(q):
        got.append(q.pop()[0])
    assert got == ["b0", "b1", "b2", "a3", "b3", "a4", "b4"]


def test_send_queue_reports_undroppable_overflow():
    q = SendQueue(2)
    assert q.put(["r1"], droppable=False) and q.put(["r2"], droppable=False)
    assert not q.put(["r3"], droppable=False)


class LiveServer(object):
    def __init__(self, **kwargs):
        self.backend = FakeBackend()
        self.counts = []
        ready = concurrent.futures.Future()
        self.thread = threading.Thread(target=self._run, args=(ready, kwargs))
        self.thread.daemon = True
        self.thread.start()
        self.port = ready.result(5)

    def _run(self, ready, kwargs):
        asyncio.set_event_loop(asyncio.new_event_loop())
        self.loop = tornado.ioloop.IOLoop.current()

        def make_session(client_id, send, call_later, close):
            return Session(client_id, self.backend, send, time.monotonic, call_later, close, SessionConfig())
        self.server = BridgeServer(make_session, "127.0.0.1", 0, on_client_count=self.counts.append, **kwargs)
        ready.set_result(self.server.start())
        self.loop.start()

    def stop(self):
        self.loop.add_callback(self.server.stop)
        self.loop.add_callback(self.loop.stop)
        self.thread.join(3)

    def wait_count(self, n, timeout=5.0):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.counts and self.counts[-1] == n:
                return
            time.sleep(0.01)
        raise AssertionError("client count %s, wanted %d" % (self.counts[-1:], n))


@pytest.fixture
def live():
    server = LiveServer(ping_interval=0.2, ping_timeout=0.5, max_message_size=2000)
    yield server
    server.stop()


def test_round_trip_size_limit_and_other_clients_unaffected(live):
    a = RawClient("ws://127.0.0.1:%d" % live.port)
    b = RawClient("ws://127.0.0.1:%d" % live.port)
    live.wait_count(2)
    a.send({"op": "call_service", "id": 1, "service": "/echo", "args": {"x": 1}})
    assert a.recv_message()["values"] == {"echo": {"x": 1}}
    b.send("x" * 5000)  # larger than max_message_size
    assert b.recv(3) is CLOSED and b.close_code == 1009
    live.wait_count(1)
    a.send({"op": "call_service", "id": 2, "service": "/echo", "args": {}})
    assert a.recv_message()["id"] == 2
    a.close()
    live.wait_count(0)


def test_silent_client_is_dropped_by_keepalive(live):
    sock = socket.create_connection(("127.0.0.1", live.port), 2)
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall(("GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                  "Sec-WebSocket-Key: %s\r\nSec-WebSocket-Version: 13\r\n\r\n" % key).encode())
    assert b"101" in sock.recv(1024).split(b"\r\n")[0]
    live.wait_count(1)
    start = time.monotonic()
    # never answers pings: its socket is closed once ping_timeout (0.5 s) passed, without waiting
    # for a close handshake (tornado's own keep-alive would add 5 s)
    live.wait_count(0, timeout=3.0)
    assert time.monotonic() - start < 1.5
    sock.settimeout(2.0)
    while sock.recv(4096):  # the server closed its end: recv drains the pings, then sees EOF
        pass
    sock.close()


def test_answering_client_is_kept_alive(live):
    client = RawClient("ws://127.0.0.1:%d" % live.port)  # tornado's client answers pings
    live.wait_count(1)
    time.sleep(1.5)  # three ping timeouts long: the client must stay connected
    client.send({"op": "call_service", "id": "alive", "service": "/echo"})
    assert client.recv_message()["id"] == "alive"
    assert live.counts[-1] == 1
    client.close()


def test_loop_poster_runs_in_order_once_per_burst_and_isolates_failures():
    calls, wakeups, errors = [], [], []

    class Loop(object):
        def add_callback(self, fn):
            wakeups.append(fn)

    poster = LoopPoster(Loop(), lambda level, text: errors.append(text))
    poster.post(calls.append, 1)
    poster.post(lambda: 1 / 0)
    poster.post(calls.append, 2)
    assert len(wakeups) == 1 and calls == []
    wakeups.pop()()
    assert calls == [1, 2] and len(errors) == 1
    poster.post(calls.append, 3)
    assert len(wakeups) == 1
    wakeups.pop()()
    assert calls == [1, 2, 3]


def test_ws_frame_headers():
    assert ws_frame("hi") == b"\x81\x02hi"
    assert ws_frame(b"\x00") == b"\x82\x01\x00"
    assert ws_frame("x" * 126)[:4] == b"\x81\x7e\x00\x7e"
    assert ws_frame(b"y" * 70000)[:10] == b"\x82\x7f" + (70000).to_bytes(8, "big")


def test_batched_frames_of_every_length_class_arrive_intact():
    server = LiveServer(ping_interval=0)
    try:
        client = RawClient("ws://127.0.0.1:%d" % server.port)
        sizes = [0, 100, 125, 126, 65535, 65536, 200000]
        for i, size in enumerate(sizes):  # sent back to back: the replies share socket writes
            client.send({"op": "call_service", "id": i, "service": "/echo", "args": {"s": "z" * size}})
        for i, size in enumerate(sizes):
            reply = client.recv_message(lambda m: m.get("op") == "service_response")
            assert reply["id"] == i and reply["values"] == {"echo": {"s": "z" * size}}
        client.close()
    finally:
        server.stop()


@pytest.mark.skipif(shutil.which("openssl") is None, reason="needs the openssl CLI to make a certificate")
def test_tls(tmp_path):
    cert, key = str(tmp_path / "cert.pem"), str(tmp_path / "key.pem")
    subprocess.check_call(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", key, "-out", cert,
                           "-days", "1", "-subj", "/CN=127.0.0.1"], stdout=subprocess.DEVNULL,
                          stderr=subprocess.DEVNULL)
    server = LiveServer(ssl_context=make_ssl_context(cert, key))
    try:
        context = ssl.create_default_context(cafile=cert)
        context.check_hostname = False
        client = RawClient("wss://127.0.0.1:%d" % server.port, ssl_options=context)
        client.send({"op": "call_service", "id": "tls", "service": "/echo"})
        assert client.recv_message()["id"] == "tls"
        client.close()
        with pytest.raises(Exception):
            RawClient("ws://127.0.0.1:%d" % server.port, timeout=2.0)
    finally:
        server.stop()
