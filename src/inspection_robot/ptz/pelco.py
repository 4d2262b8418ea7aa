"""Pelco-D protocol (INTERFACE.md section 4, "PTZ"): frames, checksum, reader, angle conversion.

Pure: no I/O and no rospy. A frame is seven bytes::

    0xFF  address  cmd1  cmd2  data1  data2  checksum      checksum = sum(bytes 2..6) mod 256

Angles on the wire are PHYSICAL hundredths of a degree (``data = angle * 100`` as msb, lsb):
pan 0..35999 clockwise from the front; tilt 0..9000 looking down, 27000..35999 looking up
(27000 straight up). The rest of the robot uses the STANDARD convention, also in integer
hundredths here so that conversions are exact: pan (-18000, 18000] counter-clockwise +, tilt
[-9000, 9000] down +.
"""
import math
from collections import namedtuple

SYNC = 0xFF
FRAME_LENGTH = 7
DEFAULT_ADDRESS = 0x01

# cmd2 of the extended commands used by the spec
CMD_SET_AUX = 0x09
CMD_CLEAR_AUX = 0x0B
CMD_SET_PAN = 0x4B
CMD_SET_TILT = 0x4D
CMD_QUERY_PAN = 0x51
CMD_QUERY_TILT = 0x53
REPLY_PAN = 0x59
REPLY_TILT = 0x5B
REPLY_FOR_QUERY = {CMD_QUERY_PAN: REPLY_PAN, CMD_QUERY_TILT: REPLY_TILT}

AUX_WIPER = 0x01
AUX_LAMP = 0x02

# cmd2 direction bits of the standard (non-extended) command
DIR_RIGHT = 0x02
DIR_LEFT = 0x04
DIR_UP = 0x08
DIR_DOWN = 0x10
MAX_SPEED = 0x3F      # 0x00..0x3F; 0x40 is "turbo" on pan only
TURBO_SPEED = 0x40

FULL_TURN = 36000
HALF_TURN = 18000
QUARTER_TURN = 9000
TILT_UP_PHYSICAL = 27000


class Frame(namedtuple("Frame", "address cmd1 cmd2 data1 data2")):
    """A decoded frame (without sync byte and checksum)."""

    @property
    def data(self):
        return (self.data1 << 8) | self.data2

    def encode(self):
        return build_frame(self.address, self.cmd1, self.cmd2, self.data1, self.data2)


def checksum(address, cmd1, cmd2, data1, data2):
    return (address + cmd1 + cmd2 + data1 + data2) & 0xFF


def build_frame(address, cmd1, cmd2, data1, data2):
    """Encode one frame; every field must be a byte value."""
    fields = (address, cmd1, cmd2, data1, data2)
    for value in fields:
        if not 0 <= int(value) <= 0xFF:
            raise ValueError("Pelco-D field out of byte range: %r" % (fields,))
    return bytes([SYNC] + [int(v) for v in fields] + [checksum(*fields)])


def _word_frame(address, cmd2, word):
    if not 0 <= word <= 0xFFFF:
        raise ValueError("Pelco-D data word out of range: %r" % (word,))
    return build_frame(address, 0x00, cmd2, (word >> 8) & 0xFF, word & 0xFF)


def set_pan(address, physical_centi):
    """Absolute pan, physical hundredths of a degree 0..35999."""
    _check_physical_pan(physical_centi)
    return _word_frame(address, CMD_SET_PAN, physical_centi)


def set_tilt(address, physical_centi):
    """Absolute tilt, physical hundredths of a degree (0..9000 or 27000..35999)."""
    _check_physical_tilt(physical_centi)
    return _word_frame(address, CMD_SET_TILT, physical_centi)


def query_pan(address):
    return build_frame(address, 0x00, CMD_QUERY_PAN, 0x00, 0x00)


def query_tilt(address):
    return build_frame(address, 0x00, CMD_QUERY_TILT, 0x00, 0x00)


def pan_reply(address, physical_centi):
    """What the head answers to query_pan."""
    return _word_frame(address, REPLY_PAN, physical_centi)


def tilt_reply(address, physical_centi):
    return _word_frame(address, REPLY_TILT, physical_centi)


def aux(address, on, aux_id):
    return build_frame(address, 0x00, CMD_SET_AUX if on else CMD_CLEAR_AUX, 0x00, aux_id)


def wiper(address, on):
    return aux(address, on, AUX_WIPER)


def lamp(address, on):
    return aux(address, on, AUX_LAMP)


def move(address, direction_bits, pan_speed=0, tilt_speed=0):
    """Continuous move: cmd2 = OR of DIR_* bits, data1 pan speed, data2 tilt speed."""
    if direction_bits & ~(DIR_RIGHT | DIR_LEFT | DIR_UP | DIR_DOWN):
        raise ValueError("not a direction: 0x%02X" % direction_bits)
    if not 0 <= pan_speed <= TURBO_SPEED or not 0 <= tilt_speed <= MAX_SPEED:
        raise ValueError("speed out of range: pan %r tilt %r" % (pan_speed, tilt_speed))
    return build_frame(address, 0x00, direction_bits, pan_speed, tilt_speed)


def stop(address):
    """terrace_stop: the all-zero standard command."""
    return build_frame(address, 0x00, 0x00, 0x00, 0x00)


class FrameReader(object):
    """Turns a byte stream into frames; resynchronises on 0xFF after garbage or bad checksums.

    A candidate frame with a wrong checksum, or that ``accept(frame)`` refuses (e.g. another
    address: garbage can pass a one-byte checksum by chance), drops only its leading 0xFF, so a
    real frame that starts inside the rejected bytes (data bytes may be 0xFF) is still found.
    """

    def __init__(self, accept=None, max_buffer=4096):
        self._accept = accept
        self._buffer = bytearray()
        self._max_buffer = max_buffer
        self.frames = 0
        self.bad_checksums = 0
        self.discarded_bytes = 0

    def feed(self, data):
        """Add bytes; return the list of complete, valid frames found."""
        self._buffer.extend(data)
        frames = []
        buf = self._buffer
        while True:
            start = buf.find(SYNC)
            if start < 0:
                self.discarded_bytes += len(buf)
                del buf[:]
                break
            if start:
                self.discarded_bytes += start
                del buf[:start]
            if len(buf) < FRAME_LENGTH:
                break
            if checksum(*buf[1:6]) != buf[6]:
                self.bad_checksums += 1
                self.discarded_bytes += 1
                del buf[:1]
                continue
            frame = Frame(*buf[1:6])
            if self._accept is not None and not self._accept(frame):
                self.discarded_bytes += 1
                del buf[:1]
                continue
            frames.append(frame)
            self.frames += 1
            del buf[:FRAME_LENGTH]
        if len(buf) > self._max_buffer:   # cannot happen with 7-byte frames; belt and braces
            self.discarded_bytes += len(buf)
            del buf[:]
        return frames


# --- angle conversion (integer hundredths of a degree, exact) ------------------------------

def _check_physical_pan(centi):
    if not isinstance(centi, int) or not 0 <= centi < FULL_TURN:
        raise ValueError("physical pan must be an integer in 0..35999, got %r" % (centi,))


def _check_physical_tilt(centi):
    if not isinstance(centi, int) or not (0 <= centi <= QUARTER_TURN or TILT_UP_PHYSICAL <= centi < FULL_TURN):
        raise ValueError("physical tilt must be an integer in 0..9000 or 27000..35999, got %r" % (centi,))


def pan_physical_to_standard(centi):
    """Physical pan (0..35999, clockwise) -> standard pan (-17999..18000, counter-clockwise +)."""
    _check_physical_pan(centi)
    standard = (-centi) % FULL_TURN
    return standard - FULL_TURN if standard > HALF_TURN else standard


def pan_standard_to_physical(centi):
    """Standard pan (-17999..18000) -> physical pan (0..35999)."""
    if not isinstance(centi, int) or not -HALF_TURN < centi <= HALF_TURN:
        raise ValueError("standard pan must be an integer in (-18000, 18000], got %r" % (centi,))
    return (-centi) % FULL_TURN


def tilt_physical_to_standard(centi):
    """Physical tilt (0..9000 down, 27000..35999 up) -> standard tilt (-9000..9000, down +)."""
    _check_physical_tilt(centi)
    return centi if centi <= QUARTER_TURN else centi - FULL_TURN


def tilt_standard_to_physical(centi):
    """Standard tilt (-9000..9000) -> physical tilt."""
    if not isinstance(centi, int) or not -QUARTER_TURN <= centi <= QUARTER_TURN:
        raise ValueError("standard tilt must be an integer in [-9000, 9000], got %r" % (centi,))
    return centi if centi >= 0 else centi + FULL_TURN


def wrap_pan_centi(centi):
    """Wrap any integer pan (hundredths) into the standard range (-18000, 18000]."""
    wrapped = int(centi) % FULL_TURN
    return wrapped - FULL_TURN if wrapped > HALF_TURN else wrapped


def degrees_to_centi(degrees):
    """Nearest integer hundredth of a degree."""
    return int(round(float(degrees) * 100.0))


def centi_to_degrees(centi):
    return centi / 100.0


def centi_to_radians(centi):
    return math.radians(centi / 100.0)
