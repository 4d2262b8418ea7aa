"""ROS message <-> JSON (and CBOR) values with rosbridge's mapping (message_conversion, ros1).

Works on genpy-style classes (``__slots__``, ``_slot_types``, ``_type``) given a
:class:`TypeSupport` that resolves type names and builds time/duration values, so this module
needs no rospy. Mapping, as rosbridge:

- time/duration <-> ``{"secs", "nsecs"}``; an incoming time may also be the string ``"now"``.
- ``uint8[]``/``char[]`` (any length) -> base64 text; in: base64 text, a list of 0..255 or bytes.
- float NaN/+-inf -> ``null`` (JSON has neither); in: ``null`` for a float is read as NaN
  (rosbridge refuses it; accepting it lets a client echo what it received).
- fields missing from the JSON keep their defaults; a message that carries a ``header`` gets
  ``header.stamp`` = now unless the header gives one; unknown fields and wrong JSON types are
  errors with rosbridge's wording. Beyond rosbridge, integers are range-checked, fixed-size
  arrays length-checked and base64 validated, so an error names the field instead of failing
  later in serialization.

CBOR values (``compression: cbor``) carry bytes raw, numbers as typed arrays and NaN as is.
Converters are compiled once per message class.
"""
import base64
import binascii
import json
import re
from collections import namedtuple

from inspection_robot.bridge.cbor import ROS_ARRAY_TAGS, typed_array

INT_RANGES = {
    "int8": (-2 ** 7, 2 ** 7 - 1), "byte": (-2 ** 7, 2 ** 7 - 1), "uint8": (0, 2 ** 8 - 1),
    "char": (0, 2 ** 8 - 1), "int16": (-2 ** 15, 2 ** 15 - 1), "uint16": (0, 2 ** 16 - 1),
    "int32": (-2 ** 31, 2 ** 31 - 1), "uint32": (0, 2 ** 32 - 1),
    "int64": (-2 ** 63, 2 ** 63 - 1), "uint64": (0, 2 ** 64 - 1),
}
FLOAT_TYPES = ("float32", "float64")
TIME_TYPES = ("time", "duration")
PRIMITIVE_TYPES = set(INT_RANGES) | set(FLOAT_TYPES) | {"bool", "string"}
BINARY_TYPES = ("uint8", "char")
HEADER_TYPES = ("Header", "std_msgs/Header", "roslib/Header")
ARRAY = re.compile(r"^(.*)\[(\d*)\]$")


class CodecError(ValueError):
    """A JSON value that does not fit the message type; the text follows rosbridge's."""


class _Mismatch(Exception):
    """Raised inside converters; turned into CodecError with the root type and field path."""

    def __init__(self, expected, found, detail=None):
        Exception.__init__(self)
        self.expected = expected
        self.found = found
        self.detail = detail
        self.path = []


class _UnknownField(Exception):
    def __init__(self, name):
        Exception.__init__(self)
        self.path = [name]


class TypeSupport(object):
    """What the codec needs from the ROS side; bridge.ros_message_types.GenpyTypes implements it."""

    def message_class(self, type_name):
        raise NotImplementedError

    def time(self, secs, nsecs):
        raise NotImplementedError

    def duration(self, secs, nsecs):
        raise NotImplementedError

    def now(self):
        raise NotImplementedError


def split_array(field_type):
    """('float64', None) for a scalar; ('float64', 0) for float64[]; ('float64', 9) for float64[9]."""
    match = ARRAY.match(field_type)
    if not match:
        return field_type, None
    return match.group(1), int(match.group(2)) if match.group(2) else 0


def _finite_or_none(value):
    return value if value - value == 0 else None


def _b64(value):
    if not isinstance(value, (bytes, bytearray)):
        value = bytes(bytearray(value))
    return base64.standard_b64encode(value).decode("ascii")


BLOB_MIN = 1 << 16  # bytes: uint8[] at least this long are spliced into JSON text unescaped
_BLOB_MARK = "\x00\x01blob\x02"  # stands for one blob in the skeleton text, where it reads as below
_BLOB_MARK_JSON = '"\\u0000\\u0001blob\\u0002"'


class Blob(object):
    """The base64 text of a large uint8[] field, kept out of the JSON encoder (see Codec.to_json_text)."""

    __slots__ = ("text",)

    def __init__(self, text):
        self.text = text


def _b64_or_blob(value):
    text = _b64(value)
    return Blob(text) if len(text) >= BLOB_MIN else text


def _time_dict(value):
    return {"secs": value.secs, "nsecs": value.nsecs}


def _raw_bytes(value):
    return bytes(value) if isinstance(value, (bytes, bytearray)) else bytes(bytearray(value))


# How one output form converts the leaves of a message: its converters by class, uint8[]/char[],
# floats, and whether numeric arrays become CBOR typed arrays.
_Leaves = namedtuple("_Leaves", "cache binary floats typed_arrays")


class Codec(object):
    """Message <-> JSON/CBOR converter for the types ``types`` (a TypeSupport) resolves."""

    def __init__(self, types):
        self._types = types
        # one walk over the message definition for every output; they differ only at the leaves
        self._json = _Leaves({}, _b64, _finite_or_none, False)
        self._json_text = _Leaves({}, _b64_or_blob, _finite_or_none, False)
        self._cbor = _Leaves({}, _raw_bytes, float, True)
        self._from_json = {}

    # ---------------------------------------------------------------- ROS -> JSON / CBOR
    def to_json(self, msg):
        """The JSON-ready dict of a message instance."""
        return self._converter(self._json, type(msg))(msg)

    def to_json_text(self, msg):
        """The compact JSON text of a message instance (the same text as encoding to_json's dict).

        Base64 text needs no JSON escaping, so large uint8[] fields (images, point clouds) are not
        fed through the JSON encoder, which would scan every character: the message is encoded
        with a marker in their place and their text spliced in afterwards.
        """
        blobs = []

        def blob_mark(obj):
            if not isinstance(obj, Blob):
                raise TypeError("Object of type %s is not JSON serializable" % type(obj).__name__)
            blobs.append(obj.text)
            return _BLOB_MARK
        skeleton = json.JSONEncoder(separators=(",", ":"), default=blob_mark).encode(
            self._converter(self._json_text, type(msg))(msg))
        if not blobs:
            return skeleton
        parts = skeleton.split(_BLOB_MARK_JSON)
        if len(parts) != len(blobs) + 1:  # a string of the message looks like the marker: encode it all
            return json.JSONEncoder(separators=(",", ":"), default=lambda b: b.text).encode(
                self._converter(self._json_text, type(msg))(msg))
        out = [parts[0]]
        for text, part in zip(blobs, parts[1:]):
            out.extend(('"', text, '"', part))
        return "".join(out)

    def to_cbor(self, msg):
        """The CBOR-ready dict (bytes raw, typed arrays, NaN kept) of a message instance."""
        return self._converter(self._cbor, type(msg))(msg)

    def _converter(self, leaves, cls):
        return _message_converter(leaves.cache, lambda field_type: self._field(leaves, field_type), cls)

    def _field(self, leaves, field_type):
        """One field's conversion (None = the value as is), recursing into arrays and messages."""
        base, length = split_array(field_type)
        if length is not None:
            if base in BINARY_TYPES:
                return leaves.binary
            if leaves.typed_arrays and base in ROS_ARRAY_TAGS:
                return lambda values, base=base: typed_array(base, values) if len(values) else []
            element = self._field(leaves, base)
            if element is None:
                return list
            return lambda values: [element(v) for v in values]
        if base in FLOAT_TYPES:
            return leaves.floats
        if base in PRIMITIVE_TYPES:
            return None
        if base in TIME_TYPES:
            return _time_dict
        return self._converter(leaves, self._types.message_class(base))

    # ---------------------------------------------------------------- JSON -> ROS
    def from_json(self, cls, value):
        """A new instance of message class ``cls`` filled from the JSON value (a dict)."""
        if not isinstance(value, dict):
            raise CodecError("Expected a JSON object for type %s but received a %s" % (cls._type, type(value)))
        try:
            return self._object_builder(cls)(value)
        except _Mismatch as exc:
            path = ".".join(reversed(exc.path))
            text = "%s message requires a %s for field %s, but got a %s" % (cls._type, exc.expected, path, exc.found)
            raise CodecError(text + (" (%s)" % exc.detail if exc.detail else ""))
        except _UnknownField as exc:
            raise CodecError("Message type %s does not have a field %s" % (cls._type, ".".join(reversed(exc.path))))

    def _object_builder(self, cls):
        build = self._from_json.get(cls)
        if build is None:
            fields = {}
            is_header = cls._type in HEADER_TYPES
            types = self._types

            def build(value):
                msg = cls()
                if is_header:
                    msg.stamp = types.now()
                for name, item in value.items():
                    conv = fields.get(name)
                    if conv is None:
                        raise _UnknownField(name)
                    try:
                        setattr(msg, name, conv(item))
                    except (_Mismatch, _UnknownField) as exc:
                        exc.path.append(name)
                        raise
                return msg
            self._from_json[cls] = build
            # filled after registration so recursive types terminate
            for name, ftype in zip(cls.__slots__, cls._slot_types):
                fields[name] = self._field_parser(ftype)
        return build

    def _field_parser(self, field_type):
        base, length = split_array(field_type)
        if length is not None:
            if base in BINARY_TYPES:
                return self._binary_parser(field_type, length)
            element = self._field_parser(base)

            def parse_list(value):
                if not isinstance(value, (list, tuple)):
                    raise _Mismatch(field_type, type(value))
                if length and len(value) != length:
                    raise _Mismatch(field_type, type(value), "%d elements instead of %d" % (len(value), length))
                return [element(v) for v in value]
            return parse_list
        if base in INT_RANGES:
            low, high = INT_RANGES[base]

            def parse_int(value):
                if type(value) is not int:
                    raise _Mismatch(base, type(value))
                if not low <= value <= high:
                    raise _Mismatch(base, type(value), "%d outside %d..%d" % (value, low, high))
                return value
            return parse_int
        if base in FLOAT_TYPES:
            def parse_float(value):
                if value is None:
                    return float("nan")
                if type(value) not in (int, float):
                    raise _Mismatch(base, type(value))
                return float(value)
            return parse_float
        if base == "bool":
            def parse_bool(value):
                if type(value) is not bool:
                    raise _Mismatch(base, type(value))
                return value
            return parse_bool
        if base == "string":
            def parse_string(value):
                if type(value) is not str:
                    raise _Mismatch(base, type(value))
                return value
            return parse_string
        if base in TIME_TYPES:
            return self._time_parser(base)
        cls = self._types.message_class(base)
        builder = self._object_builder(cls)

        def parse_object(value):
            if not isinstance(value, dict):
                raise _Mismatch(base, type(value))
            return builder(value)
        return parse_object

    @staticmethod
    def _binary_parser(field_type, length):
        def parse_binary(value):
            if isinstance(value, str):
                try:
                    data = base64.b64decode(value, validate=True)
                except (binascii.Error, ValueError):
                    raise _Mismatch(field_type, type(value), "not valid base64")
            elif isinstance(value, (bytes, bytearray)):
                data = bytes(value)
            elif isinstance(value, (list, tuple)):
                if any(type(v) is not int or not 0 <= v <= 255 for v in value):
                    raise _Mismatch(field_type, type(value), "elements must be integers 0..255")
                data = bytes(bytearray(value))
            else:
                raise _Mismatch(field_type, type(value))
            if length and len(data) != length:
                raise _Mismatch(field_type, type(value), "%d bytes instead of %d" % (len(data), length))
            return data
        return parse_binary

    def _time_parser(self, kind):
        types = self._types
        secs_low, secs_high = INT_RANGES["uint32" if kind == "time" else "int32"]

        def parse_time(value):
            if kind == "time" and value == "now":
                return types.now()
            if not isinstance(value, dict):
                raise _Mismatch(kind, type(value))
            parts = []
            for key, low, high in (("secs", secs_low, secs_high), ("nsecs", -2 ** 31, 2 ** 31 - 1)):
                part = value.get(key, 0)
                if type(part) is not int or not low <= part <= high:
                    exc = _Mismatch("int32" if key == "nsecs" or kind == "duration" else "uint32", type(part))
                    exc.path.append(key)
                    raise exc
                parts.append(part)
            unknown = set(value) - {"secs", "nsecs"}
            if unknown:
                raise _UnknownField(sorted(unknown)[0])
            return types.time(*parts) if kind == "time" else types.duration(*parts)
        return parse_time


def _message_converter(cache, field_converter, cls):
    """msg -> dict for ``cls``, compiled once per class and kept in ``cache``; ``field_converter(type)``
    gives each field's conversion (None = the value as is). The output forms differ only there."""
    conv = cache.get(cls)
    if conv is None:
        fields = [(name, field_converter(ftype)) for name, ftype in zip(cls.__slots__, cls._slot_types)]

        def conv(msg):
            return {name: (getattr(msg, name) if f is None else f(getattr(msg, name))) for name, f in fields}
        cache[cls] = conv
    return conv
