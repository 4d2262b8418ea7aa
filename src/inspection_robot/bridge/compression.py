"""Outgoing PNG compression and fragmentation, incoming fragment reassembly (rosbridge v2 3.1).

PNG: as rosbridge does it, the UTF-8 JSON text is padded with ``\\n`` to fill a near-square RGB
image, written as an 8-bit PNG (zlib, filter 0) and base64-encoded into ``{"op": "png"}``.
Fragments: the text is cut into ``fragment_size`` pieces sent as ``{"op": "fragment", "id",
"data", "num", "total"}``; :class:`Defragmenter` rebuilds incoming ones, bounded in size (per
message and per connection, counted on every fragment), count and age.
"""
import base64
import math
import struct
import zlib

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
# zlib level of outgoing PNGs: JSON text (base64 blobs, repeated keys) compresses within 1-2 % of
# level 6 (rosbridge's, via PIL) at 1/2-1/3 of the CPU, which on a 1080p image at 10 Hz is the
# difference between keeping up or not. Any zlib level decodes the same.
PNG_LEVEL = 1


def _chunk(kind, payload):
    return (struct.pack(">I", len(payload)) + kind + payload
            + struct.pack(">I", zlib.crc32(kind + payload) & 0xFFFFFFFF))


def png_encode(text):
    """The base64 (ASCII str) PNG image carrying ``text`` as rosbridge's png compression does."""
    raw = text.encode("utf-8")
    pixels = max(1, int(math.ceil(len(raw) / 3.0)))
    width = max(1, int(math.floor(math.sqrt(pixels))))
    height = int(math.ceil(pixels / float(width)))
    raw += b"\n" * (width * height * 3 - len(raw))
    stride = width * 3
    rows = bytearray(height * (stride + 1))  # each row: filter byte 0, then the row's pixels
    view = memoryview(raw)
    for y in range(height):
        start = y * (stride + 1) + 1
        rows[start:start + stride] = view[y * stride:(y + 1) * stride]
    png = (PNG_SIGNATURE
           + _chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
           + _chunk(b"IDAT", zlib.compress(rows, PNG_LEVEL))
           + _chunk(b"IEND", b""))
    return base64.standard_b64encode(png).decode("ascii")


def png_decode(data):
    """Inverse of :func:`png_encode` (8-bit RGB, filter 0 rows only): the text, padding removed."""
    png = base64.standard_b64decode(data)
    if not png.startswith(PNG_SIGNATURE):
        raise ValueError("not a PNG image")
    pos, width, idat = len(PNG_SIGNATURE), None, []
    while pos + 8 <= len(png):
        length, kind = struct.unpack(">I4s", png[pos:pos + 8])
        payload = png[pos + 8:pos + 8 + length]
        pos += 12 + length
        if kind == b"IHDR":
            width, _height, depth, colour = struct.unpack(">IIBB", payload[:10])
            if (depth, colour) != (8, 2):
                raise ValueError("only 8-bit RGB PNGs are supported")
        elif kind == b"IDAT":
            idat.append(payload)
    if width is None:
        raise ValueError("PNG without IHDR")
    rows = zlib.decompress(b"".join(idat))
    stride = width * 3 + 1
    out = []
    for start in range(0, len(rows), stride):
        if rows[start] != 0:
            raise ValueError("unsupported PNG row filter %d" % rows[start])
        out.append(rows[start + 1:start + stride])
    return b"".join(out).rstrip(b"\n").decode("utf-8")


def fragments(text, fragment_size, message_id):
    """The fragment messages (dicts) carrying ``text`` in pieces of ``fragment_size`` characters."""
    size = max(1, int(fragment_size))
    total = (len(text) + size - 1) // size
    return [{"op": "fragment", "id": message_id, "data": text[i * size:(i + 1) * size],
             "num": i, "total": total} for i in range(total)]


class FragmentError(ValueError):
    """An incoming fragment that cannot be accepted."""


def _size(data):
    """Bytes of a fragment's text as it came (UTF-8), cheap for the usual ASCII (base64, JSON)."""
    return len(data) if data.isascii() else len(data.encode("utf-8", "surrogatepass"))


class Defragmenter(object):
    """Collects incoming fragments per id; returns the whole text once every piece arrived.

    ``max_bytes`` bounds one message, ``max_total_bytes`` (default ``max_bytes``) all the messages
    being assembled at once together, ``max_pending`` their count and ``timeout`` (s) how long an
    incomplete message is kept (``clock`` gives seconds). Sizes are counted on every fragment: a
    number that comes again replaces the piece it had (its old size is given back first), so
    repeating numbers never grows what is held. A fragment that would pass a bound is refused and
    its whole message dropped (FragmentError). :meth:`clear` drops everything (the client left).
    """

    def __init__(self, clock, timeout=600.0, max_bytes=10000000, max_pending=16, max_total_bytes=None):
        self._clock = clock
        self._timeout = float(timeout)
        self._max_bytes = int(max_bytes)
        self._max_total = int(max_total_bytes if max_total_bytes is not None else max_bytes)
        self._max_pending = int(max_pending)
        self._pending = {}  # id -> [deadline, total, {num: (data, size)}, size]
        self.held_bytes = 0  # all pending messages' bytes

    @property
    def pending(self):
        return len(self._pending)

    def _drop(self, message_id):
        self.held_bytes -= self._pending.pop(message_id)[3]

    def clear(self):
        self._pending.clear()
        self.held_bytes = 0

    def add(self, message_id, num, total, data):
        """Store one fragment; return the reassembled text when complete, else None."""
        now = self._clock()
        for key in [k for k, v in self._pending.items() if v[0] < now]:
            self._drop(key)
        if total < 1 or not 0 <= num < total:
            raise FragmentError("fragment num %d outside 0..%d" % (num, total - 1))
        entry = self._pending.get(message_id)
        if entry is None:
            if len(self._pending) >= self._max_pending:
                raise FragmentError("too many fragmented messages in progress (max %d)" % self._max_pending)
            entry = self._pending[message_id] = [now + self._timeout, total, {}, 0]
        if entry[1] != total:
            self._drop(message_id)
            raise FragmentError("fragment total changed from %d to %d" % (entry[1], total))
        entry[0] = now + self._timeout
        size = _size(data)
        old = entry[2].get(num)
        grows = size - (old[1] if old is not None else 0)
        if entry[3] + grows > self._max_bytes:
            self._drop(message_id)
            raise FragmentError("fragmented message larger than %d bytes (max_message_size)" % self._max_bytes)
        if self.held_bytes + grows > self._max_total:
            self._drop(message_id)
            raise FragmentError("fragmented messages in progress larger than %d bytes together (max_message_size)"
                                % self._max_total)
        entry[2][num] = (data, size)
        entry[3] += grows
        self.held_bytes += grows
        if len(entry[2]) < total:
            return None
        self._drop(message_id)
        return "".join(entry[2][i][0] for i in range(total))
