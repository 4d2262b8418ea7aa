"""What a rosbridge v2 message may be: the op table (:data:`OPS`: every op's fields and their JSON
types) and its check (:func:`check_fields`), the error an op raises (:class:`BridgeError`) and the
JSON encoding of replies; no state.

Kept apart from protocol.py's Session (one client's state): the table is the same for every client,
and the backend, the fuzz test and the session's topic and service halves use it without a Session.
"""
import json
import math

COMPRESSIONS = ("none", "png", "cbor", "cbor-raw")
NUMBER = (int, float)
ANY_ID = (str, int, float)
ORIGINAL_MAX = 200  # characters of an offending frame quoted back in a status message
# one shared compact encoder: json.dumps(..., separators=...) would build a new encoder per call
compact_json = json.JSONEncoder(separators=(",", ":")).encode
_strict_json = json.JSONEncoder(separators=(",", ":"), allow_nan=False, default=repr).encode


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
                              % (field.name, field.type_name, shortened(json.dumps(value, default=repr))))
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


def shortened(text):
    """``text`` cut to ORIGINAL_MAX characters, to quote it back in a status message."""
    return text if len(text) <= ORIGINAL_MAX else text[:ORIGINAL_MAX] + "..."
