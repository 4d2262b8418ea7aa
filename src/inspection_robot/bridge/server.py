"""Websocket transport of the bridge (tornado >= 6.0): connections, fair scheduling, budgets, keep-alive.

Each connection gets a protocol Session (made by ``make_session``) and a :class:`SendQueue`.

Fair scheduling: a burst read from one client never starves writing. Incoming frames are
handled ``READ_SLICE`` at a time, then the handler yields to the IOLoop once, so queued outgoing
frames (to this and every other client) and ROS callbacks run between slices. When a frame
published to ROS leaves that topic's rospy publisher queue at its high-water mark
(``Session.ros_backlogged``), the client's socket is not read until the queue drained: TCP
back-pressure slows the publisher instead of rospy dropping its oldest messages.

Send queues (see :class:`SendQueue`): without a subscription ``queue_length`` no topic message is
dropped until the client's queued bytes reach its ``budget`` (bytes). Past that, new topic
messages for the client are dropped and counted per topic; the client gets a rate-limited
``status`` warning naming topic and count (at most one per ``DROP_WARNING_PERIOD`` s), and a
client still over budget ``budget_grace`` s after it first went over is disconnected (1008).
Replies (service responses, status, requests) are never dropped but count against the budget.
Frames leave in batches of at most ``BATCH_BYTES``; the next batch waits until the socket took
the previous one, so the budget covers everything the bridge holds for the client. The socket
takes at most ``UNSENT_BYTES`` not yet sent (compat_tornado.limit_unsent): the rest waits here,
where a queue_length still replaces stale messages (a video client that stalls gets the newest
frame next, not the kernel's megabytes of old ones).

Keep-alive: every ``ping_interval`` s each client is pinged; one that sent nothing (no frame, no
pong) for ``ping_timeout`` s has its socket closed within the next second (checks run every
KEEPALIVE_TICK s), at once: no close handshake is awaited from a peer that is not answering.
A frame over ``max_message_size`` bytes closes the connection with 1009 and a readable reason.
Every close the bridge decides is logged with its reason. TLS when an ssl context is given.
:class:`LoopPoster` hands work from other threads to the event loop.

Limits before trust (issue #39): while a client has not authenticated (its Session says so) a frame
over ``preauth_bytes`` is refused from its header, before its payload is buffered, and a client
whose frames together pass ``preauth_bytes`` is closed (an auth message is a few hundred bytes);
the application's ``max_message_size`` applies once it authenticated. At most
``max_clients_per_address`` websocket clients per peer address (loopback included); one more is
closed at once with 1008. No HTTP request may carry a body over ``HTTP_BODY_BYTES``. At the
process's file-descriptor limit the listening socket refuses instead of spinning
(:class:`GuardedListener`). A closed connection's objects (tornado's handler, protocol and stream
refer to each other) hold its read buffer, up to ``max_message_size``, until Python's cycle
collector runs, which counts objects, not bytes: the server runs a collection at most every
``COLLECT_PERIOD`` s after clients left, then glibc's malloc_trim, so a departed client's memory
is returned to the system.
"""
import asyncio
import collections
import ctypes
import ctypes.util
import errno
import gc
import os
import re
import socket
import ssl
import time

import tornado.httpserver
import tornado.ioloop
import tornado.netutil
import tornado.web
import tornado.websocket
from tornado.iostream import StreamClosedError

from inspection_robot.bridge import compat_tornado
from inspection_robot.bridge.access import Peer, local_names, origin_allowed
from inspection_robot.bridge.compat_tornado import CLOSE_TOO_BIG
from inspection_robot.bridge.trace import NoTrace

KEEPALIVE_TICK = 1.0  # s between checks for silent or over-budget clients (pings go every ping_interval)
READ_SLICE = 32  # incoming frames handled before the reader yields to the IOLoop once
BATCH_BYTES = 1 << 20  # outgoing bytes handed to the socket per write (at least one message)
# bytes the kernel may hold unsent per client (TCP_NOTSENT_LOWAT); by default it takes up to 4 MB,
# which for a client that stopped reading would be a backlog of ~30 stale video frames the queue_length
# of its subscription can no longer replace
UNSENT_BYTES = 128 << 10
DROP_WARNING_PERIOD = 1.0  # s: at most one drop warning per client and period
REFUSAL_LOG_PERIOD = 10.0  # s: at most one logged origin refusal per period
BACKLOG_POLL = 0.001  # s between checks of a full rospy publisher queue while a client's reading is paused
CLOSE_POLICY = 1008  # websocket close codes (RFC 6455 7.4.1)
CLOSE_GOING_AWAY = 1001
HTTP_BODY_BYTES = 65536  # largest HTTP request body taken (the websocket and the console need none)
COLLECT_PERIOD = 1.0  # s: at most one cycle collection per period after clients left
ACCEPT_PAUSE = 0.5  # s the listening socket is not polled when even a spare descriptor is gone


def _malloc_trim():
    """glibc's malloc_trim(0) (gives the free pages of every malloc arena back to the system), or a
    no-op where the C library has none."""
    try:
        trim = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6").malloc_trim
    except (OSError, AttributeError):
        return lambda: None
    trim.argtypes = [ctypes.c_size_t]
    return lambda: trim(0)


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


def _size(frames):
    return sum(len(frame) for frame in frames)


class SendQueue(object):
    """Outgoing messages (each a list of frames) of one client, bounded by a byte budget.

    ``put(frames, key, limit, droppable)``: replies (``droppable=False``) are always queued and sent
    first. A topic message (``key`` = topic) with a ``limit`` (the subscription's queue_length)
    keeps only the newest ``limit`` messages of that key waiting, as rosbridge's queue_length does
    (``limit_dropped`` counts those). Otherwise a topic message is refused only when the bytes
    held for the client (queued plus handed to the socket and not yet written) would pass
    ``budget``: it is then counted in ``dropped[key]`` and put() returns False. A message larger
    than the whole budget still goes when nothing else is held. ``over_since`` is the clock time
    the client went over budget (None while under it).
    """

    def __init__(self, budget, clock=time.monotonic):
        self.budget = max(1, int(budget))
        self._clock = clock
        self._replies = collections.deque()  # (frames, size)
        self._topics = collections.deque()   # entries: [frames, key, alive, size]
        self._by_key = {}                    # key -> deque of entries (keys with a limit only)
        self._alive = 0
        self.queued_bytes = 0
        self.in_flight = 0
        self.dropped = collections.Counter()  # key -> topic messages refused over budget
        self.limit_dropped = 0                # topic messages replaced under their queue_length
        self.discarded = 0                    # topic messages still queued when the client was closed
        self.over_since = None

    def __len__(self):
        return len(self._replies) + self._alive

    @property
    def held_bytes(self):
        return self.queued_bytes + self.in_flight

    def put(self, frames, key=None, limit=None, droppable=True):
        """Queue one message; False when a topic message was refused (over budget)."""
        size = _size(frames)
        if not droppable:
            self._replies.append((frames, size))
            self.queued_bytes += size
            self._check_budget()
            return True
        if self.held_bytes + size > self.budget and self.held_bytes > 0 and not limit:
            self.dropped[key] += 1
            if self.over_since is None:
                self.over_since = self._clock()
            return False
        entry = [frames, key, True, size]
        self._topics.append(entry)
        self._alive += 1
        self.queued_bytes += size
        if key is not None and limit:
            per_key = self._by_key.get(key)
            if per_key is None:
                per_key = self._by_key[key] = collections.deque()
            per_key.append(entry)
            self._trim(key, per_key)
            while len(per_key) > limit:
                self._kill(per_key.popleft())
                self.limit_dropped += 1
            self._prune()
        self._check_budget()
        return True

    def _check_budget(self):
        if self.held_bytes > self.budget:
            if self.over_since is None:
                self.over_since = self._clock()
        elif not self.dropped or self.held_bytes < self.budget // 2:
            # under budget again: after drops only once half of it is free, so a client hovering
            # at the edge is not told "recovered" for each message
            self.over_since = None

    def _kill(self, entry):
        if entry[2]:
            entry[2] = False
            self._alive -= 1
            self.queued_bytes -= entry[3]

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
        """The next message's frames (replies first), or None when empty; its bytes go in flight."""
        if self._replies:
            frames, size = self._replies.popleft()
        else:
            self._prune()
            if not self._topics:
                return None
            entry = self._topics.popleft()
            frames, size = entry[0], entry[3]
            entry[2] = False
            self._alive -= 1
            if self._by_key and entry[1] in self._by_key:
                self._trim(entry[1], self._by_key[entry[1]])
        self.queued_bytes -= size
        self.in_flight += size
        return frames

    def take_replies(self):
        """Every queued reply's frames, removed from the queue (sent ahead of a close)."""
        frames = []
        while self._replies:
            reply, size = self._replies.popleft()
            frames.extend(reply)
            self.queued_bytes -= size
        return frames

    def discard_topics(self):
        """Drop every topic message still queued (the client is being closed); returns how many.
        ``discarded`` counts them; the close reason tells them with the refused ones."""
        count = self._alive
        for entry in self._topics:
            self._kill(entry)
        self._topics.clear()
        self._by_key.clear()
        self.discarded += count
        return count

    def written(self, size):
        """``size`` bytes handed out by pop() have been written to the socket."""
        self.in_flight -= size
        self._check_budget()


class BridgeHandler(tornado.websocket.WebSocketHandler):
    """One websocket client; configuration comes from its BridgeServer (``initialize``)."""

    def initialize(self, server):
        self._server = server
        self._trace = server.trace
        self.queue = SendQueue(server.budget)
        self._writing = False
        self._closing = False
        self._unread = 0
        self._drops_untold = collections.Counter()
        self._warning_timer = None
        self.close_reason_sent = None
        self.session = None
        self.last_heard = time.monotonic()
        self.preauth_left = None  # bytes an unauthenticated client may still send (None: authenticated)

    def check_origin(self, origin):
        # only browsers send an Origin (tornado lets clients without one through): a page from another
        # site must not use the operator's browser, on the robot's network, to drive the robot
        if self._server.origin_allowed(origin, self.request.host, self.request.protocol):
            return True
        self._server.origin_refused(self.request.remote_ip, origin)
        return False

    def get_compression_options(self):
        return None  # permessage-deflate costs more CPU than it saves on a local link

    def get_websocket_protocol(self):
        # tornado closes an oversized frame's connection itself, with the terse "message too big":
        # give the client a reason naming the limit, and remember it so the bridge can log it
        # (how is tornado-internal: compat_tornado.name_the_size_limit)
        return compat_tornado.name_the_size_limit(super(BridgeHandler, self).get_websocket_protocol(),
                                                  self._too_big_reason)

    def _too_big_reason(self):
        if self.close_reason_sent is not None:
            return None
        if self.preauth_left is not None:
            reason = ("message too big: a frame over %d bytes before authenticating (~preauth_bytes)"
                      % self._server.preauth_bytes)
        else:
            reason = "message too big: a frame over max_message_size (%d bytes)" % self._server.max_message_size
        self.close_reason_sent = (CLOSE_TOO_BIG, reason)
        return reason

    @property
    def client_id(self):
        return self.session.client_id if self.session is not None else "?"

    def open(self):
        self.set_nodelay(True)
        compat_tornado.limit_unsent(self, UNSENT_BYTES)
        if not self._server.admit(self):
            return
        self.session = self._server.opened(self)
        if not self.session.authenticated:
            # before the first frame is read: until it authenticates, the client's frames stay small
            self.preauth_left = self._server.preauth_bytes
            compat_tornado.set_frame_limit(self, self._server.preauth_bytes)

    def on_message(self, message):
        if self._trace.on:
            self._trace.mark("read")
        self.last_heard = time.monotonic()
        if self.session is None or self.close_reason_sent is not None:
            return None
        if self.preauth_left is not None:
            self.preauth_left -= len(message)
            if self.preauth_left < 0:
                self.close_with(CLOSE_POLICY, "more than %d bytes before authenticating (~preauth_bytes)"
                                % self._server.preauth_bytes)
                return None
            self.session.on_frame(message)
            if self.session.authenticated:
                self.preauth_left = None
                compat_tornado.set_frame_limit(self, self._server.max_message_size)
            return None
        self.session.on_frame(message)
        if self.session.ros_backlogged():
            self._unread = 0
            return self._wait_for_ros()
        self._unread += 1
        if self._unread >= READ_SLICE:
            # tornado reads the next buffered frame without returning to the IOLoop; awaiting
            # here lets queued writes and ROS callbacks run between slices of a burst
            self._unread = 0
            return asyncio.sleep(0)
        return None

    async def _wait_for_ros(self):
        # not reading the socket while rospy's queue is full: TCP slows the client down
        while self.session.ros_backlogged() and self.ws_connection is not None:
            await asyncio.sleep(BACKLOG_POLL)

    def on_pong(self, data):
        self.last_heard = time.monotonic()

    def abort(self):
        """Close the socket now, without a close handshake (the peer is not answering)."""
        compat_tornado.abort(self)

    def close_with(self, code, reason):
        """Close with a reason the client can read; replies still queued (status) go out first."""
        if self.close_reason_sent is not None:
            return
        self.close_reason_sent = (code, reason)
        self._closing = True
        replies = self.queue.take_replies()
        if replies:
            try:
                compat_tornado.write_frames(self, replies)
            except (tornado.websocket.WebSocketClosedError, StreamClosedError):
                pass
        self.close(code, reason)

    def on_close(self):
        if self._warning_timer is not None:
            tornado.ioloop.IOLoop.current().remove_timeout(self._warning_timer)
            self._warning_timer = None
        self._server.closed(self)

    def send(self, frames, key=None, limit=None, droppable=True):
        if self._closing or self.ws_connection is None:
            return
        if not self.queue.put(frames, key, limit, droppable):
            self._dropped(key)
            return
        if not droppable and self.queue.held_bytes > 2 * self.queue.budget:
            # replies are never dropped; a client that lets twice its budget of them pile up goes now
            self._server.over_budget(self)
            return
        if not self._writing:
            self._writing = True
            tornado.ioloop.IOLoop.current().add_callback(self._flush)

    def _dropped(self, topic):
        self._server.dropped(self, topic)
        self._drops_untold[topic] += 1
        if self._warning_timer is None:
            self._tell_drops()

    def _tell_drops(self):
        # one warning now, then at most one per period while drops continue
        self._warning_timer = None
        if not self._drops_untold or self.session is None or self._closing:
            return
        for topic, count in sorted(self._drops_untold.items()):
            self.session.drops(topic, count, self.queue.dropped[topic], self.queue.budget)
        self._drops_untold.clear()
        self._warning_timer = tornado.ioloop.IOLoop.current().call_later(DROP_WARNING_PERIOD, self._tell_drops)

    def close_after_flush(self):
        self._closing = True
        if not self._writing:
            self.close()

    def _flush(self):
        # Runs on the loop once per pass after send(): what was queued meanwhile goes out in writes
        # of up to BATCH_BYTES, written to the socket at once (tornado tries the send right away).
        # Only when the socket did not take a batch does the next one wait for it (_written), so the
        # bytes held in tornado's buffer stay within the budget. No coroutine: its first step would
        # cost one more loop pass per write, which is most of an echo's time in the bridge.
        try:
            while True:
                batch = self._next_batch()
                if batch is None:
                    break
                future, size = batch
                if not future.done():
                    tornado.ioloop.IOLoop.current().add_future(future, lambda done: self._written(done, size))
                    return
                self._written(future, size, then_flush=False)
        except (tornado.websocket.WebSocketClosedError, StreamClosedError):
            pass
        self._done_writing()

    def _done_writing(self):
        self._writing = False
        if self._closing and self.close_reason_sent is None:
            self.close()

    def _next_batch(self):
        """Hand the next queued frames (up to BATCH_BYTES) to the socket: (write future, bytes) or None."""
        payloads, size = [], 0
        frames = self.queue.pop()
        while frames is not None:
            payloads.extend(frames)
            size += _size(frames)
            if size >= BATCH_BYTES:
                break
            frames = self.queue.pop()
        if not payloads:
            return None
        try:
            future = compat_tornado.write_frames(self, payloads)
            if self._trace.on:
                self._trace.mark("written")
            return future, size
        except (tornado.websocket.WebSocketClosedError, StreamClosedError):
            self.queue.written(size)
            raise

    def _written(self, future, size, then_flush=True):
        self.queue.written(size)
        try:
            future.result()
        except (tornado.websocket.WebSocketClosedError, StreamClosedError):
            if then_flush:
                self._done_writing()
                return
            raise
        if then_flush:
            self._flush()


class _Timer(object):
    def __init__(self, loop, handle):
        self._loop = loop
        self._handle = handle

    def cancel(self):
        self._loop.remove_timeout(self._handle)


class BridgeServer(object):
    """Listens on ``address:port`` (0 = any free port) and runs one Session per client.

    ``make_session(client_id, send, call_later, close, peer)`` returns a protocol Session (``peer``:
    access.Peer). ``allowed_origins``: browser origins accepted besides the console's own.
    ``handshake_timeout``: s for a connection's TLS and HTTP handshake (and any request body).
    ``on_client_count(n)`` is called on every connect/disconnect. ``budget`` (bytes) and
    ``budget_grace`` (s) bound each client's send queue (module docstring). Must be started on the
    thread that runs the tornado IOLoop. :meth:`stats` feeds the node's diagnostics.
    ``extra_routes``: further tornado routes (pattern, handler, kwargs) matched before the websocket;
    ``websocket_paths``: exact paths that are the websocket even inside extra_routes (the console's link).
    ``preauth_bytes``: what an unauthenticated client may send, per frame and in all;
    ``max_clients_per_address``: websocket clients per peer address (module docstring).
    ``trace``: a bridge/trace.py tracer stamping each echo's read and written stages (None: off).
    """

    def __init__(self, make_session, address="127.0.0.1", port=9090, ssl_context=None, ping_interval=10.0,
                 ping_timeout=30.0, max_message_size=10000000, budget=64 << 20, budget_grace=5.0,
                 on_client_count=None, log=None, extra_routes=(), allowed_origins=(), handshake_timeout=10.0,
                 preauth_bytes=16384, max_clients_per_address=32, websocket_paths=(), trace=None):
        self._make_session = make_session
        self.trace = trace or NoTrace()
        self.preauth_bytes = int(preauth_bytes)
        self.max_clients_per_address = int(max_clients_per_address)
        self._per_address = collections.Counter()  # peer address -> open websocket clients
        self.address_refused = 0
        self._address_log_after = 0.0
        self.accept_refused = 0
        self._accept_log_after = 0.0
        self._collect_pending = False
        self._last_collect = 0.0
        self._trim = _malloc_trim()
        self._handshake_timeout = float(handshake_timeout)
        self._allowed_origins = tuple(allowed_origins)
        self._local_names = local_names()
        self.origins_refused = 0
        self._origin_log_after = 0.0
        self._address = address
        self._port = int(port)
        self._ssl = ssl_context
        self._ping_interval = float(ping_interval)
        self._ping_timeout = float(ping_timeout)
        self.max_message_size = int(max_message_size)
        self.budget = int(budget)
        self.budget_grace = float(budget_grace)
        self._on_count = on_client_count or (lambda n: None)
        self._extra_routes = list(extra_routes)
        self._websocket_paths = list(websocket_paths)  # websocket paths matched before extra_routes
        self.log = log or (lambda level, text: None)
        self._clients = set()
        self._next_id = 0
        self._http = None
        self._pinger = None
        self._last_ping = 0.0
        self.port = None
        self.dropped_by_topic = collections.Counter()  # topic -> messages dropped over budget, all clients
        self.closed_over_budget = 0

    def routes(self):
        """The HTTP application's routes: any extra ones first, the websocket on every other path."""
        websocket = {"server": self}
        return ([(re.escape(path), BridgeHandler, websocket) for path in self._websocket_paths] + self._extra_routes
                + [(r"/.*", BridgeHandler, websocket)])

    def start(self):
        """Bind and listen; returns the actual port."""
        tick = min(self._ping_interval, KEEPALIVE_TICK) if self._ping_interval > 0 else KEEPALIVE_TICK
        self._pinger = tornado.ioloop.PeriodicCallback(self._keep_alive, tick * 1000.0)
        self._pinger.start()
        app = tornado.web.Application(self.routes(), websocket_max_message_size=self.max_message_size)
        sockets = [GuardedListener.wrap(sock, self._accept_refused)
                   for sock in tornado.netutil.bind_sockets(self._port, self._address or None)]
        # a handshake (TLS and HTTP headers) or request body that takes longer is dropped: slow-loris
        # clients cannot pile up half-open connections
        self._http = tornado.httpserver.HTTPServer(app, ssl_options=self._ssl,
                                                   max_buffer_size=self.max_message_size + 65536,
                                                   max_body_size=HTTP_BODY_BYTES,
                                                   idle_connection_timeout=self._handshake_timeout,
                                                   body_timeout=self._handshake_timeout)
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
            handler.close_with(CLOSE_GOING_AWAY, "bridge shutting down")

    def _keep_alive(self):
        now = time.monotonic()
        ping = self._ping_interval > 0 and now - self._last_ping >= self._ping_interval - 1e-3
        if ping:
            self._last_ping = now
        for handler in list(self._clients):
            since = handler.queue.over_since
            if since is not None and now - since >= self.budget_grace:
                self.over_budget(handler)
                continue
            if self._ping_interval <= 0:
                continue
            if now - handler.last_heard > self._ping_timeout:
                self.log("warning", "client %s silent for %.1f s; dropping it" % (handler.client_id,
                                                                                  now - handler.last_heard))
                handler.abort()
                continue
            if not ping:
                continue
            try:
                handler.ping(b"")
            except (tornado.websocket.WebSocketClosedError, StreamClosedError):
                pass

    def over_budget(self, handler):
        """Disconnect a client whose send queue stayed over its budget (or replies overflowed it)."""
        if handler.close_reason_sent is not None:
            return
        self.closed_over_budget += 1
        # what is still queued will never be written: told in the same count as the refused ones.
        # Messages in flight (handed to the socket) go out ahead of the close frame.
        dropped = handler.queue.discard_topics() + sum(handler.queue.dropped.values())
        handler.close_with(CLOSE_POLICY, "send queue over budget (%d bytes) for %g s: client reads too slowly; "
                           "%d messages dropped" % (self.budget, self.budget_grace, dropped))

    def origin_allowed(self, origin, host, scheme):
        return origin_allowed(origin, host, scheme, self._allowed_origins, self._local_names)

    def origin_refused(self, address, origin):
        """Log a refused browser origin; at most one line per REFUSAL_LOG_PERIOD s (a page may retry in a loop)."""
        self.origins_refused += 1
        now = time.monotonic()
        if now < self._origin_log_after:
            return
        self._origin_log_after = now + REFUSAL_LOG_PERIOD
        self.log("warning", "refused a browser connection from %s: origin %s is neither the console's nor in "
                 "~allowed_origins (%d refused so far)" % (address, origin[:200], self.origins_refused))

    def _accept_refused(self):
        """The listening socket refused a connection at the file-descriptor limit (GuardedListener)."""
        self.accept_refused += 1
        now = time.monotonic()
        if now < self._accept_log_after:
            return
        self._accept_log_after = now + REFUSAL_LOG_PERIOD
        self.log("warning", "refusing connections: the process is at its file-descriptor limit (RLIMIT_NOFILE; "
                 "systemd LimitNOFILE) with %d clients (%d refused so far)"
                 % (len(self._clients), self.accept_refused))

    def admit(self, handler):
        """False (and the connection closed with 1008) when its address has max_clients_per_address open."""
        address = handler.request.remote_ip
        if self._per_address[address] < self.max_clients_per_address:
            return True
        self.address_refused += 1
        handler.close_with(CLOSE_POLICY, "too many connections from %s (max %d: ~max_clients_per_address)"
                           % (address, self.max_clients_per_address))
        now = time.monotonic()
        if now >= self._address_log_after:
            self._address_log_after = now + REFUSAL_LOG_PERIOD
            self.log("warning", "refused a connection from %s: it has %d open (~max_clients_per_address; %d "
                     "refused so far)" % (address, self._per_address[address], self.address_refused))
        return False

    def _collect_soon(self):
        # a departed client's buffers are in reference cycles (module docstring): collect them, at
        # most once per COLLECT_PERIOD however many clients leave
        if self._collect_pending:
            return
        self._collect_pending = True
        wait = max(0.0, self._last_collect + COLLECT_PERIOD - time.monotonic())
        tornado.ioloop.IOLoop.current().call_later(wait, self._collect)

    def _collect(self):
        self._collect_pending = False
        self._last_collect = time.monotonic()
        gc.collect()
        # the event loop's thread allocates from its own malloc arena, which keeps freed buffers
        # (the bench's 9.9 MB unfinished frames: +45 % of the bridge's start-up RSS without this)
        self._trim()

    @property
    def client_count(self):
        return len(self._clients)

    def opened(self, handler):
        self._next_id += 1
        loop = tornado.ioloop.IOLoop.current()
        session = self._make_session(
            self._next_id, handler.send,
            lambda delay, fn: _Timer(loop, loop.call_later(delay, fn)),
            handler.close_after_flush, Peer(handler.request.remote_ip, handler.request.protocol == "https",
                                            handler.request.path))
        self._clients.add(handler)
        self._per_address[handler.request.remote_ip] += 1
        self.log("info", "client %d connected from %s (%d clients)"
                 % (self._next_id, handler.request.remote_ip, len(self._clients)))
        self._on_count(len(self._clients))
        return session

    def closed(self, handler):
        self._collect_soon()
        if handler not in self._clients:
            return
        self._clients.discard(handler)
        address = handler.request.remote_ip
        self._per_address[address] -= 1
        if self._per_address[address] <= 0:
            del self._per_address[address]
        if handler.session is not None:
            handler.session.close()
        if handler.close_reason_sent is not None:
            why = "closed by the bridge (%d %s)" % handler.close_reason_sent
            self.log("warning", "client %s %s (%d clients)" % (handler.client_id, why, len(self._clients)))
        else:
            why = "disconnected" if handler.close_code is None else "disconnected (%s %s)" % (
                handler.close_code, handler.close_reason or "")
            self.log("info", "client %s %s (%d clients)" % (handler.client_id, why.rstrip(), len(self._clients)))
        self._on_count(len(self._clients))

    def dropped(self, handler, topic):
        self.dropped_by_topic[topic] += 1

    def stats(self):
        """Per-client send queue figures and drop counters for diagnostics (event-loop thread)."""
        clients = []
        for handler in sorted(self._clients, key=lambda h: str(h.client_id)):
            queue = handler.queue
            clients.append({"client": handler.client_id, "held_bytes": queue.held_bytes, "messages": len(queue),
                            "dropped": sum(queue.dropped.values()), "queue_length_dropped": queue.limit_dropped,
                            "over_budget": queue.over_since is not None})
        return {"clients": clients, "dropped_by_topic": dict(self.dropped_by_topic),
                "closed_over_budget": self.closed_over_budget, "budget": self.budget,
                "origins_refused": self.origins_refused, "address_refused": self.address_refused,
                "accept_refused": self.accept_refused}


class GuardedListener(socket.socket):
    """A listening socket whose accept() refuses connections at the file-descriptor limit instead of failing.

    tornado's accept loop catches only BlockingIOError: an EMFILE / ENFILE went up to the event
    loop as a traceback, and the socket, still readable, was polled again at once (a busy loop at
    94 % CPU, ~5 MB/s of tracebacks). Here the error becomes a refusal: a spare descriptor is given
    up for a moment to accept the waiting connection and close it at once (the client sees the
    connection closed, not a hang), then BlockingIOError ends tornado's loop for this pass. Should
    even the spare be gone, the socket is not polled for ACCEPT_PAUSE s (IOLoop.update_handler).
    ``on_refused()`` is called for every refusal. Public APIs only (socket, IOLoop).
    """

    @classmethod
    def wrap(cls, sock, on_refused):
        listener = cls(sock.family, sock.type, sock.proto, fileno=sock.detach())
        listener.setblocking(False)
        listener.guard(on_refused)
        return listener

    def guard(self, on_refused):
        """Keep the spare descriptor and call ``on_refused()`` for every refusal from now on."""
        self._on_refused = on_refused
        self._spare = None
        self._reserve()

    def _reserve(self):
        try:
            self._spare = os.open(os.devnull, os.O_RDONLY)
        except OSError:
            self._spare = None

    def accept(self):
        try:
            return super(GuardedListener, self).accept()
        except OSError as exc:
            if exc.errno not in (errno.EMFILE, errno.ENFILE):
                raise
        self._on_refused()
        if self._spare is not None:
            os.close(self._spare)
            self._spare = None
            try:
                conn, _address = super(GuardedListener, self).accept()
                conn.close()
            except OSError:
                pass
            self._reserve()
        if self._spare is None:
            loop = tornado.ioloop.IOLoop.current()
            loop.update_handler(self, 0)
            loop.call_later(ACCEPT_PAUSE, self._resume)
        raise BlockingIOError(errno.EAGAIN, "connection refused at the file-descriptor limit")

    def _resume(self):
        if self.fileno() >= 0:
            if self._spare is None:
                self._reserve()
            tornado.ioloop.IOLoop.current().update_handler(self, tornado.ioloop.IOLoop.READ)

    def close(self):
        if getattr(self, "_spare", None) is not None:
            os.close(self._spare)
            self._spare = None
        super(GuardedListener, self).close()


def make_ssl_context(certfile, keyfile):
    """A server TLS context from PEM files (TLS 1.2+)."""
    context = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
    context.minimum_version = ssl.TLSVersion.TLSv1_2
    context.load_cert_chain(certfile, keyfile or None)
    return context
