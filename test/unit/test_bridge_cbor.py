"""cbor: round trips, RFC 7049 appendix A vectors, typed arrays, malformed input."""
import math
import struct

import pytest

from inspection_robot.bridge import cbor

VECTORS = [  # (value, hex) from RFC 7049 appendix A (float64 encodings for floats)
    (0, "00"), (23, "17"), (24, "1818"), (1000, "1903e8"), (1000000, "1a000f4240"),
    (18446744073709551615, "1bffffffffffffffff"), (-1, "20"), (-1000, "3903e7"),
    (False, "f4"), (True, "f5"), (None, "f6"), ("", "60"), ("IETF", "6449455446"),
    (b"\x01\x02\x03\x04", "4401020304"), ([1, [2, 3]], "8201820203"), ({"a": 1}, "a16161 01".replace(" ", "")),
    (1.1, "fb3ff199999999999a"),
]


@pytest.mark.parametrize("value, hexa", VECTORS)
def test_rfc_vectors(value, hexa):
    assert cbor.dumps(value).hex() == hexa
    assert cbor.loads(bytes.fromhex(hexa)) == value


def test_decodes_half_single_indefinite_and_unknown_tags():
    assert cbor.loads(bytes.fromhex("f93c00")) == 1.0
    assert cbor.loads(bytes.fromhex("f97c00")) == float("inf")
    assert math.isnan(cbor.loads(bytes.fromhex("f97e00")))
    assert cbor.loads(bytes.fromhex("fa47c35000")) == 100000.0
    assert cbor.loads(bytes.fromhex("9f018202039f0405ffff")) == [1, [2, 3], [4, 5]]
    assert cbor.loads(bytes.fromhex("bf61610161629f0203ffff")) == {"a": 1, "b": [2, 3]}
    assert cbor.loads(bytes.fromhex("7f657374726561646d696e67ff")) == "streaming"
    assert cbor.loads(bytes.fromhex("c11a514b67b0")) == 1363896240


def test_typed_arrays_round_trip():
    for element, values in (("float64", [1.5, -2.0]), ("float32", [0.5]), ("int32", [-5, 7]), ("uint16", [65535]),
                            ("int8", [-128, 127]), ("uint64", [2 ** 64 - 1]), ("int64", [-2 ** 63])):
        item = cbor.typed_array(element, values)
        assert cbor.loads(cbor.dumps({"a": item})) == {"a": values}
    assert cbor.dumps(cbor.typed_array("float32", [1.0]))[:2] == bytes([0xd8, 85])
    assert cbor.typed_array("int16", [1, 2]).value == struct.pack("<2h", 1, 2)


def test_matches_cbor2_when_available():
    cbor2 = pytest.importorskip("cbor2")
    value = {"op": "publish", "msg": {"x": [1, 2.5, None, True, "é", b"\x00"], "n": -2 ** 40}}
    assert cbor2.loads(cbor.dumps(value)) == value
    assert cbor.loads(cbor2.dumps(value)) == value


@pytest.mark.parametrize("hexa", ["", "18", "5a0000ffff", "62c328", "8301", "a1", "ff", "1c", "d84501",
                                  "d8560102", "a18001", "00 00".replace(" ", ""), "9f01", "5f01ff"])
def test_malformed_input_raises_cbor_error(hexa):
    with pytest.raises(cbor.CborError):
        cbor.loads(bytes.fromhex(hexa))


def test_too_deep_and_unencodable():
    with pytest.raises(cbor.CborError):
        cbor.loads(b"\x81" * 100 + b"\x00")
    with pytest.raises(cbor.CborError):
        cbor.dumps(object())
    with pytest.raises(cbor.CborError):
        cbor.dumps(2 ** 64)
