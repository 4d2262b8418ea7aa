"""One websocket client of the bridge (:class:`BridgeHandler`): reading in fair slices, writing
batches from its send queue, drop warnings, frame limits before authentication, closing with a reason.

Kept apart from server.py, which listens, admits, keeps clients alive and counts them: this is the
per-connection half of the transport whose policy server.py's docstring describes; a handler's
configuration comes from its BridgeServer.
"""
import asyncio
import collections
import time

import tornado.ioloop
import tornado.websocket
from tornado.iostream import StreamClosedError

from inspection_robot.bridge import compat_tornado
from inspection_robot.bridge.compat_tornado import CLOSE_TOO_BIG
from inspection_robot.bridge.send_queue import SendQueue, frames_size

READ_SLICE = 32  # incoming frames handled before the reader yields to the IOLoop once
BATCH_BYTES = 1 << 20  # outgoing bytes handed to the socket per write (at least one message)
# bytes the kernel may hold unsent per client (TCP_NOTSENT_LOWAT); by default it takes up to 4 MB,
# which for a client that stopped reading would be a backlog of ~30 stale video frames the queue_length
# of its subscription can no longer replace
UNSENT_BYTES = 128 << 10
DROP_WARNING_PERIOD = 1.0  # s: at most one drop warning per client and period
BACKLOG_POLL = 0.001  # s between checks of a full rospy publisher queue while a client's reading is paused
CLOSE_POLICY = 1008  # websocket close code (RFC 6455 7.4.1): policy violation


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
            size += frames_size(frames)
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
