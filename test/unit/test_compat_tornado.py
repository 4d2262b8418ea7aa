"""compat_tornado: the tornado internals the bridge's fast paths rely on are there; the fallbacks are public API."""
import pytest
import tornado.websocket

from inspection_robot.bridge import compat_tornado


def test_the_tornado_internals_are_those_the_fast_paths_expect():
    assert compat_tornado.MISSING == [], (
        "tornado %s changed internals that the bridge relies on: %s. It now runs its public-API fallbacks "
        "(a write per message): update bridge/compat_tornado.py"
        % (compat_tornado.VERSION, compat_tornado.MISSING))


class Stream(object):
    def __init__(self):
        self.written = []
        self.closed = False

    def write(self, data):
        self.written.append(data)
        return "future"

    def close(self):
        self.closed = True


class Connection(object):
    def __init__(self, closing=False):
        self.stream = Stream()
        self.closing = closing

    def is_closing(self):
        return self.closing


class Handler(object):
    def __init__(self, connection):
        self.ws_connection = connection
        self.messages = []
        self.closed = False

    def write_message(self, payload, binary=False):
        self.messages.append((payload, binary))
        return "future %d" % len(self.messages)

    def close(self):
        self.closed = True


def test_fast_paths_on_a_connection():
    handler = Handler(Connection())
    assert compat_tornado.write_frames(handler, ["hi", b"\x00"]) == "future"
    assert handler.ws_connection.stream.written == [b"\x81\x02hi\x82\x01\x00"]
    compat_tornado.abort(handler)
    assert handler.ws_connection.stream.closed and not handler.closed
    with pytest.raises(tornado.websocket.WebSocketClosedError):
        compat_tornado.write_frames(Handler(Connection(closing=True)), ["x"])


@pytest.fixture
def old_tornado(monkeypatch):
    for flag in ("RAW_WRITE", "TOO_BIG_REASON"):
        monkeypatch.setattr(compat_tornado, flag, False)


def test_fallbacks_use_the_public_api(old_tornado):
    handler = Handler(Connection())
    assert compat_tornado.write_frames(handler, ["hi", b"\x00"]) == "future 2"
    assert handler.messages == [("hi", False), (b"\x00", True)]
    assert handler.ws_connection.stream.written == []
    compat_tornado.abort(handler)
    assert handler.closed and not handler.ws_connection.stream.closed
    protocol = object()
    assert compat_tornado.name_the_size_limit(protocol, lambda: "why") is protocol


def test_the_size_limit_is_named_in_tornados_own_close():
    closes = []

    class Protocol(object):
        def close(self, code=None, reason=None):
            closes.append((code, reason))
    protocol = compat_tornado.name_the_size_limit(Protocol(), lambda: "over 10 bytes")
    protocol.close(1009, "message too big")
    protocol.close(1000, "bye")
    assert closes == [(1009, "over 10 bytes"), (1000, "bye")]
