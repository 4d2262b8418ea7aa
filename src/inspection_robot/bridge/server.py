"""Websocket transport of the bridge (tornado >= 6.0): connections, fair scheduling, budgets, keep-alive.

Each connection is a handler.BridgeHandler (reading, writing, closing) with a protocol Session
(made by ``make_session``) and a send_queue.SendQueue; this module listens, admits, keeps clients
alive, collects after them and counts for diagnostics.

Fair scheduling: a burst read from one client never starves writing. Incoming frames are
handled ``READ_SLICE`` at a time, then the handler yields to the IOLoop once, so queued outgoing
frames (to this and every other client) and ROS callbacks run between slices. When a frame
published to ROS leaves that topic's rospy publisher queue at its high-water mark
(``Session.ros_backlogged``), the client's socket is not read until the queue drained: TCP
back-pressure slows the publisher instead of rospy dropping its oldest messages.

Send queues (see send_queue.SendQueue): without a subscription ``queue_length`` no topic message is
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
(listener.GuardedListener). A closed connection's objects (tornado's handler, protocol and stream
refer to each other) hold its read buffer, up to ``max_message_size``, until Python's cycle
collector runs, which counts objects, not bytes: the server runs a collection at most every
``COLLECT_PERIOD`` s after clients left, then glibc's malloc_trim, so a departed client's memory
is returned to the system.
"""
import collections
import ctypes
import ctypes.util
import gc
import re
import ssl
import time

import tornado.httpserver
import tornado.ioloop
import tornado.netutil
import tornado.web
import tornado.websocket
from tornado.iostream import StreamClosedError

from inspection_robot.bridge.access import Peer, local_names, origin_allowed
from inspection_robot.bridge.handler import CLOSE_POLICY, BridgeHandler
from inspection_robot.bridge.listener import GuardedListener
from inspection_robot.bridge.trace import NoTrace

KEEPALIVE_TICK = 1.0  # s between checks for silent or over-budget clients (pings go every ping_interval)
REFUSAL_LOG_PERIOD = 10.0  # s: at most one logged origin refusal per period
CLOSE_GOING_AWAY = 1001  # websocket close code (RFC 6455 7.4.1)
HTTP_BODY_BYTES = 65536  # largest HTTP request body taken (the websocket and the console need none)
COLLECT_PERIOD = 1.0  # s: at most one cycle collection per period after clients left


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


def make_ssl_context(certfile, keyfile):
    """A server TLS context from PEM files (TLS 1.2+)."""
    context = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
    context.minimum_version = ssl.TLSVersion.TLSv1_2
    context.load_cert_chain(certfile, keyfile or None)
    return context
