"""codec: rosbridge's JSON mapping on real generated message classes, CBOR values, error texts."""
import base64
import math

import genpy
import pytest

from inspection_robot.bridge import cbor
from inspection_robot.bridge.codec import Codec, CodecError
from inspection_robot.bridge.ros_message_types import GenpyTypes, UnknownTypeError

TYPES = GenpyTypes(now=lambda: genpy.Time(42, 7))
CODEC = Codec(TYPES)


def cls(name):
    return TYPES.message_class(name)


def test_time_bytes_nested_and_arrays_to_json():
    image = cls("sensor_msgs/Image")(height=2, width=1, encoding="mono8", step=1, data=b"\x00\xff")
    image.header.stamp = genpy.Time(3, 4)
    out = CODEC.to_json(image)
    assert out["header"] == {"seq": 0, "stamp": {"secs": 3, "nsecs": 4}, "frame_id": ""}
    assert out["data"] == base64.standard_b64encode(b"\x00\xff").decode()
    assert list(out) == list(cls("sensor_msgs/Image").__slots__)
    path = cls("nav_msgs/Path")(poses=[cls("geometry_msgs/PoseStamped")()])
    assert CODEC.to_json(path)["poses"][0]["pose"]["orientation"] == {"x": 0.0, "y": 0.0, "z": 0.0, "w": 0.0}


def test_nan_and_inf_become_null_and_null_reads_back_as_nan():
    scan = cls("sensor_msgs/LaserScan")(ranges=[1.0, float("nan"), float("-inf")], range_max=float("inf"))
    out = CODEC.to_json(scan)
    assert out["ranges"] == [1.0, None, None] and out["range_max"] is None
    back = CODEC.from_json(cls("sensor_msgs/LaserScan"), out)
    assert back.ranges[0] == 1.0 and math.isnan(back.ranges[1]) and math.isnan(back.range_max)


def test_spec_message_round_trip_with_defaults_and_header_stamp_now():
    cmd_cls = cls("inspection_robot/GeneralCmd")
    msg = CODEC.from_json(cmd_cls, {"header": {"frame_id": "f"}, "cmd": "go", "trans_id": 9})
    assert msg.header.stamp == genpy.Time(42, 7)   # header given without stamp: now
    assert msg.sender == "" and msg.trans_id == 9
    assert CODEC.from_json(cmd_cls, {}).header.stamp == genpy.Time(0, 0)  # no header: untouched
    stamped = CODEC.from_json(cmd_cls, {"header": {"stamp": {"secs": 5, "nsecs": 6}}})
    assert stamped.header.stamp == genpy.Time(5, 6)
    assert CODEC.from_json(cmd_cls, {"header": {"stamp": "now"}}).header.stamp == genpy.Time(42, 7)


def test_binary_inputs():
    image_cls = cls("sensor_msgs/Image")
    assert CODEC.from_json(image_cls, {"data": "AAE="}).data == b"\x00\x01"
    assert CODEC.from_json(image_cls, {"data": [0, 1, 255]}).data == b"\x00\x01\xff"
    assert CODEC.from_json(image_cls, {"data": b"\x05"}).data == b"\x05"


@pytest.mark.parametrize("type_name, value, text", [
    ("std_msgs/String", {"data": 1},
     "std_msgs/String message requires a string for field data, but got a <class 'int'>"),
    ("std_msgs/Int32", {"data": 1.5}, "requires a int32 for field data"),
    ("std_msgs/Int32", {"data": True}, "requires a int32 for field data, but got a <class 'bool'>"),
    ("std_msgs/UInt8", {"data": 256}, "256 outside 0..255"),
    ("std_msgs/Bool", {"data": 1}, "requires a bool for field data"),
    ("std_msgs/String", {"nope": 1}, "Message type std_msgs/String does not have a field nope"),
    ("std_msgs/Header", {"stamp": {"secs": -1}}, "requires a uint32 for field stamp.secs"),
    ("std_msgs/Header", {"stamp": {"sec": 1}}, "does not have a field stamp.sec"),
    ("geometry_msgs/PoseStamped", {"pose": {"position": {"x": "1"}}}, "field pose.position.x"),
    ("geometry_msgs/PoseStamped", {"pose": []}, "requires a geometry_msgs/Pose for field pose"),
    ("sensor_msgs/Image", {"data": "@@@"}, "not valid base64"),
    ("sensor_msgs/Image", {"data": [1, 300]}, "0..255"),
    ("sensor_msgs/CameraInfo", {"K": [1.0] * 8}, "8 elements instead of 9"),
    ("std_msgs/Float64MultiArray", {"data": {"a": 1}}, "requires a float64[] for field data"),
])
def test_errors_name_type_field_and_value(type_name, value, text):
    with pytest.raises(CodecError) as err:
        CODEC.from_json(cls(type_name), value)
    assert text in str(err.value)


def test_root_must_be_an_object():
    with pytest.raises(CodecError, match="Expected a JSON object for type std_msgs/String but received a"):
        CODEC.from_json(cls("std_msgs/String"), [1])


def test_unknown_types():
    for name in ("nope/Nope", "std_msgs/Nope", "bad", "", "a/b/c"):
        with pytest.raises(UnknownTypeError):
            TYPES.message_class(name)
    with pytest.raises(UnknownTypeError):
        TYPES.service_class("std_msgs/String")


def test_cbor_values_use_typed_arrays_and_raw_bytes():
    info = cls("sensor_msgs/CameraInfo")(K=[1.0] * 9, D=[float("nan")])
    values = CODEC.to_cbor(info)
    assert isinstance(values["K"], cbor.Tagged) and values["K"].tag == 86
    decoded = cbor.loads(cbor.dumps(values))
    assert decoded["K"] == [1.0] * 9 and math.isnan(decoded["D"][0])
    image = CODEC.to_cbor(cls("sensor_msgs/Image")(data=b"\x01\x02"))
    assert image["data"] == b"\x01\x02"


def test_service_request_and_response_classes():
    srv = TYPES.service_class("inspection_robot/ControlService")
    request = CODEC.from_json(srv._request_class, {"cmd": "zoom", "data": "3", "trans_id": 1})
    assert request.cmd == "zoom"
    assert CODEC.to_json(srv._response_class(trans_id=1, ack="success")) == {"trans_id": 1, "ack": "success",
                                                                             "data": ""}


def test_json_text_splices_large_byte_arrays_and_equals_the_plain_encoding():
    import json
    from inspection_robot.bridge.codec import BLOB_MIN
    types = GenpyTypes()
    codec = Codec(types)
    compact = json.JSONEncoder(separators=(",", ":")).encode
    image_cls = types.message_class("sensor_msgs/Image")
    big = image_cls(height=1, width=BLOB_MIN, encoding="mono8", step=BLOB_MIN,
                    data=bytes(range(256)) * (BLOB_MIN // 256))
    small = image_cls(encoding="\x00\x01blob\x02", data=b"\x01\x02")  # a string that looks like the marker
    for msg in (big, small, types.message_class("std_msgs/String")(data='quote " and \\ and \u00e9')):
        assert codec.to_json_text(msg) == compact(codec.to_json(msg))
    jpeg = types.message_class("sensor_msgs/CompressedImage")(format="jpeg", data=b"\xff" * BLOB_MIN)
    text = codec.to_json_text(jpeg)
    assert text == compact(codec.to_json(jpeg)) and json.loads(text)["format"] == "jpeg"
    tricky = image_cls(encoding="\x00\x01blob\x02", data=b"\x07" * BLOB_MIN)  # marker string and a blob
    assert codec.to_json_text(tricky) == compact(codec.to_json(tricky))
