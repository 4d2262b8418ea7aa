"""protocol.Session against an in-memory backend: every op, errors as status, throttling, auth, cleanup."""
import hashlib
import json

import genpy

from bridge_fakes import FakeBackend, Harness
from inspection_robot.bridge import cbor
from inspection_robot.bridge.compression import fragments, png_decode
from inspection_robot.bridge.access import Authenticator, FailureLimiter, Peer
from inspection_robot.bridge.ops import OPS
from inspection_robot.bridge.protocol import LOG_PERIOD, SessionConfig
from inspection_robot.bridge.session_topics import Outgoing


def outgoing(backend, topic, text):
    cls = backend.types.message_class("std_msgs/String")
    return Outgoing(topic, cls(data=text), backend.codec)


def errors(messages):
    return [m for m in messages if m["op"] == "status" and m["level"] == "error"]


def test_advertise_publish_unadvertise():
    h = Harness()
    h.send({"op": "advertise", "id": "a1", "topic": "/t", "type": "std_msgs/String"})
    h.send({"op": "publish", "id": "p1", "topic": "/t", "msg": {"data": "hello"}})
    assert h.messages() == []
    assert h.backend.published[0][0] == "/t" and h.backend.published[0][1].data == "hello"
    h.send({"op": "unadvertise", "id": "a1", "topic": "/t"})
    assert "/t" not in h.backend.publishers


def test_publish_without_advertise_infers_the_type_or_fails():
    h = Harness()
    h.send({"op": "publish", "topic": "/known", "msg": {"data": "x"}})
    assert h.backend.published[0][1].data == "x"
    h.send({"op": "publish", "id": 7, "topic": "/unknown", "msg": {}})
    (err,) = errors(h.messages())
    assert err["id"] == 7 and "Cannot infer topic type" in err["msg"] and err["msg"].startswith("publish:")


def test_publish_type_errors_are_reported_with_id():
    h = Harness()
    h.send({"op": "advertise", "topic": "/t", "type": "std_msgs/String"})
    h.send({"op": "publish", "id": "bad", "topic": "/t", "msg": {"data": 5}})
    (err,) = errors(h.messages())
    assert err == {"op": "status", "level": "error", "id": "bad",
                   "msg": "publish: std_msgs/String message requires a string for field data, but got a <class 'int'>"}


def test_type_conflict_and_unknown_type():
    h = Harness()
    h.send({"op": "advertise", "id": 1, "topic": "/known", "type": "std_msgs/Int32"})
    h.send({"op": "advertise", "id": 2, "topic": "/x", "type": "no_such_pkg/Nope"})
    first, second = errors(h.messages())
    assert first["id"] == 1 and "already established with type std_msgs/String" in first["msg"]
    assert second["id"] == 2 and "no_such_pkg/Nope" in second["msg"]


def test_subscribe_delivers_json_once_per_client_and_unsubscribe_by_id():
    h = Harness()
    h.send({"op": "subscribe", "id": "s1", "topic": "/known"})
    h.send({"op": "subscribe", "id": "s2", "topic": "/known", "type": "std_msgs/String"})
    h.session.deliver(outgoing(h.backend, "/known", "a"))
    assert h.messages() == [{"op": "publish", "topic": "/known", "msg": {"data": "a"}}]
    h.send({"op": "unsubscribe", "id": "s1", "topic": "/known"})
    assert "/known" in h.backend.subscribers
    h.send({"op": "unsubscribe", "id": "s2", "topic": "/known"})
    assert "/known" not in h.backend.subscribers
    h.session.deliver(outgoing(h.backend, "/known", "b"))
    assert h.messages() == []


def test_subscribe_cbor_png_and_fragments():
    h = Harness()
    h.send({"op": "subscribe", "topic": "/known", "compression": "cbor"})
    h.session.deliver(outgoing(h.backend, "/known", "c"))
    (frame,) = h.sent.pop()
    assert isinstance(frame, bytes) and cbor.loads(frame) == {"op": "publish", "topic": "/known", "msg": {"data": "c"}}
    h.send({"op": "subscribe", "topic": "/p", "type": "std_msgs/String", "compression": "png"})
    h.session.deliver(outgoing(h.backend, "/p", "png me"))
    (png,) = h.messages()
    assert png["op"] == "png"
    assert json.loads(png_decode(png["data"])) == {"op": "publish", "topic": "/p", "msg": {"data": "png me"}}
    h.send({"op": "subscribe", "topic": "/f", "type": "std_msgs/String", "fragment_size": 10})
    h.session.deliver(outgoing(h.backend, "/f", "x" * 40))
    parts = h.messages()
    assert all(p["op"] == "fragment" for p in parts) and len(parts) == parts[0]["total"] > 1
    text = "".join(p["data"] for p in sorted(parts, key=lambda p: p["num"]))
    assert json.loads(text)["msg"]["data"] == "x" * 40


def test_throttle_rate_without_queue_drops_messages_inside_the_interval():
    h = Harness()
    h.send({"op": "subscribe", "topic": "/known", "throttle_rate": 100})
    for i in range(10):
        h.session.deliver(outgoing(h.backend, "/known", str(i)))
        h.advance(0.03)
    got = [m["msg"]["data"] for m in h.messages()]
    assert got == ["0", "4", "8"]


def test_throttle_rate_with_queue_length_keeps_the_newest():
    h = Harness()
    h.send({"op": "subscribe", "topic": "/known", "throttle_rate": 100, "queue_length": 2})
    for i in range(10):
        h.session.deliver(outgoing(h.backend, "/known", str(i)))
    h.advance(0.0)
    assert [m["msg"]["data"] for m in h.messages()] == ["8"]  # the queue of 2 kept 8 and 9
    h.advance(0.05)
    assert h.messages() == []
    h.advance(0.05)
    assert [m["msg"]["data"] for m in h.messages()] == ["9"]
    h.session.deliver(outgoing(h.backend, "/known", "10"))
    h.advance(0.05)
    assert h.messages() == []
    h.advance(0.05)
    assert [m["msg"]["data"] for m in h.messages()] == ["10"]


def test_call_service_dict_and_list_args_and_failure():
    h = Harness()
    h.send({"op": "call_service", "id": "c1", "service": "/echo", "args": {"a": 1}})
    h.send({"op": "call_service", "id": "c2", "service": "/missing", "args": [1, 2]})
    ok, status, failed = h.messages()
    assert ok == {"op": "service_response", "service": "/echo", "values": {"echo": {"a": 1}}, "result": True,
                  "id": "c1"}
    assert status["level"] == "error" and status["id"] == "c2"
    assert failed["result"] is False and "does not exist" in failed["values"] and failed["id"] == "c2"
    assert h.backend.calls[1] == ("/missing", [1, 2])


def test_call_service_timeout_fails_the_call_and_drops_the_late_response():
    h = Harness()
    h.send({"op": "call_service", "id": "t1", "service": "/slow", "args": {}, "timeout": 0.5})
    h.advance(0.4)
    assert h.messages() == []
    h.advance(0.2)
    status, failed = h.messages()
    assert status["level"] == "error" and status["id"] == "t1"
    assert failed["op"] == "service_response" and failed["result"] is False and failed["id"] == "t1"
    assert "Timeout" in failed["values"]
    h.backend.pending.pop()(True, {"late": 1})
    assert h.messages() == []
    # answered in time: the timer is cancelled, nothing more follows
    h.send({"op": "call_service", "id": "t2", "service": "/slow", "timeout": 1})
    h.backend.pending.pop()(True, {"x": 1})
    h.advance(2.0)
    assert [(m["id"], m["result"]) for m in h.messages()] == [("t2", True)]
    # no timeout given: the call waits as long as the backend does
    h.send({"op": "call_service", "id": "t3", "service": "/slow"})
    h.advance(1000.0)
    assert h.messages() == []
    h.backend.pending.pop()(True, {})
    assert h.messages()[0]["id"] == "t3"


def test_call_service_rejects_a_bad_timeout():
    h = Harness()
    for i, timeout in enumerate((0, -1, "soon", True)):
        h.send({"op": "call_service", "id": "b%d" % i, "service": "/echo", "timeout": timeout})
        status, = h.messages()
        assert status["op"] == "status" and status["level"] == "error" and status["id"] == "b%d" % i
    assert h.backend.calls == [] and h.timers == []


def test_advertised_service_round_trip_and_cleanup_on_close():
    h = Harness()
    h.send({"op": "advertise_service", "service": "/svc", "type": "inspection_robot/ControlService"})
    answers = []
    h.session.request("/svc", {"cmd": "x"}, lambda ok, values: answers.append((ok, values)))
    (request,) = h.messages()
    assert request["op"] == "call_service" and request["args"] == {"cmd": "x"}
    h.send({"op": "service_response", "id": request["id"], "service": "/svc", "values": {"ack": "success"},
            "result": True})
    assert answers == [(True, {"ack": "success"})]
    h.send({"op": "service_response", "id": "nope", "service": "/svc", "values": {}, "result": True})
    assert "No pending call" in errors(h.messages())[0]["msg"]
    h.session.request("/svc", {}, lambda ok, values: answers.append((ok, values)))
    h.send({"op": "advertise", "topic": "/t", "type": "std_msgs/String"})
    h.send({"op": "subscribe", "topic": "/known"})
    h.session.close()
    assert answers[-1][0] is False and "disconnected" in answers[-1][1]
    assert h.backend.services == {} and h.backend.publishers == {} and h.backend.subscribers == {}


def test_malformed_frames_get_error_status_and_session_keeps_working():
    h = Harness()
    for frame in ["{not json", "[1, 2]", json.dumps({"id": "x"}), json.dumps({"op": "dance", "id": 3}),
                  json.dumps({"op": "subscribe", "id": 4}), json.dumps({"op": "subscribe", "topic": 5, "id": 5}),
                  b"\xff\x00", json.dumps({"op": "subscribe", "topic": "/known", "compression": "zip"})]:
        h.send(frame)
    errs = errors(h.messages())
    assert len(errs) == 8
    assert "Unknown operation: dance" in errs[3]["msg"] and errs[3]["id"] == 3
    assert errs[4]["msg"] == "subscribe: Expected a topic field but none was found." and errs[4]["id"] == 4
    assert "Expected field topic to be str" in errs[5]["msg"]
    h.send({"op": "publish", "topic": "/known", "msg": {"data": "still fine"}})
    assert h.backend.published[-1][1].data == "still fine"


def test_set_level_filters_warnings():
    h = Harness()
    h.send({"op": "unsubscribe", "topic": "/nothing"})
    assert h.messages() == []  # a warning, below the default level "error"
    h.send({"op": "set_level", "level": "warning"})
    h.send({"op": "unsubscribe", "topic": "/nothing", "id": "u"})
    (warning,) = h.messages()
    assert warning["level"] == "warning" and warning["id"] == "u"
    h.send({"op": "set_level", "level": "none"})
    h.send({"op": "dance"})
    assert h.messages() == []


def test_incoming_fragments_are_reassembled():
    h = Harness()
    text = json.dumps({"op": "publish", "topic": "/known", "msg": {"data": "y" * 100}})
    parts = fragments(text, 17, "frag-1")
    for part in reversed(parts):
        h.send(part)
    assert h.backend.published[-1][1].data == "y" * 100
    h.send({"op": "fragment", "id": "z", "data": "a", "num": 3, "total": 2})
    assert "outside" in errors(h.messages())[0]["msg"]


def test_cbor_request_frames_are_accepted():
    h = Harness()
    h.send(cbor.dumps({"op": "publish", "topic": "/known", "msg": {"data": "from cbor"}}))
    assert h.backend.published[-1][1].data == "from cbor"


REMOTE = Peer("10.1.2.3", False)


def auth_config(limiter=None):
    return SessionConfig(authenticator=Authenticator("s3cret", clock=lambda: 1000.0, limiter=limiter))


def challenged(config, peer=REMOTE):
    """A harness whose client asked for a nonce; returns (harness, nonce, server time)."""
    h = Harness(config=config, peer=peer)
    h.send({"op": "auth_challenge", "id": "c1"})
    reply, = h.messages()
    assert reply["op"] == "auth_challenge" and reply["id"] == "c1" and len(reply["nonce"]) == 32
    return h, reply["nonce"], reply["t"]


def mac_auth(nonce, t=999, end=2000, secret="s3cret"):
    text = "%sclientdest%s%duser%d" % (secret, nonce, t, end)
    return {"op": "auth", "mac": hashlib.sha512(text.encode()).hexdigest(), "client": "client", "dest": "dest",
            "rand": nonce, "t": t, "level": "user", "end": end}


def authenticated(h):
    h.send({"op": "subscribe", "topic": "/known"})
    return not h.closed and "/known" in h.backend.subscribers


def test_auth_required_first():
    h = Harness(config=auth_config())
    h.send({"op": "subscribe", "topic": "/known", "id": 1})
    assert h.closed and "Not authenticated" in errors(h.messages())[0]["msg"]
    assert "/known" not in h.backend.subscribers


def test_raw_token_only_from_a_private_peer():
    config = auth_config()
    for peer in (None, Peer("127.0.0.1", False), Peer("10.1.2.3", True)):  # loopback or TLS
        h = Harness(config=config, peer=peer)
        h.send({"op": "auth", "mac": "s3cret"})
        assert authenticated(h), peer
    h = Harness(config=config, peer=REMOTE)
    h.send({"op": "auth", "mac": "s3cret"})
    assert h.closed and "only over TLS (wss) or from the robot" in errors(h.messages())[0]["msg"]
    assert not authenticated(h)


def test_mac_needs_this_connections_nonce_once():
    config = auth_config()
    h, nonce, now = challenged(config)
    assert now == 1000
    h.send(mac_auth(nonce))
    assert authenticated(h) and h.messages() == []
    replayed = Harness(config=config, peer=REMOTE)  # the captured message on a new connection
    replayed.send(mac_auth(nonce))
    assert replayed.closed and "rand must be the nonce" in errors(replayed.messages())[0]["msg"]
    other, other_nonce, _ = challenged(config)  # or with that connection's own nonce
    assert other_nonce != nonce
    other.send(mac_auth(nonce))
    assert other.closed and "rand must be the nonce" in errors(other.messages())[0]["msg"]
    own_rand = Harness(config=config, peer=REMOTE)  # rosauth clients choosing their own rand
    own_rand.send(mac_auth("r"))
    assert own_rand.closed


def test_mac_refusals_name_the_reason():
    config = auth_config(FailureLimiter(lambda: 0.0, max_failures=100))
    for auth, reason in ((lambda n: mac_auth(n, secret="guess"), "wrong mac"),
                         (lambda n: mac_auth(n, end=900), "end is in the past"),
                         (lambda n: mac_auth(n, t=900), "t is more than 60 s away"),
                         (lambda n: dict(mac_auth(n), t=float("inf")), "finite numbers"),
                         (lambda n: dict(mac_auth(n), end=float("nan")), "finite numbers")):
        h, nonce, _ = challenged(config)
        h.send(auth(nonce))
        assert h.closed and reason in errors(h.messages())[0]["msg"]
        assert not authenticated(h)


def test_one_try_per_connection_and_failures_block_the_peer():
    now = [0.0]
    limiter = FailureLimiter(lambda: now[0], max_failures=3, period=60.0)
    config = auth_config(limiter)
    h = Harness(config=config, peer=Peer("127.0.0.1", False))
    h.send({"op": "auth", "mac": "guess1"})
    h.send({"op": "auth", "mac": "s3cret"})  # the right token in the same burst: not even looked at
    assert h.closed and not authenticated(h)
    for guess in ("guess2", "guess3"):
        h = Harness(config=config, peer=Peer("127.0.0.1", False))
        h.send({"op": "auth", "mac": guess})
    blocked = Harness(config=config, peer=Peer("127.0.0.1", False))
    assert blocked.closed and "Too many failed authentications from 127.0.0.1: try again in 60 s" in \
        errors(blocked.messages())[0]["msg"]
    blocked.send({"op": "auth", "mac": "s3cret"})
    assert not authenticated(blocked)
    other = Harness(config=config, peer=REMOTE)  # another address is not affected
    assert not other.closed
    now[0] = 61.0
    h = Harness(config=config, peer=Peer("127.0.0.1", False))
    h.send({"op": "auth", "mac": "s3cret"})
    assert authenticated(h)


def test_auth_challenge_without_auth_configured():
    h = Harness()
    h.send({"op": "auth_challenge", "id": 7})
    status, = h.messages()
    assert status == {"op": "status", "level": "error", "id": 7,
                      "msg": "auth_challenge: no authentication needed on this connection"}


def test_outgoing_encodes_once_and_keeps_nan_in_cbor():
    backend = FakeBackend()
    cls = backend.types.message_class("std_msgs/Float64MultiArray")
    out = Outgoing("/f", cls(data=[1.0, float("nan")]), backend.codec)
    assert json.loads(out.json_text())["msg"]["data"] == [1.0, None]
    assert out.json_text() is out.json_text()
    data = cbor.loads(out.cbor_frame())["msg"]["data"]
    assert data[0] == 1.0 and data[1] != data[1]
    raw = cbor.loads(Outgoing("/f", cls(data=[2.0]), backend.codec, (3, 4)).cbor_raw_frame())["msg"]
    assert raw["secs"] == 3 and cls().deserialize(raw["bytes"]).data == (2.0,)
    assert genpy.Time(1, 2) == backend.types.time(1, 2)


def test_incoming_png_is_an_unknown_op_as_in_rosbridge():
    h = Harness()
    h.send({"op": "png", "id": "p", "data": "aGk="})
    status, = h.messages()
    assert status["level"] == "error" and status["id"] == "p" and status["msg"].startswith("Unknown operation: png")


def test_every_op_has_a_handler_in_the_table():
    h = Harness()
    assert sorted(h.session.handlers) == sorted(OPS)
    assert all(callable(handler) for handler in h.session.handlers.values())


def test_ros_backlogged_follows_the_publisher_of_the_latest_publish():
    h = Harness()
    assert not h.session.ros_backlogged()
    h.send({"op": "advertise", "topic": "/t", "type": "std_msgs/String"})
    h.backend.full_topics.add("/t")
    h.send({"op": "publish", "topic": "/t", "msg": {"data": "x"}})
    assert h.session.ros_backlogged()
    assert h.session.ros_backlogged()  # stays until the queue drained
    h.backend.full_topics.clear()
    assert not h.session.ros_backlogged()
    h.backend.full_topics.add("/t")
    assert not h.session.ros_backlogged()  # only a new publish pauses reading again


def test_drop_warning_passes_the_default_level_and_set_level_none_silences_it():
    h = Harness()
    h.session.drops("/cam", 12, 40, 1000)
    (warning,) = h.messages()
    assert warning == {"op": "status", "level": "warning",
                       "msg": "subscribe: dropped 12 messages on /cam (40 in all): the client reads slower than the "
                              "topic and its send queue is over its budget of 1000 bytes"}
    h.send({"op": "set_level", "level": "none"})
    h.session.drops("/cam", 1, 41, 1000)
    assert h.messages() == []


def test_protocol_errors_are_logged_at_most_once_per_period_per_client():
    h = Harness()
    for i in range(50):
        h.send("not json %d" % i)
    assert len(errors(h.messages())) == 50  # the client hears of every one
    assert len(h.logged) == 1 and "client 1: Unable to parse" in h.logged[0]
    h.now += LOG_PERIOD
    h.send({"op": "nope"})
    assert len(h.logged) == 2 and h.logged[1].endswith("(+49 more since the last line)")


def test_compression_per_topic_and_each_encoding_made_once():
    h = Harness()
    h.send({"op": "subscribe", "topic": "/known", "type": "std_msgs/String", "compression": "cbor"})
    assert h.session.compression("/known") == "cbor" and h.session.compression("/other") is None
    outgoing = Outgoing("/known", h.backend.types.message_class("std_msgs/String")(data="x"), h.backend.codec)
    frame = outgoing.encoded("cbor")  # what the ROS side computes ahead, in its own thread
    assert isinstance(frame, bytes) and outgoing.encoded("cbor") is frame
    assert outgoing.encoded("none") == '{"op":"publish","topic":"/known","msg":{"data":"x"}}'
    h.session.deliver(outgoing)
    assert h.sent[-1] == [frame]  # the very bytes computed ahead


def test_an_unauthenticated_client_is_closed_after_auth_timeout():
    h = Harness(config=SessionConfig(authenticator=Authenticator("s3cret", clock=lambda: 1000.0), auth_timeout=10.0))
    h.send({"op": "auth_challenge"})
    h.advance(9.9)
    assert not h.closed
    h.advance(0.2)
    assert h.closed and errors(h.messages())[0]["msg"] == "Not authenticated within 10 s; closing"
    ok = Harness(config=SessionConfig(authenticator=Authenticator("s3cret", clock=lambda: 1000.0)))
    ok.send({"op": "auth", "mac": "s3cret"})
    ok.advance(60.0)
    assert authenticated(ok)


# ---------------------------------------------------------------- issue #39: limits before trust (branch limits)
def strict_messages(h):
    """The frames sent, parsed as strict JSON: a bare NaN / Infinity (invalid JSON) fails the test."""
    def refuse(constant):
        raise AssertionError("invalid JSON: bare %s" % constant)
    out = [json.loads(frame, parse_constant=refuse) for frames in h.sent for frame in frames]
    del h.sent[:]
    return out


def test_a_malformed_auth_closes_the_connection_with_its_reason():
    config = auth_config(FailureLimiter(lambda: 0.0, max_failures=100))
    for auth, reason in (({"op": "auth"}, "auth: Expected a mac field but none was found.; closing"),
                         ({"op": "auth", "mac": 5}, "auth: Expected field mac to be str. Invalid value: 5; closing"),
                         ({"op": "auth", "mac": "x", "t": "soon"}, "Expected field t to be time"),
                         ({"op": "auth", "mac": "x", "client": ["a"]}, "Expected field client to be str")):
        h = Harness(config=config, peer=REMOTE)
        h.send(dict(auth, id="a"))
        (err,) = errors(h.messages())
        assert h.closed and reason in err["msg"] and err["id"] == "a", err
        assert not authenticated(h)
    ok = Harness(config=config, peer=Peer("127.0.0.1", False))   # a well-formed auth still opens
    ok.send({"op": "auth", "mac": "s3cret"})
    assert authenticated(ok) and ok.session.authenticated


def test_a_malformed_op_after_auth_keeps_the_connection():
    h = Harness(config=auth_config(), peer=Peer("127.0.0.1", False))
    h.send({"op": "auth", "mac": "s3cret"})
    h.send({"op": "subscribe", "topic": 5})
    assert "Expected field topic to be str" in errors(h.messages())[0]["msg"] and not h.closed


def test_a_non_finite_id_is_not_echoed_and_replies_stay_valid_json():
    for literal in ("NaN", "Infinity", "-Infinity", "1e400"):
        h = Harness()
        h.send('{"op": "publish", "id": %s, "topic": "/unknown", "msg": {}}' % literal)
        h.send('{"op": "call_service", "id": %s, "service": "/echo", "args": {"x": 1}}' % literal)
        h.send('{"op": "dance", "id": %s}' % literal)
        status, response, unknown = strict_messages(h)
        assert "id" not in status and "Cannot infer topic type" in status["msg"]
        assert "id" not in response and response["values"] == {"echo": {"x": 1}}
        assert "id" not in unknown and "Unknown operation" in unknown["msg"]
    h = Harness()
    h.send(cbor.dumps({"op": "dance", "id": float("nan")}))   # CBOR carries NaN as is
    (status,) = strict_messages(h)
    assert "id" not in status
    h.send('{"op": "fragment", "id": NaN, "data": "x", "num": 0, "total": 2}')
    (status,) = strict_messages(h)
    assert "fragment id must be a string or a finite number" in status["msg"]
    h.send('{"op": "dance", "id": 7.5}')   # a finite number is echoed as it came
    assert strict_messages(h)[0]["id"] == 7.5


def test_non_finite_values_in_a_reply_become_null():
    h = Harness()
    h.send('{"op": "call_service", "id": "n", "service": "/echo", "args": {"x": NaN, "y": [Infinity, 1.5]}}')
    (response,) = strict_messages(h)
    assert response["id"] == "n" and response["values"] == {"echo": {"x": None, "y": [None, 1.5]}}


def test_repeated_fragments_are_bounded_and_freed_when_the_client_leaves():
    """issue #39 item 3: re-sending fragment numbers grew the bridge without bound and let a
    message over max_message_size through."""
    h = Harness(config=SessionConfig(max_message_size=1000))
    for _ in range(50):   # the same numbers again and again, 600 bytes each: held once
        h.send({"op": "fragment", "id": "f", "data": "x" * 600, "num": 0, "total": 3})
    assert h.session.fragment_bytes == 600 and errors(h.messages()) == []
    h.send({"op": "fragment", "id": "f", "data": "y" * 600, "num": 1, "total": 3})
    (err,) = errors(h.messages())
    assert err["msg"] == "fragment: fragmented message larger than 1000 bytes (max_message_size)"
    assert h.session.fragment_bytes == 0
    text = json.dumps({"op": "publish", "topic": "/known", "msg": {"data": "z" * 1000}})   # over 1000 bytes whole
    for part in fragments(text, 300, "big"):
        h.send(part)
    assert "larger than 1000 bytes" in errors(h.messages())[0]["msg"] and h.backend.published == []
    text = json.dumps({"op": "publish", "topic": "/known", "msg": {"data": "z" * 500}})   # within: passes
    for part in fragments(text, 300, "ok"):
        h.send(part)
    assert h.backend.published[-1][1].data == "z" * 500
    h.send({"op": "fragment", "id": "g", "data": "x" * 400, "num": 0, "total": 2})
    h.send({"op": "fragment", "id": "h", "data": "x" * 400, "num": 0, "total": 2})
    h.send({"op": "fragment", "id": "i", "data": "x" * 400, "num": 0, "total": 2})   # 1200 together: refused
    assert "together" in errors(h.messages())[0]["msg"] and h.session.fragment_bytes == 800
    h.session.close()
    assert h.session.fragment_bytes == 0


def test_leaving_or_authenticating_cancels_the_auth_timer():
    """The auth_timeout timer refers to the session and so to its connection's buffers: a client that
    left must not stay in memory until it fires."""
    for finish in (lambda h: h.session.close(), lambda h: h.send({"op": "auth", "mac": "s3cret"})):
        h = Harness(config=auth_config(), peer=Peer("127.0.0.1", False))
        (timer,) = h.timers
        assert not timer.cancelled
        finish(h)
        assert timer.cancelled
