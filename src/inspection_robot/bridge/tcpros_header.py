"""TCPROS connection headers (wiki.ros.org/ROS/Connection Header): encoding, parsing, and reading
one from a socket with a bound on its size and on each read's time.

Kept apart from ros_tcpros.py: the codec needs no ROS, so it is pure and its tests (and the
integration tests' hand-made subscribers) use it alone.
"""
import socket
import struct

MAX_HEADER_BYTES = 1 << 20   # a subscriber's header carries its message_definition: a few kB, rarely more
LENGTH = struct.Struct("<I")  # the 4-byte little-endian length before a header, a field or a message


class HeaderError(ValueError):
    """A connection header that is truncated, oversized or malformed."""


def encode_header(fields):
    """A TCPROS connection header: 4-byte little-endian length, then each ``key=value`` with its length."""
    parts = []
    for key, value in fields.items():
        if not key or "=" in key:
            raise HeaderError("bad header field name %r" % (key,))
        field = ("%s=%s" % (key, value)).encode("utf-8")
        parts.append(LENGTH.pack(len(field)))
        parts.append(field)
    body = b"".join(parts)
    return LENGTH.pack(len(body)) + body


def parse_header(body):
    """The fields of a header's body (what follows its 4-byte length); HeaderError when malformed."""
    fields = {}
    pos = 0
    while pos < len(body):
        if pos + 4 > len(body):
            raise HeaderError("header truncated: %d bytes left at byte %d, a field length takes 4"
                              % (len(body) - pos, pos))
        (length,) = LENGTH.unpack_from(body, pos)
        pos += 4
        if pos + length > len(body):
            raise HeaderError("header field of %d bytes at byte %d overruns the %d-byte header"
                              % (length, pos, len(body)))
        key, sep, value = bytes(body[pos:pos + length]).partition(b"=")
        pos += length
        if not sep or not key:
            raise HeaderError("header field %r is not key=value" % (key[:40],))
        try:
            fields[key.decode("utf-8")] = value.decode("utf-8")
        except UnicodeDecodeError:
            raise HeaderError("header field %r is not UTF-8" % (key[:40],))
    return fields


def _recv_exactly(sock, count, what):
    chunks = []
    while count:
        try:
            chunk = sock.recv(min(count, 65536))
        except socket.timeout:
            raise HeaderError("no complete %s within %.1f s" % (what, sock.gettimeout()))
        if not chunk:
            raise HeaderError("connection closed during the %s" % what)
        chunks.append(chunk)
        count -= len(chunk)
    return b"".join(chunks)


def read_header(sock, max_bytes=MAX_HEADER_BYTES):
    """Read one connection header from a blocking socket (its timeout bounds each read)."""
    (length,) = LENGTH.unpack(_recv_exactly(sock, 4, "header length"))
    if length > max_bytes:
        raise HeaderError("header of %d bytes is over the limit of %d" % (length, max_bytes))
    return parse_header(_recv_exactly(sock, length, "header"))
