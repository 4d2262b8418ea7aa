"""Fuzzing the op handlers with hypothesis: random JSON shapes never raise, bad frames get a status."""
import json

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bridge_fakes import Harness
from inspection_robot.bridge import cbor
from inspection_robot.bridge.ops import OPS, BridgeError, check_fields

SCALARS = st.one_of(st.none(), st.booleans(), st.integers(-2 ** 70, 2 ** 70), st.floats(allow_nan=True),
                    st.text(max_size=20))
JSON = st.recursive(SCALARS, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                     st.dictionaries(st.text(max_size=8), inner, max_size=4)),
                    max_leaves=12)
FIELD_NAMES = sorted({f.name for fields in OPS.values() for f in fields} | {"msg", "args", "values", "id"})
TOPICS = st.sampled_from(["/known", "/t", "", "no slash", "/x/y"])
TYPES = st.sampled_from(["std_msgs/String", "std_msgs/Int32", "sensor_msgs/Image", "nope/Nope", "", "x"])


@st.composite
def op_messages(draw):
    message = {"op": draw(st.sampled_from(sorted(OPS) + ["nope", ""]))}
    for name in draw(st.lists(st.sampled_from(FIELD_NAMES), max_size=6)):
        message[name] = draw(st.one_of(JSON, TOPICS, TYPES))
    return message


def new_harness():
    h = Harness()
    h.send({"op": "subscribe", "topic": "/known", "id": "watch"})
    h.messages()
    return h


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(op_messages(), min_size=1, max_size=5))
def test_random_ops_never_raise_and_session_stays_usable(messages):
    h = new_harness()
    for message in messages:
        h.send(json.dumps(message))  # must not raise
    h.messages()
    h.send({"op": "publish", "topic": "/known", "msg": {"data": "alive"}})
    assert h.backend.published and h.backend.published[-1][1].data == "alive"
    h.session.close()


@settings(max_examples=150, deadline=None)
@given(st.one_of(st.text(max_size=40), st.binary(max_size=40), JSON.map(json.dumps)))
def test_random_frames_get_an_error_status_unless_valid(frame):
    h = new_harness()
    h.session.on_frame(frame)
    out = h.messages()
    try:
        decoded = cbor.loads(frame) if isinstance(frame, bytes) else json.loads(frame)
    except (ValueError, RecursionError):
        decoded = None
    if isinstance(decoded, dict) and decoded.get("op") in OPS:
        return  # a real op by chance: its own tests say what it answers
    assert [(m["op"], m["level"]) for m in out] == [("status", "error")], out


@settings(max_examples=200, deadline=None)
@given(st.sampled_from(sorted(OPS)), st.sampled_from([n for n in FIELD_NAMES if n != "id"]), JSON)
def test_every_wrongly_typed_field_is_reported_with_the_id(op, name, value):
    h = new_harness()
    message = {"op": op, "id": "fuzz", name: value}
    h.send(json.dumps(message))
    statuses = [m for m in h.messages() if m["op"] == "status"]
    for status in statuses:
        assert status["id"] == "fuzz" and status["msg"].startswith(op + ":")
    try:
        check_fields(op, message)
    except BridgeError:  # a missing or wrongly typed field: the client must be told
        assert statuses, "no status for %r" % message


@settings(max_examples=150, deadline=None)
@given(st.dictionaries(st.sampled_from(["header", "height", "width", "encoding", "data", "step", "bogus"]), JSON,
                       max_size=5))
def test_random_message_bodies_publish_or_report(body):
    h = new_harness()
    h.send({"op": "advertise", "topic": "/img", "type": "sensor_msgs/Image"})
    before = len(h.backend.published)
    h.send({"op": "publish", "id": "p", "topic": "/img", "msg": body})
    statuses = [m for m in h.messages() if m["op"] == "status"]
    assert (len(h.backend.published) == before + 1) != bool(statuses)
    if statuses:
        assert statuses[0]["id"] == "p" and statuses[0]["level"] == "error"
