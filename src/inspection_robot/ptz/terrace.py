"""cloud_terrace's command table and preset_rotate geometry (pure: no rospy).

Commands and data formats (INTERFACE.md section 4, "PTZ"); every angle is STANDARD and travels as
integer hundredths of a degree (``"12300"`` = 123.00 deg; decimals such as ``"123.5"`` are refused):

- ``set_pan_angle`` pan, ``set_tilt_angle`` tilt, ``set_angle`` "pan,tilt": complete when the head
  reports the angle (within ``reach_tolerance``) or fail after ``move_timeout`` seconds.
- ``get_pan_angle`` -> "pan", ``get_tilt_angle`` -> "tilt", ``get_angle`` -> "pan,tilt".
- ``pan_left``/``pan_right``/``tilt_up``/``tilt_down`` data ``high_speed|mid_speed|low_speed``:
  continuous move until ``terrace_stop`` (or the head's limit).
- ``terrace_stop``, ``brush_on``/``brush_off`` (wiper), ``light_on``/``light_off`` (lamp): data "".
"""
import math
import time

from inspection_robot.command import (MAX_NUMBER_CHARS, CommandError, CommandTable, no_data, parse_choice,
                                      split_fields)
from inspection_robot.interface import ANGLE_CENTI_DEG, TERRACE_SPEEDS
from inspection_robot.ptz import pelco
from inspection_robot.ptz.driver import HeadError

PAN_MIN_CENTI = -pelco.HALF_TURN + 1      # standard pan is (-18000, 18000]
PAN_MAX_CENTI = pelco.HALF_TURN


def parse_centi(text, name, low, high):
    """A strict integer of hundredths of a degree within [low, high]."""
    text = str(text)
    if text == "":
        raise CommandError("%s is missing" % name)
    if text != text.strip():
        raise CommandError("%s must not contain spaces, got '%s'" % (name, text))
    body = text[1:] if text[:1] in "+-" else text
    if len(body) > MAX_NUMBER_CHARS:
        raise CommandError("%s out of range [%d, %d] (hundredths of a degree): '%s...' (%d characters)"
                           % (name, low, high, text[:20], len(text)))
    if not body.isdigit() or not body.isascii():
        raise CommandError("%s must be an integer number of hundredths of a degree (12300 = 123.00 deg), "
                           "got '%s'" % (name, text))
    value = int(text)
    if not low <= value <= high:
        raise CommandError("%s out of range [%d, %d] (hundredths of a degree): %d" % (name, low, high, value))
    return value


def format_centi(*values):
    return ",".join("%d" % v for v in values)


def pixel_target(pan_deg, tilt_deg, focal_px, delta_x, delta_y):
    """Standard pan/tilt (deg) that puts the pixel at (centre + delta) on the optical axis.

    The ray through the pixel in the camera frame (x forward, y left, z up) is
    (f, -delta_x, delta_y); the head's orientation is Rz(pan) * Ry(tilt) (tilt down + is a
    positive rotation about y). The new angles are the ray's azimuth and depression.
    """
    x, y, z = float(focal_px), -float(delta_x), float(delta_y)
    t = math.radians(tilt_deg)
    x, z = x * math.cos(t) + z * math.sin(t), -x * math.sin(t) + z * math.cos(t)
    p = math.radians(pan_deg)
    x, y = x * math.cos(p) - y * math.sin(p), x * math.sin(p) + y * math.cos(p)
    return math.degrees(math.atan2(y, x)), math.degrees(math.atan2(-z, math.hypot(x, y)))


class Terrace(object):
    """The terrace commands on a :class:`~inspection_robot.ptz.driver.PanTiltHead`.

    ``speeds``: {speed name: Pelco-D speed byte}; ``tilt_limits_centi``: (min, max) standard;
    ``reach_tolerance_centi``; ``move_timeout`` and ``poll_period`` in s; ``sleep``/``clock``
    injectable for tests.
    """

    def __init__(self, head, speeds, tilt_limits_centi=(-9000, 9000), reach_tolerance_centi=1,
                 move_timeout=10.0, poll_period=0.05, sleep=time.sleep, clock=time.monotonic):
        missing = [name for name in TERRACE_SPEEDS if name not in speeds]
        if missing:
            raise ValueError("speeds lacks %s" % ", ".join(missing))
        for name, value in speeds.items():
            if not 1 <= int(value) <= pelco.MAX_SPEED:
                raise ValueError("speed %s must be 1..%d, got %r" % (name, pelco.MAX_SPEED, value))
        low, high = (int(v) for v in tilt_limits_centi)
        if not -pelco.QUARTER_TURN <= low < high <= pelco.QUARTER_TURN:
            raise ValueError("tilt limits must satisfy -9000 <= min < max <= 9000, got %r" % (tilt_limits_centi,))
        self.head = head
        self.speeds = {name: int(value) for name, value in speeds.items()}
        self.tilt_limits = (low, high)
        self.tolerance = int(reach_tolerance_centi)
        self.move_timeout = float(move_timeout)
        self.poll_period = float(poll_period)
        self._sleep = sleep
        self._clock = clock

    def table(self):
        return CommandTable({
            "set_pan_angle": self.set_pan_angle, "get_pan_angle": no_data(self.get_pan_angle),
            "set_tilt_angle": self.set_tilt_angle, "get_tilt_angle": no_data(self.get_tilt_angle),
            "set_angle": self.set_angle, "get_angle": no_data(self.get_angle),
            "pan_left": lambda data: self._move(data, pan=1),
            "pan_right": lambda data: self._move(data, pan=-1),
            "tilt_up": lambda data: self._move(data, tilt=-1),
            "tilt_down": lambda data: self._move(data, tilt=1),
            "terrace_stop": _head_action(self.head.stop),
            "brush_on": _head_action(lambda: self.head.set_wiper(True)),
            "brush_off": _head_action(lambda: self.head.set_wiper(False)),
            "light_on": _head_action(lambda: self.head.set_lamp(True)),
            "light_off": _head_action(lambda: self.head.set_lamp(False)),
        })

    # --- parsing --------------------------------------------------------------------------
    def _pan(self, text):
        return parse_centi(text, "pan", PAN_MIN_CENTI, PAN_MAX_CENTI)

    def _tilt(self, text):
        return parse_centi(text, "tilt", self.tilt_limits[0], self.tilt_limits[1])

    # --- handlers -------------------------------------------------------------------------
    def set_pan_angle(self, data):
        pan = self._pan(data)
        _device(lambda: self.head.set_pan(pan))
        self._wait_reached(pan, None)

    def set_tilt_angle(self, data):
        tilt = self._tilt(data)
        _device(lambda: self.head.set_tilt(tilt))
        self._wait_reached(None, tilt)

    def set_angle(self, data):
        pan_text, tilt_text = split_fields(data, 2)
        pan, tilt = self._pan(pan_text), self._tilt(tilt_text)
        self.go_to(pan, tilt)

    def go_to(self, pan, tilt):
        """Absolute move to standard hundredths; returns when reached, CommandError otherwise."""
        _device(lambda: self.head.set_pan(pan))
        _device(lambda: self.head.set_tilt(tilt))
        self._wait_reached(pan, tilt)

    def get_pan_angle(self, _data):
        return format_centi(_device(self.head.query_pan))

    def get_tilt_angle(self, _data):
        return format_centi(_device(self.head.query_tilt))

    def get_angle(self, _data):
        return format_centi(*self.angles())

    def angles(self):
        """Current standard (pan, tilt) in hundredths; CommandError if the head does not answer."""
        return _device(self.head.query_pan), _device(self.head.query_tilt)

    def _move(self, data, pan=0, tilt=0):
        speed = self.speeds[parse_choice(data, "speed", TERRACE_SPEEDS)]
        _device(lambda: self.head.move(pan, tilt, speed, speed))

    def _wait_reached(self, pan, tilt):
        deadline = self._clock() + self.move_timeout
        last = "no reading"
        while True:
            try:
                now_pan = self.head.query_pan() if pan is not None else None
                now_tilt = self.head.query_tilt() if tilt is not None else None
            except HeadError as err:
                last = str(err)
            else:
                if ((pan is None or _pan_distance(now_pan, pan) <= self.tolerance)
                        and (tilt is None or abs(now_tilt - tilt) <= self.tolerance)):
                    return
                last = "at pan %s tilt %s" % (_deg(now_pan), _deg(now_tilt))
            if not self.head.connected:
                raise CommandError("pan/tilt head not connected: %s" % last)
            if self._clock() >= deadline:
                raise CommandError("pan/tilt head did not reach pan %s tilt %s within %.1f s (%s)"
                                   % (_deg(pan), _deg(tilt), self.move_timeout, last))
            self._sleep(self.poll_period)

    # --- preset_rotate ----------------------------------------------------------------------
    def pixel_target(self, optics, zoom, width, height, delta_x, delta_y):
        """Standard (pan, tilt) hundredths that centre the pixel (delta_x right +, delta_y up +
        from the picture centre) of a ``width`` x ``height`` picture at ``zoom``; tilt is clamped
        to the limits. Reads the current angles from the head."""
        if width <= 0 or height <= 0:
            raise CommandError("picture size must be positive, got %dx%d" % (width, height))
        if abs(delta_x) > width / 2.0 or abs(delta_y) > height / 2.0:
            raise CommandError("offset (%d, %d) lies outside a %dx%d picture" % (delta_x, delta_y, width, height))
        pan, tilt = self.angles()
        new_pan, new_tilt = pixel_target(pan / float(ANGLE_CENTI_DEG), tilt / float(ANGLE_CENTI_DEG),
                                         optics.focal_px(zoom, width), delta_x, delta_y)
        target_pan = pelco.wrap_pan_centi(pelco.degrees_to_centi(new_pan))
        target_tilt = min(max(pelco.degrees_to_centi(new_tilt), self.tilt_limits[0]), self.tilt_limits[1])
        return target_pan, target_tilt


def _pan_distance(a, b):
    return abs(pelco.wrap_pan_centi(a - b))


def _deg(centi):
    return "-" if centi is None else "%.2f" % (centi / float(ANGLE_CENTI_DEG))


def _head_action(action):
    """The handler of a command without data that runs one head action and answers nothing."""
    def run(_data):
        _device(action)
    return no_data(run)


def _device(action):
    try:
        return action()
    except HeadError as err:
        raise CommandError(str(err))
