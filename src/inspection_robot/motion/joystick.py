"""Joystick teleoperation (joy_control's logic) and the Linux joystick event decoder.

JoyTeleop turns sensor_msgs/Joy axes/buttons (mapping from config/joy_control.yaml) into actions:
- ``("mode", cmd, data)``: acquire joy / release, on the button's press;
- ``("control", cmd)``: enable_stop / disable_stop, on the button's press;
- ``("move", velocity_x_units, velocity_yaw_units, wheel_control)``: every tick while the
  dead-man button is held; one explicit zero when it is released or the Joy stream goes silent
  for ``joy_timeout`` (a lost wireless link must not repeat the last command);
- ``("terrace", cmd, data)``: pan_left/pan_right/tilt_up/tilt_down/terrace_stop, on change of the
  right stick's dominant direction (terrace_stop also when the stream goes silent).
Axes follow the ROS joy convention: up and left are +1.

JsDecoder decodes ``struct js_event`` (linux/joystick.h: u32 time ms, s16 value, u8 type,
u8 number; 8 bytes, native little-endian) into axes/buttons in the same convention.
"""
import math
import struct

from inspection_robot.interface import (MODE_CMD_ACQUIRE, MODE_CMD_RELEASE, MODE_JOY, MODE_NAMES,
                                        MOVE_VELOCITY_X_UNIT_M_S, MOVE_VELOCITY_YAW_UNIT_RAD_S, TERRACE_SPEEDS,
                                        WHEEL_STEER, WHEEL_STRAIGHT)

AXIS_NAMES = ("velocity_x", "velocity_yaw", "pan", "tilt")
BUTTON_NAMES = ("deadman", "acquire", "release", "estop", "estop_release", "steer_mode")
TERRACE_THRESHOLD = 0.5  # stick deflection that starts the pan/tilt head


class JoyTeleop(object):
    def __init__(self, axes, buttons, max_velocity_x, max_velocity_yaw, deadzone=0.1, joy_timeout=0.5,
                 terrace_speed="mid_speed"):
        missing = [n for n in AXIS_NAMES if n not in axes] + [n for n in BUTTON_NAMES if n not in buttons]
        if missing:
            raise ValueError("joystick mapping lacks %s" % ", ".join(missing))
        if terrace_speed not in TERRACE_SPEEDS:
            raise ValueError("terrace_speed must be one of %s" % (TERRACE_SPEEDS,))
        if not (0.0 <= deadzone < 1.0 and max_velocity_x > 0 and max_velocity_yaw > 0 and joy_timeout > 0):
            raise ValueError("bad joystick limits")
        self._axes = {n: int(axes[n]) for n in AXIS_NAMES}
        self._buttons = {n: int(buttons[n]) for n in BUTTON_NAMES}
        self.max_velocity_x = float(max_velocity_x)
        self.max_velocity_yaw = float(max_velocity_yaw)
        self.deadzone = float(deadzone)
        self.joy_timeout = float(joy_timeout)
        self.terrace_speed = terrace_speed
        self._pressed = {n: False for n in BUTTON_NAMES}
        self._stick = {n: 0.0 for n in AXIS_NAMES}
        self._last_joy = None
        self._moving = False
        self._terrace = "terrace_stop"

    def on_joy(self, axes, buttons, now):
        """A Joy message; returns the actions its button presses and stick changes cause."""
        self._last_joy = now
        actions = []
        pressed = {n: _index(buttons, i) > 0 for n, i in self._buttons.items()}
        self._stick = {n: self._shape(_index(axes, i)) for n, i in self._axes.items()}
        edges = {n for n in BUTTON_NAMES if pressed[n] and not self._pressed[n]}
        self._pressed = pressed
        if "estop" in edges:
            actions.append(("control", "enable_stop"))
        if "estop_release" in edges:
            actions.append(("control", "disable_stop"))
        if "acquire" in edges:
            actions.append(("mode", MODE_CMD_ACQUIRE, MODE_NAMES[MODE_JOY]))
        if "release" in edges:
            actions += self._stop_moving()
            actions.append(("mode", MODE_CMD_RELEASE, ""))
        if not pressed["deadman"]:
            actions += self._stop_moving()
        terrace = self._terrace_command()
        if terrace != self._terrace:
            self._terrace = terrace
            actions.append(("terrace", terrace, "" if terrace == "terrace_stop" else self.terrace_speed))
        return actions

    def tick(self, now):
        """Periodic: move_cmd while the dead-man is held; stop everything when the stream is silent."""
        if self._last_joy is None:
            return []
        if now - self._last_joy > self.joy_timeout:
            actions = self._stop_moving()
            self._pressed = {n: False for n in BUTTON_NAMES}
            if self._terrace != "terrace_stop":
                self._terrace = "terrace_stop"
                actions.append(("terrace", "terrace_stop", ""))
            return actions
        if not self._pressed["deadman"]:
            return []
        self._moving = True
        steer = self._pressed["steer_mode"]
        vx = 0.0 if steer else self._stick["velocity_x"] * self.max_velocity_x
        wz = self._stick["velocity_yaw"] * self.max_velocity_yaw
        return [("move", round(vx / MOVE_VELOCITY_X_UNIT_M_S), round(wz / MOVE_VELOCITY_YAW_UNIT_RAD_S),
                 WHEEL_STEER if steer else WHEEL_STRAIGHT)]

    def _stop_moving(self):
        if not self._moving:
            return []
        self._moving = False
        return [("move", 0, 0, WHEEL_STEER if self._pressed["steer_mode"] else WHEEL_STRAIGHT)]

    def _shape(self, value):
        if not math.isfinite(value):
            return 0.0
        value = max(-1.0, min(1.0, value))
        if abs(value) <= self.deadzone:
            return 0.0
        return math.copysign((abs(value) - self.deadzone) / (1.0 - self.deadzone), value)

    def _terrace_command(self):
        pan, tilt = self._stick["pan"], self._stick["tilt"]
        if max(abs(pan), abs(tilt)) < TERRACE_THRESHOLD:
            return "terrace_stop"
        if abs(pan) >= abs(tilt):
            return "pan_left" if pan > 0 else "pan_right"
        return "tilt_up" if tilt > 0 else "tilt_down"


def _index(values, i):
    try:
        return float(values[i])
    except (IndexError, TypeError, ValueError):
        return 0.0


JS_EVENT = struct.Struct("<IhBB")
JS_EVENT_BUTTON = 0x01
JS_EVENT_AXIS = 0x02
JS_EVENT_INIT = 0x80
JS_AXIS_MAX = 32767.0
MAX_INDEX = 64  # a larger axis/button number is corrupt data


class JsDecoder(object):
    """Feed raw bytes from /dev/input/jsN; keeps the current axes (ROS sign: up/left +) and buttons."""

    def __init__(self):
        self.axes = []
        self.buttons = []
        self._buffer = b""

    def feed(self, data):
        """Decode every complete event in ``data`` (partial events wait for more); returns the event count."""
        self._buffer += data
        count = 0
        while len(self._buffer) >= JS_EVENT.size:
            _time_ms, value, kind, number = JS_EVENT.unpack_from(self._buffer)
            self._buffer = self._buffer[JS_EVENT.size:]
            kind &= ~JS_EVENT_INIT
            if number >= MAX_INDEX:
                continue
            if kind == JS_EVENT_AXIS:
                _grow(self.axes, number, 0.0)
                self.axes[number] = max(-1.0, min(1.0, -value / JS_AXIS_MAX))
                count += 1
            elif kind == JS_EVENT_BUTTON:
                _grow(self.buttons, number, 0)
                self.buttons[number] = 1 if value else 0
                count += 1
        return count


def _grow(values, index, fill):
    while len(values) <= index:
        values.append(fill)


def js_event(kind, number, value, time_ms=0):
    """Encode one js_event (for tests and simulators)."""
    return JS_EVENT.pack(time_ms & 0xFFFFFFFF, value, kind, number)
