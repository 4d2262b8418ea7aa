"""rosbridge v2 protocol, one :class:`Session` per websocket client; no rospy, no sockets.

An op table (:data:`OPS`) declares every op's fields and their JSON types; a frame is parsed,
checked against it and dispatched through the session's handler table (``Session.handlers``,
op name -> method). Any problem becomes a ``status`` message at level ``error`` naming the op
and echoing the ``id``; the session keeps serving. The log gets at most one line per client
every ``LOG_PERIOD`` s for such problems, with the count of those left out.
ROS effects go through a backend (bridge.ros_backend.RosBackend, or a fake in the unit tests), frames
out through ``send(frames, key, limit)`` of the transport's bounded queue. All methods run on
the transport's event-loop thread; the backend hands ROS callbacks over to that thread.
"""
import base64
import json
import math

from inspection_robot.bridge import cbor
from inspection_robot.bridge.access import Peer
from inspection_robot.bridge.compression import Defragmenter, FragmentError, fragments, png_encode
from inspection_robot.bridge.surface import SurfaceError

LEVELS = {"info": 0, "warning": 1, "error": 2, "none": 3}
DEFAULT_LEVEL = "error"
COMPRESSIONS = ("none", "png", "cbor", "cbor-raw")
NUMBER = (int, float)
ANY_ID = (str, int, float)
ORIGINAL_MAX = 200  # characters of an offending frame quoted back in a status message
LOG_PERIOD = 5.0  # s: at most one logged protocol error per client and period
# one shared compact encoder: json.dumps(..., separators=...) would build a new encoder per call
compact_json = json.JSONEncoder(separators=(",", ":")).encode
_strict_json = json.JSONEncoder(separators=(",", ":"), allow_nan=False, default=repr).encode
_PUBLISH_PREFIX = {}  # topic -> '{"op":"publish","topic":"<topic>","msg":'


class BridgeError(Exception):
    """An op that cannot be carried out; its text goes to the client in a status message."""

    def __init__(self, text, level="error"):
        Exception.__init__(self, text)
        self.level = level


class Field(object):
    """One declared field of an op: name, accepted JSON types, required or default."""

    __slots__ = ("name", "types", "required", "default", "type_name")

    def __init__(self, name, types, required=False, default=None, type_name=None):
        self.name = name
        self.types = types if isinstance(types, tuple) else (types,)
        self.required = required
        self.default = default
        self.type_name = type_name or "/".join(t.__name__ for t in self.types)


def _f(name, types, required=False, default=None, type_name=None):
    return Field(name, types, required, default, type_name)


OPS = {
    "advertise": [_f("topic", str, True), _f("type", str, True), _f("latch", bool, default=False),
                  _f("queue_size", int, default=100)],
    "unadvertise": [_f("topic", str, True)],
    "publish": [_f("topic", str, True), _f("msg", dict, default=None), _f("latch", bool, default=False)],
    "subscribe": [_f("topic", str, True), _f("type", str), _f("throttle_rate", int, default=0),
                  _f("queue_length", int, default=0), _f("fragment_size", int),
                  _f("compression", str, default="none")],
    "unsubscribe": [_f("topic", str, True)],
    "call_service": [_f("service", str, True), _f("args", (list, dict), type_name="list or object"),
                     _f("type", str), _f("fragment_size", int), _f("compression", str, default="none"),
                     _f("timeout", NUMBER, type_name="number")],
    "advertise_service": [_f("service", str, True), _f("type", str, True)],
    "unadvertise_service": [_f("service", str, True)],
    "service_response": [_f("service", str, True),
                         _f("values", (dict, list, str, type(None)), default=None, type_name="object"),
                         _f("result", bool, default=True)],
    "set_level": [_f("level", str, True)],
    "fragment": [_f("id", ANY_ID, True, type_name="string"), _f("data", str, True), _f("num", int, True),
                 _f("total", int, True)],
    "auth": [_f("mac", str, True), _f("client", str, default=""), _f("dest", str, default=""),
             _f("rand", str, default=""), _f("t", (int, float, dict), default=0, type_name="time"),
             _f("level", str, default=""), _f("end", (int, float, dict), default=0, type_name="time")],
    "auth_challenge": [],
}


def check_fields(op, msg):
    """The declared fields of ``op`` from ``msg`` (defaults filled); BridgeError names the culprit."""
    args = {}
    for field in OPS[op]:
        if field.name not in msg or (msg[field.name] is None and not field.required
                                     and type(None) not in field.types):
            if field.required:
                raise BridgeError("Expected a %s field but none was found." % field.name)
            args[field.name] = field.default
            continue
        value = msg[field.name]
        if type(value) is bool and bool not in field.types or not isinstance(value, field.types):
            raise BridgeError("Expected field %s to be %s. Invalid value: %s"
                              % (field.name, field.type_name, _short(json.dumps(value, default=repr))))
        args[field.name] = value
    return args


def _finite(value):
    """``value`` with every NaN / infinite float replaced by None (JSON has neither)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return dict((key, _finite(item)) for key, item in value.items())
    if isinstance(value, (list, tuple)):
        return [_finite(item) for item in value]
    return value


def reply_json(message):
    """Compact JSON text of a reply built from a client's values: never invalid JSON (a NaN or
    infinity, which Python's encoder would write as a bare NaN / Infinity, becomes null)."""
    try:
        return _strict_json(message)
    except ValueError:
        return _strict_json(_finite(message))


def valid_id(mid):
    """The request id to echo: a string or a finite number (not bool); None for anything else."""
    if isinstance(mid, bool) or not isinstance(mid, ANY_ID):
        return None
    if isinstance(mid, float) and not math.isfinite(mid):
        return None
    return mid


def _short(text):
    return text if len(text) <= ORIGINAL_MAX else text[:ORIGINAL_MAX] + "..."


class Outgoing(object):
    """One ROS message on ``topic`` for every subscribed client; encodings computed once, lazily."""

    __slots__ = ("topic", "msg", "_codec", "_stamp", "_json", "_cbor", "_png", "_raw")

    def __init__(self, topic, msg, codec, stamp=None):
        self.topic = topic
        self.msg = msg
        self._codec = codec
        self._stamp = stamp  # (secs, nsecs) of reception, for cbor-raw
        self._json = self._cbor = self._png = self._raw = None

    def json_text(self):
        if self._json is None:
            prefix = _PUBLISH_PREFIX.get(self.topic)
            if prefix is None:
                if len(_PUBLISH_PREFIX) > 10000:
                    _PUBLISH_PREFIX.clear()
                prefix = _PUBLISH_PREFIX[self.topic] = '{"op":"publish","topic":%s,"msg":' % compact_json(self.topic)
            self._json = prefix + self._codec.to_json_text(self.msg) + "}"
        return self._json

    def cbor_frame(self):
        if self._cbor is None:
            self._cbor = cbor.dumps({"op": "publish", "topic": self.topic, "msg": self._codec.to_cbor(self.msg)})
        return self._cbor

    def cbor_raw_frame(self):
        if self._raw is None:
            from io import BytesIO
            buff = BytesIO()
            self.msg.serialize(buff)
            secs, nsecs = self._stamp or (0, 0)
            self._raw = cbor.dumps({"op": "publish", "topic": self.topic,
                                    "msg": {"bytes": buff.getvalue(), "secs": secs, "nsecs": nsecs}})
        return self._raw

    def png_text(self):
        if self._png is None:
            self._png = compact_json({"op": "png", "data": png_encode(self.json_text())})
        return self._png

    def encoded(self, compression):
        """The message as a subscription with ``compression`` receives it: text (JSON, PNG) or bytes (CBOR).

        Any thread may call it (the ROS side does, for the compressions its subscribers use, so the
        event loop only writes); two threads encoding at once both get the same result.
        """
        if compression == "cbor":
            return self.cbor_frame()
        if compression == "cbor-raw":
            return self.cbor_raw_frame()
        if compression == "png":
            return self.png_text()
        return self.json_text()


class _Subscription(object):
    """A client's subscriptions to one topic (by id), merged as rosbridge merges them."""

    __slots__ = ("by_id", "throttle_ms", "queue_length", "fragment_size", "compression", "last_sent",
                 "backlog", "timer")

    def __init__(self):
        self.by_id = {}
        self.last_sent = None
        self.backlog = []
        self.timer = None

    def update(self):
        options = list(self.by_id.values())
        self.throttle_ms = min(o["throttle_rate"] for o in options)
        self.queue_length = max(o["queue_length"] for o in options)
        sizes = [o["fragment_size"] for o in options if o["fragment_size"] is not None]
        self.fragment_size = min(sizes) if sizes else None
        kinds = [o["compression"] for o in options]
        self.compression = next((k for k in ("cbor-raw", "cbor", "png") if k in kinds), "none")
        del self.backlog[:max(0, len(self.backlog) - max(1, self.queue_length))]


class SessionConfig(object):
    """Per-client limits, read once by the node and shared by all sessions."""

    def __init__(self, authenticator=None, fragment_timeout=600.0, max_message_size=10000000,
                 service_timeout=10.0, auth_timeout=10.0):
        self.authenticator = authenticator
        self.auth_timeout = float(auth_timeout)  # s an unauthenticated client may stay connected
        self.fragment_timeout = float(fragment_timeout)
        self.max_message_size = int(max_message_size)
        self.service_timeout = float(service_timeout)


class Session(object):
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
            self.status("error", "Unable to parse the message (%s): %s" % (exc, _short(_text(frame))))
            return
        except RecursionError:
            self.status("error", "Unable to parse the message: nested too deeply")
            return
        self.handle(msg, frame)

    def handle(self, msg, original=None):
        """Dispatch one decoded message. Never raises."""
        if not isinstance(msg, dict):
            self.status("error", "Received a message that is not a JSON object: %s" % _short(_text(original)))
            return
        mid = valid_id(msg.get("id"))
        op = msg.get("op")
        if not self._authenticated and op not in ("auth", "auth_challenge"):
            self._refuse("Not authenticated: the first message must be an auth op (or auth_challenge); closing",
                         mid)
            return
        if op is None:
            self.status("error", "Received a message without an op. All messages require 'op' field with value "
                        "one of: %s. Original message was: %s" % (sorted(OPS), _short(_text(original))), mid)
            return
        if not isinstance(op, str) or op not in OPS:
            self.status("error", "Unknown operation: %s. Allowed operations: %s" % (_short(str(op)), sorted(OPS)),
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

    def compression(self, topic):
        """The compression of this client's subscription to ``topic`` (None if none); any thread."""
        sub = self._subscriptions.get(topic)
        return sub.compression if sub is not None else None

    def deliver(self, outgoing):
        """A ROS message arrived on a topic this client subscribes to (event-loop thread)."""
        sub = self._subscriptions.get(outgoing.topic)
        if sub is None:
            return
        if sub.throttle_ms <= 0:
            self._emit(sub, outgoing)
            return
        now = self._clock()
        if sub.queue_length <= 0:
            if sub.last_sent is None or (now - sub.last_sent) * 1000.0 >= sub.throttle_ms:
                sub.last_sent = now
                self._emit(sub, outgoing)
            return
        sub.backlog.append(outgoing)
        del sub.backlog[:max(0, len(sub.backlog) - sub.queue_length)]
        if sub.timer is None:
            wait = 0.0 if sub.last_sent is None else sub.last_sent + sub.throttle_ms / 1000.0 - now
            sub.timer = self._call_later(max(0.0, wait), lambda: self._flush(outgoing.topic))

    def _flush(self, topic):
        sub = self._subscriptions.get(topic)
        if sub is None or self._closed:
            return
        sub.timer = None
        if sub.backlog:
            sub.last_sent = self._clock()
            self._emit(sub, sub.backlog.pop(0))
        if sub.backlog:
            sub.timer = self._call_later(sub.throttle_ms / 1000.0, lambda: self._flush(topic))

    def _emit(self, sub, outgoing):
        data = outgoing.encoded(sub.compression)
        frames = [data] if isinstance(data, bytes) else self._fragmented(data, sub.fragment_size, None)
        self._send(frames, outgoing.topic, sub.queue_length or None, True)

    # ------------------------------------------------------------------ topics
    def _allowed(self, kind, name):
        """Raise BridgeError unless this client's role may ``kind`` ``name`` (bridge.surface)."""
        if self.surface is not None:
            try:
                self.surface.check(kind, name)
            except SurfaceError as exc:
                raise BridgeError(str(exc))

    def _op_advertise(self, args, mid):
        topic = args["topic"]
        self._allowed("publish", topic)
        ids = self._advertised.get(topic)
        if ids is None:
            self._backend.advertise(self, topic, args["type"], args["latch"], max(1, args["queue_size"]))
            ids = self._advertised[topic] = set()
        else:
            self._backend.check_type(topic, args["type"])
        ids.add(mid)

    def _op_unadvertise(self, args, mid):
        topic = args["topic"]
        ids = self._advertised.get(topic)
        if ids is None:
            raise BridgeError("Topic %s is not advertised by this client" % topic, "warning")
        ids.discard(mid)
        if mid is None or not ids:
            del self._advertised[topic]
            self._backend.unadvertise(self, topic)

    def _op_publish(self, args, mid):
        topic = args["topic"]
        self._allowed("publish", topic)
        if self.surface is not None and not self.surface.open:
            # a robot command is never meaningful with NaN, ±Infinity or null (read as NaN): told here,
            # where the backend hears it, instead of a node dropping it with only a log line
            field = _not_finite(args["msg"] or {})
            if field is not None:
                raise BridgeError("%s refused: field %s is %s; commands take finite numbers (nothing published)"
                                  % (topic, field[0] or "msg", field[1]))
        if topic not in self._advertised:
            topic_type = self._backend.topic_type(topic)
            if not topic_type:
                raise BridgeError("Cannot infer topic type for topic %s as it is not yet advertised" % topic)
            self._backend.advertise(self, topic, topic_type, args["latch"], 100)
            self._advertised[topic] = {None}
        self._backend.publish(topic, args["msg"] or {})
        self._last_published = topic

    def _op_subscribe(self, args, mid):
        topic = args["topic"]
        self._allowed("subscribe", topic)
        if args["compression"] not in COMPRESSIONS:
            raise BridgeError("compression must be one of %s, not %r"
                              % (", ".join(COMPRESSIONS), args["compression"]))
        if args["throttle_rate"] < 0 or args["queue_length"] < 0:
            raise BridgeError("throttle_rate and queue_length must not be negative")
        sub = self._subscriptions.get(topic)
        if sub is None:
            self._backend.subscribe(self, topic, args["type"])
            sub = self._subscriptions[topic] = _Subscription()
        elif args["type"]:
            self._backend.check_type(topic, args["type"])
        sub.by_id[mid] = args
        sub.update()

    def _op_unsubscribe(self, args, mid):
        topic = args["topic"]
        sub = self._subscriptions.get(topic)
        if sub is None:
            raise BridgeError("Not subscribed to topic %s" % topic, "warning")
        if mid is not None and mid in sub.by_id:
            del sub.by_id[mid]
        else:
            sub.by_id.clear()
        if sub.by_id:
            sub.update()
            return
        self._drop_subscription(topic)

    def _drop_subscription(self, topic):
        sub = self._subscriptions.pop(topic)
        if sub.timer is not None:
            sub.timer.cancel()
        self._backend.unsubscribe(self, topic)

    # ------------------------------------------------------------------ services
    def _op_call_service(self, args, mid):
        service = args["service"]
        fragment_size, compression, timeout = args["fragment_size"], args["compression"], args["timeout"]
        if compression not in COMPRESSIONS:
            raise BridgeError("compression must be one of %s" % ", ".join(COMPRESSIONS))
        if timeout is not None and not (timeout > 0 and timeout < 1e9):
            raise BridgeError("timeout must be a positive number of seconds, not %r" % (timeout,))
        state = {"answered": False, "timer": None}

        def done(ok, values):
            if self._closed or state["answered"]:
                return
            state["answered"] = True
            if state["timer"] is not None:
                state["timer"].cancel()
            message = {"op": "service_response", "service": service, "values": values, "result": ok}
            if mid is not None:
                message["id"] = mid
            if not ok:
                self.status("error", "call_service: %s" % values, mid, "call_service")
            self._send_json(message, fragment_size, compression)

        call_args = args["args"] if args["args"] is not None else {}
        refusal = self._call_refusal(service, call_args)
        if refusal:   # answered like a failed call: roslibjs/roslibpy see the reason as the call's error
            done(False, refusal)
            return
        if timeout is not None:
            # as rosbridge (ros2 branch): past the timeout the call fails; a late response is dropped
            state["timer"] = self._call_later(timeout, lambda: done(
                False, "Timeout exceeded while waiting for service %s (%g s)" % (service, timeout)))
        try:
            if self._rosapi is not None and self._rosapi.handles(service):
                visible = None
                if self.surface is not None:
                    visible = lambda name: self.surface.allows("params", name)  # noqa: E731
                self._backend.run_blocking(lambda: self._rosapi.call(service, call_args, visible), done)
            else:
                self._backend.call_service(service, call_args, args["type"], timeout, done)
        except Exception:
            state["answered"] = True  # the error status answers the call
            if state["timer"] is not None:
                state["timer"].cancel()
            raise

    def _call_refusal(self, service, call_args):
        """Why this client's role may not make this call (the service, or the parameter a rosapi call
        names), or None."""
        try:
            self._allowed("call", service)
            if self._rosapi is not None and self._rosapi.handles(service):
                name = self._rosapi.param_name(service, call_args)
                if name is not None:
                    self._allowed("params", name)
        except BridgeError as exc:
            return str(exc)
        return None

    def _op_advertise_service(self, args, mid):
        service = args["service"]
        if self.surface is not None and not self.surface.open:
            raise BridgeError("advertising services is refused: no role offers services to the robot (rule "
                              "%s.advertise_service; docs/interface.md, Backend surface)" % self.surface.role)
        if self._rosapi is not None and self._rosapi.handles(service):
            raise BridgeError("Service %s is provided by the bridge itself" % service)
        if service in self._services:
            self._backend.unadvertise_service(self, service)
            self._services.discard(service)
        self._backend.advertise_service(self, service, args["type"])
        self._services.add(service)

    def _op_unadvertise_service(self, args, mid):
        service = args["service"]
        if service not in self._services:
            raise BridgeError("Service %s is not advertised by this client" % service, "warning")
        self._services.discard(service)
        self._backend.unadvertise_service(self, service)
        for request_id, (svc, callback) in list(self._pending_requests.items()):
            if svc == service:
                del self._pending_requests[request_id]
                callback(False, "service %s was unadvertised" % service)

    def request(self, service, args, callback):
        """ROS calls a service this client provides: forward it; ``callback(result, values)`` later."""
        if self._closed or service not in self._services:
            callback(False, "client %s does not provide %s" % (self.client_id, service))
            return None
        self._request_counter += 1
        request_id = "service_request:%s:%d" % (service, self._request_counter)
        self._pending_requests[request_id] = (service, callback)
        self._send([compact_json({"op": "call_service", "id": request_id, "service": service, "args": args})],
                   None, None, False)
        return request_id

    def cancel_request(self, request_id):
        """Forget a forwarded request (it timed out on the ROS side)."""
        self._pending_requests.pop(request_id, None)

    def _op_service_response(self, args, mid):
        entry = self._pending_requests.pop(mid, None) if mid is not None else None
        if entry is None:
            raise BridgeError("No pending call of service %s with id %s" % (args["service"], mid))
        values = args["values"]
        if args["result"] and not isinstance(values, dict):
            if values is not None:
                entry[1](False, "the response values of %s must be an object" % args["service"])
                raise BridgeError("the values of a successful response must be an object")
            values = {}
        entry[1](args["result"], values)

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


def _not_finite(value, path=""):
    """(field path, what) of the first NaN, ±Infinity or null in a message's JSON value, or None."""
    if value is None:
        return path, "null"
    if isinstance(value, float) and not math.isfinite(value):
        return path, repr(value).replace("inf", "Infinity").replace("nan", "NaN")
    if isinstance(value, dict):
        items = value.items()
    elif isinstance(value, list):
        items = enumerate(value)
    else:
        return None
    for key, item in items:
        found = _not_finite(item, "%s.%s" % (path, key) if path else str(key))
        if found is not None:
            return found
    return None


def _text(frame):
    if isinstance(frame, (bytes, bytearray)):
        return base64.standard_b64encode(bytes(frame[:ORIGINAL_MAX])).decode("ascii")
    return frame if isinstance(frame, str) else repr(frame)
