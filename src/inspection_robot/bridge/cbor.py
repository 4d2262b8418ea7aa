"""A small CBOR (RFC 7049) encoder and decoder, as rosbridge's ``compression: cbor`` needs it.

Encodes None, bool, int (64-bit range), float (always as float64, so NaN and infinities survive),
str, bytes, list/tuple, dict and :class:`Tagged` values; numeric arrays go out as the
little-endian typed-array tags of draft-ietf-cbor-array-tags, as rosbridge sends them.
The decoder accepts everything the encoder writes plus half/single floats, indefinite lengths and
the typed-array tags (decoded to lists); it raises :class:`CborError` on any malformed input.
"""
import struct

MAX_DEPTH = 64

# typed-array tags (little-endian) -> struct item format
TYPED_ARRAY_FORMATS = {
    64: "B", 68: "B", 69: "<H", 70: "<I", 71: "<Q", 72: "b", 77: "<h", 78: "<i", 79: "<q",
    85: "<f", 86: "<d",
}
# ROS primitive array element type -> typed-array tag (uint8/char go out as byte strings)
ROS_ARRAY_TAGS = {
    "uint16": 69, "uint32": 70, "uint64": 71, "int8": 72, "byte": 72, "int16": 77, "int32": 78,
    "int64": 79, "float32": 85, "float64": 86,
}


class CborError(ValueError):
    """Malformed or unsupported CBOR data."""


class Tagged(object):
    """A tagged CBOR item: ``tag`` number and its ``value``."""

    __slots__ = ("tag", "value")

    def __init__(self, tag, value):
        self.tag = tag
        self.value = value

    def __eq__(self, other):
        return isinstance(other, Tagged) and (self.tag, self.value) == (other.tag, other.value)

    def __repr__(self):
        return "Tagged(%d, %r)" % (self.tag, self.value)


def typed_array(element_type, values):
    """The CBOR typed-array item for a list of ROS numbers of ``element_type`` (e.g. float64)."""
    tag = ROS_ARRAY_TAGS[element_type]
    fmt = TYPED_ARRAY_FORMATS[tag]
    return Tagged(tag, struct.pack("%s%d%s" % (fmt[0] if fmt[0] == "<" else "", len(values), fmt[-1]), *values))


def _head(major, value):
    if value < 24:
        return struct.pack("B", (major << 5) | value)
    if value < 0x100:
        return struct.pack(">BB", (major << 5) | 24, value)
    if value < 0x10000:
        return struct.pack(">BH", (major << 5) | 25, value)
    if value < 0x100000000:
        return struct.pack(">BI", (major << 5) | 26, value)
    if value < 0x10000000000000000:
        return struct.pack(">BQ", (major << 5) | 27, value)
    raise CborError("integer too large for CBOR: %d" % value)


def dumps(obj):
    """Encode ``obj`` as CBOR bytes."""
    out = []
    _encode(obj, out, 0)
    return b"".join(out)


def _encode(obj, out, depth):
    if depth > MAX_DEPTH:
        raise CborError("nesting deeper than %d" % MAX_DEPTH)
    if obj is None:
        out.append(b"\xf6")
    elif obj is True:
        out.append(b"\xf5")
    elif obj is False:
        out.append(b"\xf4")
    elif isinstance(obj, int):
        out.append(_head(0, obj) if obj >= 0 else _head(1, -1 - obj))
    elif isinstance(obj, float):
        out.append(b"\xfb" + struct.pack(">d", obj))
    elif isinstance(obj, str):
        data = obj.encode("utf-8")
        out.append(_head(3, len(data)))
        out.append(data)
    elif isinstance(obj, (bytes, bytearray, memoryview)):
        data = bytes(obj)
        out.append(_head(2, len(data)))
        out.append(data)
    elif isinstance(obj, (list, tuple)):
        out.append(_head(4, len(obj)))
        for item in obj:
            _encode(item, out, depth + 1)
    elif isinstance(obj, dict):
        out.append(_head(5, len(obj)))
        for key, value in obj.items():
            _encode(key, out, depth + 1)
            _encode(value, out, depth + 1)
    elif isinstance(obj, Tagged):
        out.append(_head(6, obj.tag))
        _encode(obj.value, out, depth + 1)
    else:
        raise CborError("cannot encode %s as CBOR" % type(obj).__name__)


def loads(data):
    """Decode one CBOR item that spans all of ``data``."""
    decoder = _Decoder(bytes(data))
    value = decoder.item(0)
    if decoder.pos != len(data):
        raise CborError("%d trailing bytes after the CBOR item" % (len(data) - decoder.pos))
    return value


_BREAK = object()


class _Decoder(object):
    def __init__(self, data):
        self.data = data
        self.pos = 0

    def take(self, n):
        end = self.pos + n
        if end > len(self.data):
            raise CborError("truncated CBOR data")
        chunk = self.data[self.pos:end]
        self.pos = end
        return chunk

    def argument(self, info):
        if info < 24:
            return info
        if info == 24:
            return self.take(1)[0]
        if info == 25:
            return struct.unpack(">H", self.take(2))[0]
        if info == 26:
            return struct.unpack(">I", self.take(4))[0]
        if info == 27:
            return struct.unpack(">Q", self.take(8))[0]
        raise CborError("reserved additional information %d" % info)

    def item(self, depth, allow_break=False):
        if depth > MAX_DEPTH:
            raise CborError("nesting deeper than %d" % MAX_DEPTH)
        initial = self.take(1)[0]
        major, info = initial >> 5, initial & 0x1F
        if major == 7:
            return self.simple(info, allow_break)
        if info == 31:
            return self.indefinite(major, depth)
        arg = self.argument(info)
        if major == 0:
            return arg
        if major == 1:
            return -1 - arg
        if major == 2:
            return self.take(arg)
        if major == 3:
            return self.text(self.take(arg))
        if major == 4:
            self.check_count(arg)
            return [self.item(depth + 1) for _ in range(arg)]
        if major == 5:
            self.check_count(arg)
            result = {}
            for _ in range(arg):
                key = self.item(depth + 1)
                result[self.hashable(key)] = self.item(depth + 1)
            return result
        return self.tagged(arg, self.item(depth + 1))

    def check_count(self, count):
        if count > len(self.data) - self.pos:  # every item takes at least one byte
            raise CborError("truncated CBOR data")

    @staticmethod
    def hashable(key):
        try:
            hash(key)
        except TypeError:
            raise CborError("unhashable map key of type %s" % type(key).__name__)
        return key

    @staticmethod
    def text(raw):
        try:
            return raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise CborError("invalid UTF-8 in text string: %s" % exc)

    def simple(self, info, allow_break):
        if info == 20:
            return False
        if info == 21:
            return True
        if info in (22, 23):
            return None
        if info == 25:
            return _half(self.take(2))
        if info == 26:
            return struct.unpack(">f", self.take(4))[0]
        if info == 27:
            return struct.unpack(">d", self.take(8))[0]
        if info == 31 and allow_break:
            return _BREAK
        if info < 24:
            return None  # unassigned simple values carry no meaning here
        raise CborError("unsupported simple value %d" % info)

    def indefinite(self, major, depth):
        if major in (2, 3):
            chunks = []
            while True:
                chunk = self.item(depth + 1, allow_break=True)
                if chunk is _BREAK:
                    break
                if not isinstance(chunk, bytes if major == 2 else str):
                    raise CborError("bad chunk in an indefinite-length string")
                chunks.append(chunk)
            return (b"" if major == 2 else "").join(chunks)
        if major == 4:
            items = []
            while True:
                value = self.item(depth + 1, allow_break=True)
                if value is _BREAK:
                    return items
                items.append(value)
        if major == 5:
            result = {}
            while True:
                key = self.item(depth + 1, allow_break=True)
                if key is _BREAK:
                    return result
                result[self.hashable(key)] = self.item(depth + 1)
        raise CborError("indefinite length not allowed for major type %d" % major)

    @staticmethod
    def tagged(tag, value):
        fmt = TYPED_ARRAY_FORMATS.get(tag)
        if fmt is None:
            return value  # other tags (dates, bignums...) keep their plain content
        if not isinstance(value, bytes):
            raise CborError("typed-array tag %d needs a byte string" % tag)
        size = struct.calcsize(fmt)
        if len(value) % size:
            raise CborError("typed-array tag %d: %d bytes is not a multiple of %d" % (tag, len(value), size))
        return list(struct.unpack("%s%d%s" % ("<" if fmt[0] == "<" else "", len(value) // size, fmt[-1]), value))


def _half(raw):
    bits = struct.unpack(">H", raw)[0]
    sign = -1.0 if bits & 0x8000 else 1.0
    exponent = (bits >> 10) & 0x1F
    fraction = bits & 0x3FF
    if exponent == 0:
        return sign * fraction * 2.0 ** -24
    if exponent == 31:
        return sign * float("inf") if fraction == 0 else float("nan")
    return sign * (1 + fraction / 1024.0) * 2.0 ** (exponent - 15)
