"""A minimal blocking websocket client for tests and benchmarks of the bridge (tornado, own thread).

Not used by the robot: it lets rostests and bench/bench_bridge.py send raw frames (JSON, CBOR,
fragments, malformed input) that roslibpy cannot produce, and read every frame the server sends.
:class:`SocketClient` is a client that does not read until asked (a stuck backend).
"""
import asyncio
import base64
import json
import os
import queue
import socket
import struct
import threading

import tornado.httpclient
import tornado.ioloop
import tornado.websocket

from inspection_robot.bridge import cbor

CLOSED = object()


# how long a test waits for a frame it expects: a bound for a lost one, not a speed limit (a loaded CI
# machine took over 5 s to close a refused connection); waits for silence pass their own short timeout
REPLY_WAIT_S = 30.0


class RawClient(object):
    """Connects to ``url`` (ws:// or wss://); frames are read with :meth:`recv`. ``headers``: extra
    handshake headers (an ``Origin`` to act as a browser page); ``source_ip``: the local address to
    connect from (another loopback address acts as another peer)."""

    def __init__(self, url, timeout=5.0, ssl_options=None, max_message_size=64 * 1024 * 1024, headers=None,
                 source_ip=None):
        self.url = url
        self.frames = queue.Queue()
        self.close_code = None
        self.close_reason = None
        self._error = None
        self._conn = None
        self._loop = None
        self._ready = threading.Event()
        self._request = tornado.httpclient.HTTPRequest(url, ssl_options=ssl_options, headers=headers,
                                                       network_interface=source_ip)
        self._max = max_message_size
        self._thread = threading.Thread(target=self._run, name="raw_ws_client")
        self._thread.daemon = True
        self._thread.start()
        if not self._ready.wait(timeout):
            raise RuntimeError("no websocket connection to %s within %.1f s" % (url, timeout))
        if self._error is not None:
            raise self._error

    def _run(self):
        asyncio.set_event_loop(asyncio.new_event_loop())
        self._loop = tornado.ioloop.IOLoop.current()
        try:
            self._conn = self._loop.run_sync(self._connect)
        except Exception as exc:  # boundary: reported to the constructor's caller
            self._error = exc
            self._ready.set()
            return
        self._ready.set()
        self._loop.start()

    async def _connect(self):
        return await tornado.websocket.websocket_connect(self._request, on_message_callback=self._on_message,
                                                         max_message_size=self._max)

    def _on_message(self, message):
        if message is None:
            self.close_code = self._conn.close_code if self._conn is not None else None
            self.close_reason = self._conn.close_reason if self._conn is not None else None
            self.frames.put(CLOSED)
        else:
            self.frames.put(message)

    def send(self, data):
        """Send a dict (as JSON), a str (text frame) or bytes (binary frame)."""
        if isinstance(data, dict):
            data = json.dumps(data)
        self._loop.add_callback(self._write, data)

    def send_many(self, frames, slice_size=64):
        """Send a burst of frames in order; the client keeps reading between slices of the burst."""
        frames = list(frames)

        async def write_all():
            for start in range(0, len(frames), slice_size):
                for data in frames[start:start + slice_size]:
                    self._write(data)
                await asyncio.sleep(0)
        self._loop.add_callback(write_all)

    def _write(self, data):
        try:
            self._conn.write_message(data, binary=isinstance(data, bytes))
        except tornado.websocket.WebSocketClosedError:
            pass

    def recv(self, timeout=REPLY_WAIT_S):
        """The next frame (str or bytes), CLOSED when the server closed; queue.Empty on timeout."""
        return self.frames.get(timeout=timeout)

    def recv_message(self, predicate=lambda m: True, timeout=REPLY_WAIT_S):
        """The next decoded message (JSON or CBOR) satisfying ``predicate``; others are skipped."""
        import time
        deadline = time.monotonic() + timeout
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise queue.Empty()
            frame = self.recv(remaining)
            if frame is CLOSED:
                raise ConnectionError("server closed the connection (code %s)" % self.close_code)
            message = cbor.loads(frame) if isinstance(frame, bytes) else json.loads(frame)
            if predicate(message):
                return message

    def close(self):
        def shut():
            self._conn.close()
            self._loop.call_later(0.2, self._loop.stop)
        if self._loop is not None and self._conn is not None:
            self._loop.add_callback(shut)
        self._thread.join(2.0)


class SocketClient(object):
    """A websocket client on a plain blocking socket that reads only when asked (or never).

    Models a slow or stuck backend: ``rcvbuf`` shrinks the kernel's receive buffer so the
    server's writes back up quickly. ``send(dict)`` sends one masked text frame (< 64 kB),
``send_many`` several in one write;
    ``frames()`` yields the server's frames as (opcode, payload) up to its close frame.
    """

    def __init__(self, port, rcvbuf=None):
        self.sock = socket.socket()
        if rcvbuf:
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        self.sock.settimeout(5.0)
        self.sock.connect(("127.0.0.1", port))
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall(("GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                           "Sec-WebSocket-Key: %s\r\nSec-WebSocket-Version: 13\r\n\r\n" % key).encode())
        self.buffer = b""
        while b"\r\n\r\n" not in self.buffer:
            self.buffer += self.sock.recv(1024)
        head, self.buffer = self.buffer.split(b"\r\n\r\n", 1)
        assert b"101" in head.split(b"\r\n")[0]

    def send(self, message):
        self.send_many([message])

    def send_many(self, messages):
        """Several frames in one socket write (the server finds them buffered together)."""
        data = b""
        for message in messages:
            payload = json.dumps(message).encode()
            mask = os.urandom(4)
            assert len(payload) <= 0xFFFF
            head = (struct.pack("!BB", 0x81, 0x80 | len(payload)) if len(payload) < 126
                    else struct.pack("!BBH", 0x81, 0x80 | 126, len(payload)))
            data += head + mask + bytes(
                b ^ mask[i % 4] for i, b in enumerate(payload))
        self.sock.sendall(data)

    def _take(self, n):
        while len(self.buffer) < n:
            chunk = self.sock.recv(65536)
            if not chunk:
                raise EOFError()
            self.buffer += chunk
        data, self.buffer = self.buffer[:n], self.buffer[n:]
        return data

    def frames(self):
        """(opcode, payload) of each server frame, up to and including a close frame."""
        while True:
            first, length = struct.unpack("!BB", self._take(2))
            if length == 126:
                length = struct.unpack("!H", self._take(2))[0]
            elif length == 127:
                length = struct.unpack("!Q", self._take(8))[0]
            opcode = first & 0x0F
            yield opcode, self._take(length)
            if opcode == 0x8:
                return
