"""rosbridge v2 protocol, one :class:`Session` per websocket client; no rospy, no sockets.

An op table (ops.OPS) declares every op's fields and their JSON types; a frame is parsed,
checked against it and dispatched through the session's handler table (``Session.handlers``,
op name -> method). Any problem becomes a ``status`` message at level ``error`` naming the op
and echoing the ``id``; the session keeps serving. The log gets at most one line per client
every ``LOG_PERIOD`` s for such problems, with the count of those left out.
ROS effects go through a backend (bridge.ros_backend.RosBackend, or a fake in the unit tests), frames
out through ``send(frames, key, limit)`` of the transport's bounded queue. All methods run on
the transport's event-loop thread; the backend hands ROS callbacks over to that thread.
This module holds a client's state, dispatch, authentication, status and teardown; the topic ops
and message delivery are in session_topics.py, the service ops in session_services.py (mixins of
Session, same state), the op table and reply encoding in ops.py.
"""
import base64
import json
import math

from inspection_robot.bridge import cbor
from inspection_robot.bridge.access import Peer
from inspection_robot.bridge.compression import Defragmenter, FragmentError, fragments, png_encode
from inspection_robot.bridge.ops import (OPS, ORIGINAL_MAX, BridgeError, check_fields, compact_json, reply_json,
                                         shortened, valid_id)
from inspection_robot.bridge.session_services import ServiceOps
from inspection_robot.bridge.session_topics import TopicOps
from inspection_robot.bridge.surface import SurfaceError

LEVELS = {"info": 0, "warning": 1, "error": 2, "none": 3}
DEFAULT_LEVEL = "error"
LOG_PERIOD = 5.0  # s: at most one logged protocol error per client and period


class SessionConfig(object):
    """Per-client limits, read once by the node and shared by all sessions."""

    def __init__(self, authenticator=None, fragment_timeout=600.0, max_message_size=10000000,
                 service_timeout=10.0, auth_timeout=10.0):
        self.authenticator = authenticator
        self.auth_timeout = float(auth_timeout)  # s an unauthenticated client may stay connected
        self.fragment_timeout = float(fragment_timeout)
        self.max_message_size = int(max_message_size)
        self.service_timeout = float(service_timeout)


class Session(TopicOps, ServiceOps):
    """The protocol state of one client.

    ``backend``: ROS side (see bridge.ros_backend.RosBackend for the interface). ``send(frames, key, limit,
    droppable)``: queue a list of frames (str text / bytes binary) as one message. ``clock()``:
    monotonic seconds. ``call_later(delay_s, fn)``: returns a handle with ``cancel()``.
    ``close()``: drop the connection after the queued frames. ``rosapi``: RosApi or None.
    ``peer``: the client's access.Peer (address, TLS), for authentication.
    """

    def __init__(self, client_id, backend, send, clock, call_later, close, config, rosapi=None, log=None,
                 peer=None, surface=None):
        self.client_id = client_id
        self.surface = surface  # bridge.surface.Surface: what this client may reach (None: everything)
        self.peer = peer or Peer("127.0.0.1", False)
        self._backend = backend
        self._send = send
        self._clock = clock
        self._call_later = call_later
        self._close = close
        self._config = config
        self._rosapi = rosapi
        self._log = log or (lambda level, text: None)
        self._level = LEVELS[DEFAULT_LEVEL]
        self._authenticated = config.authenticator is None
        self._nonce = None  # the auth_challenge nonce issued to this client, until an auth uses it
        self._auth_timer = None  # cancelled when the client authenticates or leaves: it holds the session
        # one bound for a message and for all of a client's messages in progress together
        self._defrag = Defragmenter(clock, config.fragment_timeout, config.max_message_size,
                                    max_total_bytes=config.max_message_size)
        self._advertised = {}   # topic -> set of advertise ids
        self._subscriptions = {}  # topic -> _Subscription
        self._services = set()  # services this client provides
        self._pending_requests = {}  # request id -> callback(result, values)
        self._request_counter = 0
        self._closed = False
        self._last_published = None  # topic of the latest publish (for ros_backlogged)
        self._log_after = None  # clock time before which protocol errors are counted, not logged
        self._unlogged = 0
        # op name -> handler; every entry of OPS has one (checked by the unit tests)
        self.handlers = {
            "advertise": self._op_advertise,
            "unadvertise": self._op_unadvertise,
            "publish": self._op_publish,
            "subscribe": self._op_subscribe,
            "unsubscribe": self._op_unsubscribe,
            "call_service": self._op_call_service,
            "advertise_service": self._op_advertise_service,
            "unadvertise_service": self._op_unadvertise_service,
            "service_response": self._op_service_response,
            "set_level": self._op_set_level,
            "fragment": self._op_fragment,
            "auth": self._op_auth,
            "auth_challenge": self._op_auth_challenge,
        }
        if not self._authenticated:
            wait = config.authenticator.limiter.blocked_for(self.peer.address)
            if wait > 0:
                self._refuse("Too many failed authentications from %s: try again in %d s; closing"
                             % (self.peer.address, math.ceil(wait)))
            else:  # a connection that never authenticates must not hold a slot forever
                self._auth_timer = self._call_later(config.auth_timeout, self._auth_overdue)

    @property
    def authenticated(self):
        """True once the client may use every op (at once when no authentication is required)."""
        return self._authenticated

    @property
    def fragment_bytes(self):
        """Bytes of this client's incomplete fragmented messages held for reassembly."""
        return self._defrag.held_bytes

    # ------------------------------------------------------------------ incoming frames
    def on_frame(self, frame):
        """Handle one websocket frame (str: JSON, bytes: CBOR). Never raises."""
        if self._closed:
            return
        try:
            if isinstance(frame, (bytes, bytearray)):
                msg = cbor.loads(frame)
            else:
                msg = json.loads(frame)
        except ValueError as exc:
            self.status("error", "Unable to parse the message (%s): %s" % (exc, shortened(_text(frame))))
            return
        except RecursionError:
            self.status("error", "Unable to parse the message: nested too deeply")
            return
        self.handle(msg, frame)

    def handle(self, msg, original=None):
        """Dispatch one decoded message. Never raises."""
        if not isinstance(msg, dict):
            self.status("error", "Received a message that is not a JSON object: %s" % shortened(_text(original)))
            return
        mid = valid_id(msg.get("id"))
        op = msg.get("op")
        if not self._authenticated and op not in ("auth", "auth_challenge"):
            self._refuse("Not authenticated: the first message must be an auth op (or auth_challenge); closing",
                         mid)
            return
        if op is None:
            self.status("error", "Received a message without an op. All messages require 'op' field with value "
                        "one of: %s. Original message was: %s" % (sorted(OPS), shortened(_text(original))), mid)
            return
        if not isinstance(op, str) or op not in OPS:
            self.status("error", "Unknown operation: %s. Allowed operations: %s" % (shortened(str(op)), sorted(OPS)),
                        mid)
            return
        try:
            args = check_fields(op, msg)
        except BridgeError as exc:
            if not self._authenticated:   # a malformed auth / auth_challenge is a failed attempt
                self._refuse("%s: %s; closing" % (op, exc), mid)
                return
            self.status(exc.level, "%s: %s" % (op, exc), mid, op)
            return
        try:
            self.handlers[op](args, mid)
        except BridgeError as exc:
            self.status(exc.level, "%s: %s" % (op, exc), mid, op)
        except ValueError as exc:  # bad message contents or type names (codec, type loading)
            self.status("error", "%s: %s" % (op, exc), mid, op)
        except Exception as exc:  # boundary: one bad op never takes the connection down
            self._log("error", "client %s: %s failed: %r" % (self.client_id, op, exc))
            self.status("error", "%s: %s" % (op, exc), mid, op)

    def _auth_overdue(self):
        if not self._authenticated and not self._closed:
            self._refuse("Not authenticated within %g s; closing" % self._config.auth_timeout)

    def _refuse(self, text, mid=None):
        """Tell an unauthenticated client why, close, and handle none of its further frames (a burst of
        guesses gets one try per connection)."""
        self.status("error", text, mid, always=True)
        self._close()
        self._closed = True  # nothing to clean up: an unauthenticated client has opened nothing

    # ------------------------------------------------------------------ outgoing
    def status(self, level, text, mid=None, op=None, always=False):
        """Send a status message if ``level`` passes the client's set_level (``always``: unless it is none)."""
        if level in ("error", "warning"):
            self._log_throttled("warning" if level == "warning" else "error", text)
        if LEVELS[level] < self._level and not (always and self._level < LEVELS["none"]):
            return
        message = {"op": "status", "level": level, "msg": text}
        if mid is not None:
            message["id"] = mid
        self._send([reply_json(message)], None, None, False)

    def _log_throttled(self, level, text):
        now = self._clock()
        if self._log_after is not None and now < self._log_after:
            self._unlogged += 1
            return
        more = " (+%d more since the last line)" % self._unlogged if self._unlogged else ""
        self._log(level, "client %s: %s%s" % (self.client_id, text, more))
        self._unlogged = 0
        self._log_after = now + LOG_PERIOD

    def drops(self, topic, count, total, budget):
        """Tell the client that ``count`` messages on ``topic`` were dropped (its send queue is over budget).

        Sent at level warning even under the default level error (a loss must not be silent);
        ``set_level none`` silences it.
        """
        self.status("warning", "subscribe: dropped %d messages on %s (%d in all): the client reads slower than "
                    "the topic and its send queue is over its budget of %d bytes" % (count, topic, total, budget),
                    always=True)

    def ros_backlogged(self):
        """True while the ROS publisher of this client's latest publish has a full queue (stop reading)."""
        topic = self._last_published
        if topic is None:
            return False
        if self._backend.publisher_full(topic):
            return True
        self._last_published = None
        return False

    def _send_json(self, message, fragment_size=None, compression="none", droppable=False):
        if compression in ("cbor", "cbor-raw"):
            self._send([cbor.dumps(message)], None, None, droppable)
            return
        text = reply_json(message)
        if compression == "png":
            text = compact_json({"op": "png", "data": png_encode(text)})
        self._send(self._fragmented(text, fragment_size, message.get("id")), None, None, droppable)

    def _fragmented(self, text, fragment_size, mid):
        if fragment_size is None or fragment_size <= 0 or len(text) <= fragment_size:
            return [text]
        if mid is None:
            self._request_counter += 1
            mid = "fragment:%s:%d" % (self.client_id, self._request_counter)
        return [compact_json(f) for f in fragments(text, fragment_size, mid)]

    # ------------------------------------------------------------------ access
    def _allowed(self, kind, name):
        """Raise BridgeError unless this client's role may ``kind`` ``name`` (bridge.surface)."""
        if self.surface is not None:
            try:
                self.surface.check(kind, name)
            except SurfaceError as exc:
                raise BridgeError(str(exc))

    # ------------------------------------------------------------------ misc
    def _op_set_level(self, args, mid):
        if args["level"] not in LEVELS:
            raise BridgeError("level must be one of %s" % ", ".join(sorted(LEVELS, key=LEVELS.get)))
        self._level = LEVELS[args["level"]]

    def _op_fragment(self, args, mid):
        if valid_id(args["id"]) is None:
            raise BridgeError("fragment id must be a string or a finite number")
        try:
            text = self._defrag.add(args["id"], args["num"], args["total"], args["data"])
        except FragmentError as exc:
            raise BridgeError(str(exc))
        if text is not None:
            self.on_frame(text)

    def _op_auth(self, args, mid):
        authenticator = self._config.authenticator
        if authenticator is None or self._authenticated:
            return  # nothing to check (rosbridge also ignores a late auth)
        nonce, self._nonce = self._nonce, None  # single use, whatever the outcome
        refusal = authenticator.refusal(args, self.peer, nonce)
        if refusal is not None:
            authenticator.limiter.failed(self.peer.address)
            self._refuse("auth: authentication failed: %s; closing" % refusal, mid)
            return
        self._authenticated = True
        self._cancel_auth_timer()

    def _cancel_auth_timer(self):
        # the timer refers to this session and so to the connection's buffers: a closed connection
        # must not stay in memory for ~auth_timeout (the bench's 360 refused connections held 25 MB)
        if self._auth_timer is not None:
            self._auth_timer.cancel()
            self._auth_timer = None

    def _op_auth_challenge(self, args, mid):
        authenticator = self._config.authenticator
        if authenticator is None or self._authenticated:
            raise BridgeError("no authentication needed on this connection")
        self._nonce, now = authenticator.challenge()
        reply = {"op": "auth_challenge", "nonce": self._nonce, "t": now}
        if mid is not None:
            reply["id"] = mid
        self._send_json(reply)

    # ------------------------------------------------------------------ teardown
    def close(self):
        """The client left: remove its publishers, subscribers and services; fail its pending calls;
        free its incomplete fragmented messages."""
        self._defrag.clear()
        self._cancel_auth_timer()
        if self._closed:
            return
        self._closed = True
        for topic in list(self._subscriptions):
            self._safely(self._drop_subscription, topic)
        for topic in list(self._advertised):
            del self._advertised[topic]
            self._safely(self._backend.unadvertise, self, topic)
        for service in list(self._services):
            self._safely(self._backend.unadvertise_service, self, service)
        self._services.clear()
        for service, callback in self._pending_requests.values():
            callback(False, "client %s disconnected" % self.client_id)
        self._pending_requests.clear()

    def _safely(self, fn, *args):
        try:
            fn(*args)
        except Exception as exc:  # boundary: cleanup of one item must not stop the others
            self._log("error", "client %s: cleanup failed: %r" % (self.client_id, exc))


def _text(frame):
    if isinstance(frame, (bytes, bytearray)):
        return base64.standard_b64encode(bytes(frame[:ORIGINAL_MAX])).decode("ascii")
    return frame if isinstance(frame, str) else repr(frame)
