"""The publish/subscribe half of a protocol Session: the topic ops (advertise, unadvertise, publish,
subscribe, unsubscribe), each subscription's throttle_rate, queue_length, fragment_size and
compression, and the encodings of an outgoing ROS message (:class:`Outgoing`, computed once for
every subscribed client).

Kept apart from protocol.py, which holds a client's state, dispatch, authentication and teardown:
:class:`TopicOps` is a mixin of protocol.Session; its methods use the session's backend, send,
clock, call_later, surface check (``_allowed``) and fragmenting, and its ``_advertised`` and
``_subscriptions``.
"""
import math

from inspection_robot.bridge import cbor
from inspection_robot.bridge.compression import png_encode
from inspection_robot.bridge.ops import COMPRESSIONS, BridgeError, compact_json

_PUBLISH_PREFIX = {}  # topic -> '{"op":"publish","topic":"<topic>","msg":'


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


class TopicOps(object):
    """The topic ops and the delivery of ROS messages to one client (a mixin of protocol.Session)."""

    # ------------------------------------------------------------------ topics
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

    # ------------------------------------------------------------------ delivery
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
