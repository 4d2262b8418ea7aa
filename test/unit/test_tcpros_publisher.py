"""bridge/ros_tcpros.py (with tcpros_header, tcpros_publication, tcpros_slave) on real sockets on 127.0.0.1,
a recording master instead of a roscore.

Headers (encode, parse, truncated, oversized, malformed), the handshake's answers (md5sum and type
mismatch, unknown topic, a silent client), the slave API, latched and early messages, and the
publishing path: in order, never blocked by a subscriber that does not read, bounded per connection.
"""
import socket
import struct
import threading
import time
import xmlrpc.client

import pytest
from std_msgs.msg import Header, String

from inspection_robot.bridge import tcpros_header, tcpros_publication
from inspection_robot.bridge.ros_tcpros import TcprosPublisher
from inspection_robot.bridge.tcpros_header import HeaderError, encode_header, parse_header, read_header


def wait_for(condition, timeout=5.0, what="condition"):
    deadline = time.monotonic() + timeout
    while True:
        value = condition()
        if value:
            return value
        assert time.monotonic() < deadline, "timed out waiting for " + what
        time.sleep(0.002)


class RecordingMaster(object):
    def __init__(self, subscribers=()):
        self.calls = []
        self.subscribers = list(subscribers)   # the slave URIs registerPublisher answers

    def registerPublisher(self, topic, type_name, uri):
        self.calls.append(("register", topic, type_name, uri))
        return list(self.subscribers)

    def unregisterPublisher(self, topic, uri):
        self.calls.append(("unregister", topic, uri))
        return 1

    def getUri(self):
        return "http://master:11311/"


@pytest.fixture
def publisher():
    logs = []
    pub = TcprosPublisher("/bridge/tcpros", RecordingMaster(), host="127.0.0.1", bind_address="127.0.0.1",
                          log=lambda level, text: logs.append((level, text)), handshake_timeout=0.5)
    pub.logs = logs
    yield pub
    pub.close()


def subscriber_header(topic="/chatter", md5sum=String._md5sum, type_name="std_msgs/String", callerid="/listener"):
    return {"callerid": callerid, "topic": topic, "md5sum": md5sum, "type": type_name, "tcp_nodelay": "1",
            "message_definition": String._full_text}


def connect(publisher, header=None):
    """A raw TCPROS subscriber: (socket, the publisher's reply header)."""
    sock = socket.create_connection(("127.0.0.1", publisher.port), timeout=30)
    sock.sendall(encode_header(header or subscriber_header()))
    return sock, read_header(sock)


def read_frames(sock, count):
    messages = []
    for _ in range(count):
        (length,) = struct.unpack("<I", tcpros_header._recv_exactly(sock, 4, "frame"))
        msg = String()
        msg.deserialize(tcpros_header._recv_exactly(sock, length, "frame"))
        messages.append(msg.data)
    return messages


def test_header_round_trip_is_the_wire_format():
    wire = encode_header({"topic": "/a", "md5sum": "*"})
    assert wire == b"\x18\x00\x00\x00\x08\x00\x00\x00topic=/a\x08\x00\x00\x00md5sum=*"
    assert parse_header(wire[4:]) == {"topic": "/a", "md5sum": "*"}
    assert parse_header(encode_header({"message_definition": "a=b\nc"})[4:]) == {"message_definition": "a=b\nc"}


@pytest.mark.parametrize("body, error", [
    (b"\x08\x00", "truncated"),
    (b"\x20\x00\x00\x00topic=/a", "overruns"),
    (b"\x05\x00\x00\x00topic", "not key=value"),
    (b"\x03\x00\x00\x00=/a", "not key=value"),
    (b"\x03\x00\x00\x00a=\xff", "not UTF-8"),
])
def test_a_malformed_header_is_a_clear_error(body, error):
    with pytest.raises(HeaderError, match=error):
        parse_header(body)


def test_read_header_refuses_oversized_truncated_and_silent_peers():
    ours, peer = socket.socketpair()
    ours.settimeout(0.2)
    peer.sendall(struct.pack("<I", tcpros_header.MAX_HEADER_BYTES + 1))
    with pytest.raises(HeaderError, match="over the limit"):
        read_header(ours)
    peer.sendall(b"\x10\x00\x00\x00abc")
    with pytest.raises(HeaderError, match="no complete header within 0.2 s"):
        read_header(ours)
    peer.close()
    with pytest.raises(HeaderError, match="closed during the header length"):
        read_header(ours)
    ours.close()


def test_the_handshake_answers_as_rospy_and_refuses_a_wrong_md5sum(publisher):
    publisher.advertise("/chatter", String, latch=False, queue_size=10)
    assert publisher._master.calls == [("register", "/chatter", "std_msgs/String", publisher.uri)]
    sock, reply = connect(publisher)
    assert reply == {"callerid": "/bridge/tcpros", "md5sum": String._md5sum, "type": "std_msgs/String",
                     "latching": "0", "message_definition": String._full_text, "topic": "/chatter"}
    sock.close()
    sock, reply = connect(publisher, subscriber_header(md5sum="0" * 32))
    assert "wants topic [/chatter] to have datatype/md5sum [std_msgs/String/" + "0" * 32 in reply["error"]
    assert sock.recv(1) == b""  # and closed
    sock, reply = connect(publisher, subscriber_header(md5sum="0" * 32, type_name="std_msgs/Int32"))
    assert reply == {"error": "topic types do not match: [std_msgs/Int32] vs. [std_msgs/String]"}
    sock, reply = connect(publisher, subscriber_header(topic="/other"))
    assert reply["error"].startswith("[/bridge/tcpros] is not a publisher of [/other]")
    sock, reply = connect(publisher, {"topic": "/chatter", "md5sum": "*"})
    assert reply == {"error": "Missing required 'callerid' field"}
    sock, reply = connect(publisher, subscriber_header(md5sum="*", type_name="*"))  # rostopic echo
    assert reply["md5sum"] == String._md5sum


def test_a_silent_client_does_not_hold_up_the_next(publisher):
    publisher.advertise("/chatter", String)
    silent = socket.create_connection(("127.0.0.1", publisher.port))
    sock, reply = connect(publisher)
    assert reply["topic"] == "/chatter"
    assert silent.recv(1) == b""  # dropped after handshake_timeout
    wait_for(lambda: any("no complete header length within 0.5 s" in text for _level, text in publisher.logs))


def test_messages_arrive_in_order_with_header_seq(publisher):
    from geometry_msgs.msg import PointStamped
    points = publisher.advertise("/point", PointStamped)
    sock, _reply = connect(publisher, {"callerid": "/l", "topic": "/point", "md5sum": PointStamped._md5sum})
    wait_for(lambda: points.num_connections())
    points.publish([PointStamped(header=Header(frame_id="map")) for _ in range(3)])
    for seq in (1, 2, 3):
        (length,) = struct.unpack("<I", tcpros_header._recv_exactly(sock, 4, "frame"))
        msg = PointStamped().deserialize(tcpros_header._recv_exactly(sock, length, "frame"))
        assert (msg.header.seq, msg.header.frame_id) == (seq, "map")


def test_latched_and_early_messages_reach_a_late_subscriber(publisher, monkeypatch):
    latched = publisher.advertise("/latched", String, latch=True)
    early = publisher.advertise("/chatter", String)
    early.publish([String("e1"), String("e2")])
    latched.publish([String("old"), String("last")])
    sock, reply = connect(publisher, subscriber_header(topic="/latched"))
    assert reply["latching"] == "1"
    assert read_frames(sock, 2) == ["old", "last"]  # both in the early window (the latched one is its last)
    sock, _ = connect(publisher)
    assert read_frames(sock, 2) == ["e1", "e2"]
    monkeypatch.setattr(tcpros_publication, "EARLY_WINDOW_S", 0.0)
    sock, _ = connect(publisher, subscriber_header(topic="/latched"))
    assert read_frames(sock, 1) == ["last"]
    sock.settimeout(0.2)
    with pytest.raises(socket.timeout):
        sock.recv(1)  # nothing else


def test_early_messages_wait_for_the_subscribers_the_master_listed(monkeypatch):
    monkeypatch.setattr(tcpros_publication, "EARLY_WINDOW_S", 0.0)   # a loaded machine: they connect after it
    pub = TcprosPublisher("/bridge/tcpros", RecordingMaster(["http://a:1/", "http://b:2/"]), host="127.0.0.1",
                          bind_address="127.0.0.1", handshake_timeout=0.5)
    try:
        topic = pub.advertise("/chatter", String)
        topic.publish([String("e1")])
        first, _ = connect(pub, subscriber_header(callerid="/a"))
        assert read_frames(first, 1) == ["e1"]
        topic.publish([String("e2")])
        assert read_frames(first, 1) == ["e2"]
        second, _ = connect(pub, subscriber_header(callerid="/b"))
        assert read_frames(second, 2) == ["e1", "e2"]   # the second one listed gets them too
        late, _ = connect(pub, subscriber_header(callerid="/c"))
        late.settimeout(0.2)
        with pytest.raises(socket.timeout):
            late.recv(1)   # every subscriber listed has connected: no more early messages
        assert topic.early == [] or not topic.early_open()
        monkeypatch.setattr(tcpros_publication, "EARLY_WAIT_MAX_S", 0.0)   # the wait is bounded
        other = pub.advertise("/other", String)
        other.publish([String("x")])
        assert not other.early_open() and other.awaited == 2
    finally:
        pub.close()


def test_a_subscriber_that_never_reads_blocks_neither_the_caller_nor_the_others(publisher):
    topic = publisher.advertise("/chatter", String, queue_size=1000)
    stuck = socket.socket()
    stuck.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # before connecting: a small window
    stuck.connect(("127.0.0.1", publisher.port))
    stuck.sendall(encode_header(subscriber_header(callerid="/stuck")))
    read_header(stuck)
    reader, _ = connect(publisher)
    wait_for(lambda: topic.num_connections() == 2)
    received = []
    thread = threading.Thread(target=lambda: received.extend(read_frames(reader, 3000)), daemon=True)
    thread.start()
    payload = "x" * 2000
    started = time.monotonic()
    for i in range(3000):  # 6 MB: more than the stuck one's socket buffers hold
        topic.publish([String("%d %s" % (i, payload))])
    assert time.monotonic() - started < 10.0
    thread.join(30)
    assert [m.split()[0] for m in received] == [str(i) for i in range(3000)]
    assert topic.queue_depth() == 1000  # the stuck one's queue, bounded: its oldest dropped and logged
    assert any("/stuck does not keep up: dropped its" in text for _level, text in publisher.logs)
    stuck.close()  # a peer that closes is dropped without another publish
    wait_for(lambda: topic.num_connections() == 1, what="the closed subscriber dropped")
    assert topic.queue_depth() == 0


def test_slave_api_and_unadvertise(publisher):
    topic = publisher.advertise("/chatter", String)
    api = xmlrpc.client.ServerProxy(publisher.uri)
    ready = [1, "ready on 127.0.0.1:%d" % publisher.port, ["TCPROS", "127.0.0.1", publisher.port]]
    assert api.requestTopic("/x", "/chatter", [["TCPROS"]]) == ready
    assert api.requestTopic("/x", "/other", [["TCPROS"]])[0] == -1
    assert api.requestTopic("/x", "/chatter", [["UDPROS"]])[0] == 0
    assert api.getPublications("/x") == [1, "publications", [["/chatter", "std_msgs/String"]]]
    assert api.getSubscriptions("/x") == [1, "subscriptions", []]
    assert api.getMasterUri("/x") == [1, "", "http://master:11311/"]
    assert api.getPid("/x")[2] > 0
    sock, _ = connect(publisher)
    wait_for(lambda: topic.num_connections())
    topic.publish([String("a")])
    read_frames(sock, 1)
    (info,) = api.getBusInfo("/x")[2]
    assert info[1:6] == ["/listener", "o", "TCPROS", "/chatter", True]
    stats = api.getBusStats("/x")[2][0]
    assert stats[0][0] == "/chatter" and stats[0][2][0][2] == 1
    assert publisher.advertise("/chatter", String) is topic  # a second advertise shares it
    publisher.unadvertise(topic)
    assert publisher._master.calls[-1][0] == "register"
    publisher.unadvertise(topic)
    assert publisher._master.calls[-1] == ("unregister", "/chatter", publisher.uri)
    assert sock.recv(1) == b""
    with pytest.raises(RuntimeError, match="unadvertised"):
        topic.publish([String("late")])
    assert api.getPublications("/x") == [1, "publications", []]
