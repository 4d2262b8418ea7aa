"""Websocket transport of the bridge (tornado >= 6.0): connections, keep-alive, bounded send queues.

Each connection gets a protocol Session (made by ``make_session``) and a :class:`SendQueue`.
Topic messages are droppable: past ``send_queue_size`` waiting messages the oldest is dropped,
and a subscription's ``queue_length`` bounds its own waiting messages, so a slow client loses
old data instead of stalling others or growing memory. Replies (service responses, status,
requests) are never dropped; a client that lets more than ``send_queue_size`` of them pile up is
disconnected. Frames leave in batches: everything queued when the writer runs is framed and
handed to the socket in one write, and the writer waits for the socket only once per batch.
Keep-alive: every ``ping_interval`` s each client is pinged; one that sent nothing (no frame, no
pong) for ``ping_timeout`` s has its socket closed within the next second (checks run every
KEEPALIVE_TICK s), at once: no close handshake is awaited from a peer that is not answering.
Frames over ``max_message_size`` bytes close the connection (1009). TLS when an ssl context is
given. :class:`LoopPoster` hands work from other threads to the event loop.
"""
import collections
import ssl
import struct
import time

import tornado.httpserver
import tornado.ioloop
import tornado.netutil
import tornado.web
import tornado.websocket
from tornado.iostream import StreamClosedError

KEEPALIVE_TICK = 1.0  # s between checks for silent clients (pings go out every ping_interval)


class LoopPoster(object):
    """``post(fn, *args)`` from any thread runs ``fn(*args)`` on the loop, in posting order.

    One ``add_callback`` (a wake-up of the loop) per burst instead of one per call: a callback
    is scheduled only when none is pending, and it runs what was queued when it started. Lock-free:
    the flag is cleared before the queue is read, so an item posted meanwhile is either run by
    this pass or schedules the next one.
    """

    def __init__(self, loop, log=None):
        self._loop = loop
        self._items = collections.deque()
        self._scheduled = False
        self._log = log or (lambda level, text: None)

    def post(self, fn, *args):
        self._items.append((fn, args))
        if not self._scheduled:
            self._scheduled = True
            self._loop.add_callback(self._run)

    def _run(self):
        self._scheduled = False
        items = self._items
        for _ in range(len(items)):
            fn, args = items.popleft()
            try:
                fn(*args)
            except Exception as exc:  # boundary: one failing callback must not drop the others
                self._log("error", "callback %r failed: %r" % (fn, exc))


def ws_frame(payload):
    """An unmasked, final websocket frame: text for str, binary for bytes (RFC 6455 5.2)."""
    if isinstance(payload, str):
        payload = payload.encode("utf-8")
        first = 0x81
    else:
        first = 0x82
    size = len(payload)
    if size < 126:
        header = struct.pack("!BB", first, size)
    elif size <= 0xFFFF:
        header = struct.pack("!BBH", first, 126, size)
    else:
        header = struct.pack("!BBQ", first, 127, size)
    return header + payload


class SendQueue(object):
    """Outgoing messages (each a list of frames) of one client; see the module docstring."""

    def __init__(self, max_messages):
        self.max_messages = max(1, int(max_messages))
        self._replies = collections.deque()
        self._topics = collections.deque()   # entries: [frames, key, alive]
        self._by_key = {}                    # key -> deque of entries
        self._alive = 0
        self.dropped = 0

    def __len__(self):
        return len(self._replies) + self._alive

    def put(self, frames, key=None, limit=None, droppable=True):
        """Queue one message; False when undroppable replies overflow (the client must go)."""
        if not droppable:
            self._replies.append(frames)
            return len(self._replies) <= self.max_messages
        entry = [frames, key, True]
        self._topics.append(entry)
        self._alive += 1
        if key is not None and limit:
            per_key = self._by_key.get(key)
            if per_key is None:
                per_key = self._by_key[key] = collections.deque()
            per_key.append(entry)
            self._trim(key, per_key)
            while len(per_key) > limit:
                self._kill(per_key.popleft())
        if self._alive > self.max_messages:
            while self._alive > self.max_messages:
                self._prune()
                self._kill(self._topics[0])
            self._prune()
        return True

    def _kill(self, entry):
        if entry[2]:
            entry[2] = False
            self._alive -= 1
            self.dropped += 1

    def _trim(self, key, per_key):
        # dead entries of a key are always its oldest ones: drop that prefix
        while per_key and not per_key[0][2]:
            per_key.popleft()
        if not per_key:
            del self._by_key[key]

    def _prune(self):
        while self._topics and not self._topics[0][2]:
            self._topics.popleft()

    def pop(self):
        """The next message's frames (replies first), or None when empty."""
        if self._replies:
            return self._replies.popleft()
        self._prune()
        if not self._topics:
            return None
        entry = self._topics.popleft()
        entry[2] = False
        self._alive -= 1
        if self._by_key and entry[1] in self._by_key:
            self._trim(entry[1], self._by_key[entry[1]])
        return entry[0]


class BridgeHandler(tornado.websocket.WebSocketHandler):
    """One websocket client; configuration comes from its BridgeServer (``initialize``)."""

    def initialize(self, server):
        self._server = server
        self._queue = SendQueue(server.send_queue_size)
        self._writing = False
        self._closing = False
        self.session = None
        self.last_heard = time.monotonic()

    def check_origin(self, origin):
        return True  # as rosbridge: any origin; restrict with the address/auth parameters

    def get_compression_options(self):
        return None  # permessage-deflate costs more CPU than it saves on a local link

    def open(self):
        self.set_nodelay(True)
        self.session = self._server.opened(self)

    def on_message(self, message):
        self.last_heard = time.monotonic()
        if self.session is not None:
            self.session.on_frame(message)

    def on_pong(self, data):
        self.last_heard = time.monotonic()

    def abort(self):
        """Close the socket now, without a close handshake (the peer is not answering)."""
        connection = self.ws_connection
        if connection is not None and getattr(connection, "stream", None) is not None:
            connection.stream.close()
        else:
            self.close()

    def on_close(self):
        self._server.closed(self)

    def send(self, frames, key=None, limit=None, droppable=True):
        if self._closing or self.ws_connection is None:
            return
        before = self._queue.dropped
        if not self._queue.put(frames, key, limit, droppable):
            self._server.log("warning", "client %s: %d replies waiting; disconnecting"
                             % (self.session.client_id, len(self._queue)))
            self._closing = True
            self.close(1008, "send queue overflow")
            return
        if self._queue.dropped != before:
            self._server.dropped(self)
        if not self._writing:
            self._writing = True
            tornado.ioloop.IOLoop.current().add_callback(self._drain)

    def close_after_flush(self):
        self._closing = True
        if not self._writing:
            self.close()

    async def _drain(self):
        # Everything queued now goes out in one stream write; the next batch waits until the socket
        # took this one, so at most one queue's worth sits in tornado's buffer.
        try:
            while True:
                chunks = []
                frames = self._queue.pop()
                while frames is not None:
                    chunks.extend(ws_frame(frame) for frame in frames)
                    frames = self._queue.pop()
                if not chunks:
                    break
                future = self._write_raw(b"".join(chunks) if len(chunks) > 1 else chunks[0])
                if not future.done():
                    await future
        except (tornado.websocket.WebSocketClosedError, StreamClosedError):
            pass
        finally:
            self._writing = False
        if self._closing:
            self.close()

    def _write_raw(self, data):
        connection = self.ws_connection
        if connection is None or connection.is_closing():
            raise tornado.websocket.WebSocketClosedError()
        return connection.stream.write(data)


class _Timer(object):
    def __init__(self, loop, handle):
        self._loop = loop
        self._handle = handle

    def cancel(self):
        self._loop.remove_timeout(self._handle)


class BridgeServer(object):
    """Listens on ``address:port`` (0 = any free port) and runs one Session per client.

    ``http_routes`` (tornado rules) are matched before the websocket, which takes every other path.

    ``make_session(client_id, send, call_later, close)`` returns a protocol Session.
    ``on_client_count(n)`` is called on every connect/disconnect. Must be started on the thread
    that runs the tornado IOLoop.
    """

    def __init__(self, make_session, address="127.0.0.1", port=9090, ssl_context=None, ping_interval=10.0,
                 ping_timeout=30.0, max_message_size=10000000, send_queue_size=1000, on_client_count=None,
                 log=None, http_routes=()):
        self._make_session = make_session
        self._http_routes = list(http_routes)
        self._address = address
        self._port = int(port)
        self._ssl = ssl_context
        self._ping_interval = float(ping_interval)
        self._ping_timeout = float(ping_timeout)
        self._max_message_size = int(max_message_size)
        self.send_queue_size = int(send_queue_size)
        self._on_count = on_client_count or (lambda n: None)
        self.log = log or (lambda level, text: None)
        self._clients = set()
        self._next_id = 0
        self._http = None
        self._pinger = None
        self._last_ping = 0.0
        self.port = None
        self.dropped_messages = 0

    def start(self):
        """Bind and listen; returns the actual port."""
        settings = {"websocket_max_message_size": self._max_message_size}
        if self._ping_interval > 0:
            tick = min(self._ping_interval, KEEPALIVE_TICK)
            self._pinger = tornado.ioloop.PeriodicCallback(self._keep_alive, tick * 1000.0)
            self._pinger.start()
        # Plain HTTP routes (the console's static files) first; every other path is the websocket.
        app = tornado.web.Application(self._http_routes + [(r"/.*", BridgeHandler, {"server": self})], **settings)
        sockets = tornado.netutil.bind_sockets(self._port, self._address or None)
        self._http = tornado.httpserver.HTTPServer(app, ssl_options=self._ssl, max_buffer_size=self._max_message_size
                                                   + 65536)
        self._http.add_sockets(sockets)
        self.port = sockets[0].getsockname()[1]
        self._on_count(0)
        return self.port

    def stop(self):
        if self._pinger is not None:
            self._pinger.stop()
        if self._http is not None:
            self._http.stop()
        for handler in list(self._clients):
            handler.close(1001, "bridge shutting down")

    def _keep_alive(self):
        now = time.monotonic()
        ping = now - self._last_ping >= self._ping_interval - 1e-3
        if ping:
            self._last_ping = now
        for handler in list(self._clients):
            if now - handler.last_heard > self._ping_timeout:
                self.log("warning", "client %s silent for %.1f s; dropping it"
                         % (handler.session.client_id if handler.session else "?", now - handler.last_heard))
                handler.abort()
                continue
            if not ping:
                continue
            try:
                handler.ping(b"")
            except (tornado.websocket.WebSocketClosedError, StreamClosedError):
                pass

    @property
    def client_count(self):
        return len(self._clients)

    def opened(self, handler):
        self._next_id += 1
        loop = tornado.ioloop.IOLoop.current()
        session = self._make_session(
            self._next_id, handler.send,
            lambda delay, fn: _Timer(loop, loop.call_later(delay, fn)),
            handler.close_after_flush)
        self._clients.add(handler)
        self.log("info", "client %d connected from %s (%d clients)"
                 % (self._next_id, handler.request.remote_ip, len(self._clients)))
        self._on_count(len(self._clients))
        return session

    def closed(self, handler):
        if handler not in self._clients:
            return
        self._clients.discard(handler)
        if handler.session is not None:
            handler.session.close()
            self.log("info", "client %s disconnected (%d clients)" % (handler.session.client_id, len(self._clients)))
        self._on_count(len(self._clients))

    def dropped(self, handler):
        self.dropped_messages += 1


def make_ssl_context(certfile, keyfile):
    """A server TLS context from PEM files (TLS 1.2+)."""
    context = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
    context.minimum_version = ssl.TLSVersion.TLSv1_2
    context.load_cert_chain(certfile, keyfile or None)
    return context
