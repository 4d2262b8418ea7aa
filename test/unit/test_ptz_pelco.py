"""Pelco-D frames against hand-computed bytes, the reader's resync, and the angle conversions."""
import pytest
from hypothesis import given
from hypothesis import strategies as st

from inspection_robot.ptz import pelco


def hexbytes(text):
    return bytes.fromhex(text)


# Hand-computed: checksum = (address + cmd1 + cmd2 + data1 + data2) mod 256.
# standard pan 123.00 -> physical (360 - 123) = 237.00 -> 23700 = 0x5C94
# standard tilt -3.00 (up) -> physical 357.00 -> 35700 = 0x8B74
VECTORS = [
    (pelco.set_pan(1, 23700), "FF 01 00 4B 5C 94 3C"),
    (pelco.set_pan(2, 0), "FF 02 00 4B 00 00 4D"),
    (pelco.set_tilt(1, 35700), "FF 01 00 4D 8B 74 4D"),
    (pelco.set_tilt(1, 9000), "FF 01 00 4D 23 28 99"),
    (pelco.query_pan(1), "FF 01 00 51 00 00 52"),
    (pelco.query_tilt(1), "FF 01 00 53 00 00 54"),
    (pelco.pan_reply(1, 23700), "FF 01 00 59 5C 94 4A"),
    (pelco.tilt_reply(1, 9000), "FF 01 00 5B 23 28 A7"),
    (pelco.wiper(1, True), "FF 01 00 09 00 01 0B"),
    (pelco.wiper(1, False), "FF 01 00 0B 00 01 0D"),
    (pelco.lamp(1, True), "FF 01 00 09 00 02 0C"),
    (pelco.lamp(1, False), "FF 01 00 0B 00 02 0E"),
    (pelco.move(1, pelco.DIR_LEFT, 0x3F, 0), "FF 01 00 04 3F 00 44"),
    (pelco.move(1, pelco.DIR_RIGHT, 0x20, 0), "FF 01 00 02 20 00 23"),
    (pelco.move(1, pelco.DIR_UP, 0, 0x08), "FF 01 00 08 00 08 11"),
    (pelco.move(1, pelco.DIR_DOWN, 0, 0x3F), "FF 01 00 10 00 3F 50"),
    (pelco.stop(1), "FF 01 00 00 00 00 01"),
]


@pytest.mark.parametrize("frame,expected", VECTORS)
def test_frames_match_hand_computed_bytes(frame, expected):
    assert frame == hexbytes(expected)


def test_builders_refuse_impossible_values():
    for bad in (lambda: pelco.set_pan(1, 36000), lambda: pelco.set_tilt(1, 9001), lambda: pelco.set_tilt(1, 26999),
                lambda: pelco.move(1, 0x01, 0, 0), lambda: pelco.move(1, pelco.DIR_UP, 0, 0x40),
                lambda: pelco.build_frame(256, 0, 0, 0, 0)):
        with pytest.raises(ValueError):
            bad()


def test_reader_recovers_from_garbage_split_frames_and_bad_checksums():
    reader = pelco.FrameReader()
    good = pelco.pan_reply(1, 23700)
    corrupt = good[:6] + bytes([good[6] ^ 0x01])
    stream = b"\x00\x13\xff\xff\x42" + corrupt + good + b"\xff\x01" + pelco.tilt_reply(1, 9000)
    frames = []
    for i in range(0, len(stream), 3):        # split everywhere
        frames += reader.feed(stream[i:i + 3])
    assert [(f.cmd2, f.data) for f in frames] == [(pelco.REPLY_PAN, 23700), (pelco.REPLY_TILT, 9000)]
    assert reader.bad_checksums >= 1


def test_reader_finds_a_frame_whose_data_contains_0xff():
    frame = pelco.pan_reply(1, 0x00FF)
    assert pelco.FrameReader().feed(b"\xff\x00" + frame) == [pelco.Frame(1, 0, pelco.REPLY_PAN, 0x00, 0xFF)]


def test_reader_accept_rejects_other_addresses_without_losing_the_real_frame():
    reader = pelco.FrameReader(accept=lambda f: f.address == 1)
    noise = pelco.build_frame(0xFF, 0, 0, 0, 0)[:6]        # FF FF 00 00 00 00 ...
    frames = reader.feed(noise + pelco.pan_reply(1, 100))
    assert [f.data for f in frames] == [100]


def test_angle_conventions():
    assert pelco.pan_physical_to_standard(9000) == -9000        # 90 deg clockwise = right = negative
    assert pelco.pan_physical_to_standard(27000) == 9000
    assert pelco.pan_physical_to_standard(18000) == 18000
    assert pelco.pan_physical_to_standard(0) == 0
    assert pelco.tilt_physical_to_standard(9000) == 9000         # straight down
    assert pelco.tilt_physical_to_standard(27000) == -9000       # straight up
    assert pelco.tilt_physical_to_standard(35999) == -1
    with pytest.raises(ValueError):
        pelco.tilt_physical_to_standard(18000)
    with pytest.raises(ValueError):
        pelco.pan_standard_to_physical(-18000)


def test_every_physical_angle_round_trips_exactly():
    for physical in range(pelco.FULL_TURN):
        assert pelco.pan_standard_to_physical(pelco.pan_physical_to_standard(physical)) == physical
    for physical in list(range(0, 9001)) + list(range(27000, 36000)):
        assert pelco.tilt_standard_to_physical(pelco.tilt_physical_to_standard(physical)) == physical


@given(st.integers(min_value=-17999, max_value=18000))
def test_standard_pan_round_trips(centi):
    physical = pelco.pan_standard_to_physical(centi)
    assert 0 <= physical < 36000
    assert pelco.pan_physical_to_standard(physical) == centi


@given(st.integers(min_value=-9000, max_value=9000))
def test_standard_tilt_round_trips(centi):
    assert pelco.tilt_physical_to_standard(pelco.tilt_standard_to_physical(centi)) == centi


@given(st.floats(min_value=-179.994, max_value=180.0, allow_nan=False))
def test_pan_degrees_round_trip_to_a_hundredth(degrees):
    centi = pelco.wrap_pan_centi(pelco.degrees_to_centi(degrees))
    frame = pelco.set_pan(1, pelco.pan_standard_to_physical(centi))
    decoded = pelco.FrameReader().feed(frame)[0]
    back = pelco.pan_physical_to_standard(decoded.data) / 100.0
    assert abs(pelco.wrap_pan_centi(pelco.degrees_to_centi(back - degrees))) <= 1
    assert abs(back - degrees) <= 0.005 + 1e-9 or abs(abs(back - degrees) - 360) <= 0.005 + 1e-9


@given(st.floats(min_value=-90.0, max_value=90.0, allow_nan=False))
def test_tilt_degrees_round_trip_to_a_hundredth(degrees):
    centi = pelco.degrees_to_centi(degrees)
    frame = pelco.set_tilt(1, pelco.tilt_standard_to_physical(centi))
    back = pelco.tilt_physical_to_standard(pelco.FrameReader().feed(frame)[0].data) / 100.0
    assert abs(back - degrees) <= 0.005 + 1e-9


@given(st.integers(min_value=-10 ** 6, max_value=10 ** 6))
def test_wrap_pan_range(centi):
    wrapped = pelco.wrap_pan_centi(centi)
    assert -18000 < wrapped <= 18000
    assert (wrapped - centi) % 36000 == 0
