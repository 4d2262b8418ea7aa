"""The one place that touches tornado's websocket internals (the bridge's transport, server.py and handler.py).

tornado's public websocket API writes one message per call (a future, a frame header built in
Python, a try at the socket each). The bridge needs three things it does not offer; each is
checked once, at import, by reading the names tornado's own constructors assign (nothing is
built), and falls back to the public API when they differ:

- :func:`write_frames`: many messages as ready-made frames (:func:`ws_frame`) in one write on the
  connection's stream. Fallback: WebSocketHandler.write_message per message.
- :func:`abort`: close the socket now, with no close handshake. Fallback: WebSocketHandler.close.
- :func:`limit_unsent`: bound the bytes the kernel holds unsent for a client (the connection's
  socket). Fallback: the kernel's default (no bound).
- :func:`name_the_size_limit`: the close tornado itself sends for an oversized frame (1009, "message
  too big") carries a reason naming the limit. Fallback: tornado's own reason.
- :func:`set_frame_limit`: change one connection's frame size limit while it is open (tornado reads
  it from the connection's params before it buffers each frame's payload), so an unauthenticated
  client may send only small frames. Fallback: the application's limit for every frame.

``MISSING`` lists what was not found; test_compat_tornado fails loudly, naming tornado's version,
when it is not empty.
"""
import socket
import struct

import tornado
import tornado.iostream
import tornado.websocket

CLOSE_TOO_BIG = 1009  # websocket close code (RFC 6455 7.4.1)


def _assigned(function):
    """Attribute names a function's code uses (what a constructor assigns appears here)."""
    return set(getattr(getattr(function, "__code__", None), "co_names", ()))


def _missing(what, names, available):
    return ["%s.%s" % (what, name) for name in names if name not in available]


def _check():
    handler = tornado.websocket.WebSocketHandler
    protocol = tornado.websocket.WebSocketProtocol
    protocol13 = getattr(tornado.websocket, "WebSocketProtocol13", None)
    connection = (_missing("WebSocketHandler", ["ws_connection"], _assigned(handler.__init__))
                  + _missing("WebSocketProtocol", ["stream"], _assigned(protocol.__init__))
                  + _missing("WebSocketProtocol", ["is_closing"], set(dir(protocol))))
    receive = getattr(protocol13, "_receive_frame", None)
    receive_names = _assigned(receive)
    return {
        "frame_limit": (_missing("WebSocketProtocol13", ["params"], _assigned(getattr(protocol13, "__init__", None)))
                        + _missing("WebSocketProtocol13._receive_frame", ["params", "max_message_size"],
                                   receive_names)),
        "write_frames": connection + _missing("BaseIOStream", ["write", "close"],
                                              set(dir(tornado.iostream.BaseIOStream))),
        "too_big_reason": (_missing("WebSocketHandler", ["get_websocket_protocol"], set(dir(handler)))
                           + _missing("WebSocketProtocol13._receive_frame", ["close(%d)" % CLOSE_TOO_BIG],
                                      {"close(%d)" % CLOSE_TOO_BIG}
                                      if CLOSE_TOO_BIG in getattr(getattr(receive, "__code__", None), "co_consts", ())
                                      else set())),
    }


_CHECKED = _check()
MISSING = sorted(set(name for names in _CHECKED.values() for name in names))
RAW_WRITE = not _CHECKED["write_frames"]
TOO_BIG_REASON = not _CHECKED["too_big_reason"]
FRAME_LIMIT = not _CHECKED["frame_limit"]
VERSION = tornado.version


def describe():
    """One line for a node's log: which fast paths run, and what is missing for the others."""
    if not MISSING:
        return "tornado %s internals as expected: every fast path on" % VERSION
    return "tornado %s internals differ (missing %s): public-API fallbacks in use" % (VERSION, ", ".join(MISSING))


def ws_frame(payload):
    """An unmasked, final websocket frame: text for str, binary for bytes (RFC 6455 5.2)."""
    if isinstance(payload, str):
        payload = payload.encode("utf-8")
        first = 0x81
    else:
        first = 0x82
    size = len(payload)
    if size < 126:
        header = struct.pack("!BB", first, size)
    elif size <= 0xFFFF:
        header = struct.pack("!BBH", first, 126, size)
    else:
        header = struct.pack("!BBQ", first, 127, size)
    return header + payload


def write_frames(handler, payloads):
    """Send ``payloads`` (str: text, bytes: binary messages) in order; the future of the write.

    Raises WebSocketClosedError when the connection is gone or closing (as write_message does).
    Fast path: one write of ready-made frames (no compression, the server's frames are unmasked).
    """
    if not RAW_WRITE:
        future = None
        for payload in payloads:
            future = handler.write_message(payload, binary=isinstance(payload, bytes))
        return future
    connection = handler.ws_connection
    if connection is None or connection.is_closing():
        raise tornado.websocket.WebSocketClosedError()
    data = ws_frame(payloads[0]) if len(payloads) == 1 else b"".join(ws_frame(payload) for payload in payloads)
    return connection.stream.write(data)


def abort(handler):
    """Close the socket now, without a close handshake (the peer is not answering)."""
    connection = handler.ws_connection
    if RAW_WRITE and connection is not None and getattr(connection, "stream", None) is not None:
        connection.stream.close()
    else:
        handler.close()


def limit_unsent(handler, nbytes):
    """Let the kernel hold at most about ``nbytes`` of this client's data not yet sent (Linux
    TCP_NOTSENT_LOWAT): past that, writes wait in the bridge, where a subscription's queue_length
    can still replace them. True when set."""
    option = getattr(socket, "TCP_NOTSENT_LOWAT", None)
    stream = getattr(handler.ws_connection, "stream", None) if RAW_WRITE else None
    sock = getattr(stream, "socket", None)
    if option is None or sock is None:
        return False
    try:
        sock.setsockopt(socket.IPPROTO_TCP, option, int(nbytes))
    except OSError:
        return False
    return True


def name_the_size_limit(protocol, reason_for_too_big):
    """Make the close tornado sends for an oversized frame (1009) carry ``reason_for_too_big()``
    (a str, or None for tornado's own); ``protocol`` is what get_websocket_protocol returned."""
    if not TOO_BIG_REASON or protocol is None:
        return protocol
    close = protocol.close

    def close_with_reason(code=None, reason=None):
        if code == CLOSE_TOO_BIG:
            reason = reason_for_too_big() or reason
        close(code, reason)
    protocol.close = close_with_reason
    return protocol


def set_frame_limit(handler, nbytes):
    """Frames over ``nbytes`` (announced in their header) close this connection with 1009 before their
    payload is read; True when set (tornado reads ``params.max_message_size`` for every frame)."""
    params = getattr(handler.ws_connection, "params", None) if FRAME_LIMIT else None
    if params is None or not hasattr(params, "max_message_size"):
        return False
    params.max_message_size = int(nbytes)
    return True
