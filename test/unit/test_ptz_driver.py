"""PelcoHead on a raw pseudo-terminal (real bytes), the terrace command logic, the simulated head."""
import math
import os
import select
import tty

import pytest

from inspection_robot.camera.optics import ZoomOptics
from inspection_robot.ptz import pelco
from inspection_robot.ptz.driver import HeadError, PanTiltHead, PelcoHead
from inspection_robot.ptz.terrace import Terrace, parse_centi, pixel_target
from inspection_robot.command import CommandError
from inspection_robot.sim.pelco_head import PtyPelcoServer, SimPelcoHead

SPEEDS = {"high_speed": 63, "mid_speed": 32, "low_speed": 8}


@pytest.fixture
def pty_head():
    master, slave = os.openpty()
    tty.setraw(slave)
    head = PelcoHead(os.ttyname(slave), reply_timeout=0.3, backoff=(0.02, 0.1))
    assert head.wait_connected(2.0)
    yield head, master
    head.close()
    os.close(master)
    os.close(slave)


def read_frame(master, timeout=10.0):   # a bound for lost bytes, not a speed limit
    data = b""
    while len(data) < 7:
        ready, _, _ = select.select([master], [], [], timeout)
        assert ready, "no bytes from the driver"
        data += os.read(master, 7 - len(data))
    return data


def test_commands_put_the_expected_bytes_on_the_wire(pty_head):
    head, master = pty_head
    table = Terrace(head, SPEEDS).table()
    for cmd, data, expected in (("pan_left", "high_speed", "FF 01 00 04 3F 00 44"),
                                ("pan_right", "mid_speed", "FF 01 00 02 20 00 23"),
                                ("tilt_up", "low_speed", "FF 01 00 08 00 08 11"),
                                ("tilt_down", "high_speed", "FF 01 00 10 00 3F 50"),
                                ("terrace_stop", "", "FF 01 00 00 00 00 01"),
                                ("brush_on", "", "FF 01 00 09 00 01 0B"), ("brush_off", "", "FF 01 00 0B 00 01 0D"),
                                ("light_on", "", "FF 01 00 09 00 02 0C"), ("light_off", "", "FF 01 00 0B 00 02 0E")):
        assert table.dispatch(cmd, data).ack == "success"
        assert read_frame(master) == bytes.fromhex(expected), cmd


def test_query_survives_garbage_and_split_reply(pty_head):
    head, master = pty_head
    import threading
    result = {}
    thread = threading.Thread(target=lambda: result.update(pan=head.query_pan()))
    thread.start()
    assert read_frame(master) == pelco.query_pan(1)
    reply = b"\x00\xff\x17" + pelco.pan_reply(1, 23700)
    os.write(master, reply[:5])
    os.write(master, reply[5:])
    thread.join(2.0)
    assert result["pan"] == 12300


def test_query_times_out_with_a_reason(pty_head):
    head, _master = pty_head
    with pytest.raises(HeadError, match="no reply"):
        head.query_tilt()


def test_unopenable_port_reports_not_connected():
    head = PelcoHead("/nonexistent/pelco", backoff=(0.01, 0.05))
    try:
        with pytest.raises(HeadError, match="not connected"):
            head.stop()
    finally:
        head.close()


def test_pty_simulator_round_trip_unplug_replug(tmp_path):
    link = str(tmp_path / "pelco")
    server = PtyPelcoServer(SimPelcoHead(position_speed_deg_s=3600.0), link)
    server.plug()
    head = PelcoHead(link, reply_timeout=0.3, backoff=(0.02, 0.1))
    try:
        assert head.wait_connected(2.0)
        terrace = Terrace(head, SPEEDS, move_timeout=2.0, poll_period=0.01)
        assert terrace.table().dispatch("set_angle", "-12345,-4500").ack == "success"
        assert terrace.table().dispatch("get_angle", "").data == "-12345,-4500"
        server.unplug()
        reply = terrace.table().dispatch("get_angle", "")
        assert reply.ack == "failed"
        assert not head.connected     # the dead link is dropped by the failed command itself
        server.plug()
        assert head.wait_connected(3.0)
        assert terrace.table().dispatch("get_angle", "").data == "-12345,-4500"
    finally:
        head.close()
        server.unplug()


@pytest.mark.parametrize("text", ["abc", "123.5", "1e3", "", " 1", "+-1", "١٢٣", "18001", "1" * 100000])
def test_parse_centi_rejects(text):
    with pytest.raises(CommandError):
        parse_centi(text, "pan", -17999, 18000)


def test_parse_centi_accepts_signed_integers():
    assert parse_centi("-300", "tilt", -9000, 9000) == -300
    assert parse_centi("+18000", "pan", -17999, 18000) == 18000


class FakeHead(PanTiltHead):
    """Reaches targets only after a number of queries; never moves when ``stuck``."""

    @property
    def connected(self):
        return True

    port = "fake"

    def __init__(self, stuck=False):
        self.pan = self.tilt = 0
        self.target = (0, 0)
        self.stuck = stuck

    def set_pan(self, pan):
        self.target = (pan, self.target[1])

    def set_tilt(self, tilt):
        self.target = (self.target[0], tilt)

    def query_pan(self):
        if not self.stuck:
            self.pan = self.target[0]
        return self.pan

    def query_tilt(self):
        if not self.stuck:
            self.tilt = self.target[1]
        return self.tilt


def test_set_angle_fails_after_timeout_when_the_head_does_not_move():
    now = [0.0]

    def sleep(dt):
        now[0] += dt
    terrace = Terrace(FakeHead(stuck=True), SPEEDS, move_timeout=1.0, poll_period=0.1, sleep=sleep,
                      clock=lambda: now[0])
    reply = terrace.table().dispatch("set_angle", "100,200")
    assert reply.ack == "failed" and "did not reach pan 1.00 tilt 2.00 within 1.0 s" in reply.data
    assert 1.0 <= now[0] <= 1.2


def test_set_angle_succeeds_when_reached():
    terrace = Terrace(FakeHead(), SPEEDS)
    assert terrace.table().dispatch("set_angle", "100,200").ack == "success"
    assert terrace.table().dispatch("get_angle", "").data == "100,200"


def test_pixel_target_matches_the_optics_at_the_origin_and_centres_the_ray():
    optics = ZoomOptics([[1.0, 59.8], [30.0, 2.2]], 1920, 1080)
    focal = optics.focal_px(1.0)
    pan, tilt = pixel_target(0.0, 0.0, focal, 400, -200)
    want = optics.pixel_to_angles(1.0, 400, -200, 1920, 1080)
    assert pan == pytest.approx(want[0]) and tilt == pytest.approx(want[1])
    # centre pixel: no change, anywhere
    assert pixel_target(30.0, 20.0, focal, 0, 0) == pytest.approx((30.0, 20.0))
    # a pixel straight above the centre while looking level: pure tilt up
    pan, tilt = pixel_target(10.0, 0.0, focal, 0, 100)
    assert pan == pytest.approx(10.0) and tilt == pytest.approx(-math.degrees(math.atan2(100, focal)))


def test_sim_head_slews_at_finite_speed_and_respects_limits():
    now = [0.0]
    head = SimPelcoHead(max_speed_deg_s=60.0, position_speed_deg_s=90.0, tilt_limits_centi=(-4500, 4500),
                        clock=lambda: now[0])
    head.handle(pelco.FrameReader().feed(pelco.set_pan(1, pelco.pan_standard_to_physical(9000)))[0])
    now[0] = 0.5
    assert head.state()[0] == 4500          # halfway after 0.5 s at 90 deg/s
    now[0] = 2.0
    assert head.state()[0] == 9000
    head.handle(pelco.Frame(1, 0, pelco.DIR_DOWN, 0, 0x3F))
    now[0] = 4.0
    assert head.state()[1] == 4500          # stopped at the tilt limit
    head.handle(pelco.Frame(1, 0, 0, 0, 0))
    head.handle(pelco.Frame(1, 0, pelco.CMD_SET_AUX, 0, pelco.AUX_LAMP))
    assert head.state()[3] is True
    reply = head.handle(pelco.Frame(1, 0, pelco.CMD_QUERY_TILT, 0, 0))
    assert reply == pelco.tilt_reply(1, 4500)
    head.fault = "bad_checksum"
    assert pelco.FrameReader().feed(head.handle(pelco.Frame(1, 0, pelco.CMD_QUERY_TILT, 0, 0))) == []
    head.fault = "silence"
    assert head.handle(pelco.Frame(1, 0, pelco.CMD_QUERY_TILT, 0, 0)) == b""
    assert head.handle(pelco.Frame(2, 0, pelco.CMD_QUERY_TILT, 0, 0)) == b""
