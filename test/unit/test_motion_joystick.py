"""joy_control's teleop logic and the Linux joystick event decoder."""
import pytest

from inspection_robot.motion.joystick import (JS_EVENT_AXIS, JS_EVENT_BUTTON, JS_EVENT_INIT, JoyTeleop, JsDecoder,
                                              js_event)

AXES = {"velocity_x": 1, "velocity_yaw": 0, "pan": 3, "tilt": 4}
BUTTONS = {"deadman": 4, "acquire": 7, "release": 6, "estop": 1, "estop_release": 2, "steer_mode": 5}


def teleop():
    return JoyTeleop(AXES, BUTTONS, max_velocity_x=0.8, max_velocity_yaw=0.5, deadzone=0.1, joy_timeout=0.5)


def joy(axes=None, buttons=()):
    a = [0.0] * 6
    for i, v in (axes or {}).items():
        a[i] = v
    b = [0] * 8
    for i in buttons:
        b[i] = 1
    return a, b


def test_acquire_release_estop_on_press_edges_only():
    t = teleop()
    assert t.on_joy(*joy(buttons=[7]), now=0.0) == [("mode", "acquire", "joy")]
    assert t.on_joy(*joy(buttons=[7]), now=0.1) == []
    assert t.on_joy(*joy(buttons=[1]), now=0.2) == [("control", "enable_stop")]
    assert t.on_joy(*joy(buttons=[2]), now=0.3) == [("control", "disable_stop")]
    assert t.on_joy(*joy(buttons=[6]), now=0.4) == [("mode", "release", "")]


def test_deadman_moves_and_sends_one_stop_on_release():
    t = teleop()
    t.on_joy(*joy({1: 1.0, 0: -0.55}, buttons=[4]), now=0.0)
    assert t.tick(0.05) == [("move", 800, -250, 0)]
    assert t.on_joy(*joy({1: 1.0}), now=0.1) == [("move", 0, 0, 0)]
    assert t.tick(0.15) == []
    assert t.on_joy(*joy({1: 1.0}), now=0.2) == []


def test_no_motion_without_deadman_and_deadzone():
    t = teleop()
    t.on_joy(*joy({1: 1.0}), now=0.0)
    assert t.tick(0.05) == []
    t.on_joy(*joy({1: 0.05, 0: -0.09}, buttons=[4]), now=0.1)
    assert t.tick(0.15) == [("move", 0, 0, 0)]


def test_steer_mode_button_spins_in_place():
    t = teleop()
    t.on_joy(*joy({1: 1.0, 0: 1.0}, buttons=[4, 5]), now=0.0)
    assert t.tick(0.05) == [("move", 0, 500, 1)]


def test_silent_stream_stops_once():
    t = teleop()
    t.on_joy(*joy({1: 1.0, 3: 1.0}, buttons=[4]), now=0.0)
    assert t.tick(0.1) == [("move", 800, 0, 0)]
    assert t.tick(0.7) == [("move", 0, 0, 0), ("terrace", "terrace_stop", "")]
    assert t.tick(0.8) == []


def test_terrace_commands_on_direction_change():
    t = teleop()
    assert t.on_joy(*joy({3: 0.9}), now=0.0) == [("terrace", "pan_left", "mid_speed")]
    assert t.on_joy(*joy({3: 0.8}), now=0.1) == []
    assert t.on_joy(*joy({3: -0.9}), now=0.2) == [("terrace", "pan_right", "mid_speed")]
    assert t.on_joy(*joy({4: 0.9, 3: 0.2}), now=0.3) == [("terrace", "tilt_up", "mid_speed")]
    assert t.on_joy(*joy({4: -0.9}), now=0.4) == [("terrace", "tilt_down", "mid_speed")]
    assert t.on_joy(*joy(), now=0.5) == [("terrace", "terrace_stop", "")]


def test_bad_joy_input_is_harmless():
    t = teleop()
    assert t.on_joy([float("nan")], [1], now=0.0) == []  # short arrays: missing = 0
    t.on_joy([float("inf"), float("nan")] + [0.0] * 4, [0, 0, 0, 0, 1], now=0.1)
    assert t.tick(0.15) == [("move", 0, 0, 0)]


def test_bad_mapping_rejected():
    with pytest.raises(ValueError):
        JoyTeleop({}, BUTTONS, 1.0, 1.0)
    with pytest.raises(ValueError):
        JoyTeleop(AXES, BUTTONS, 1.0, 1.0, terrace_speed="warp")
    with pytest.raises(ValueError):
        JoyTeleop(AXES, BUTTONS, 0.0, 1.0)


def test_js_decoder_init_events_axes_sign_and_partial_reads():
    dec = JsDecoder()
    data = (js_event(JS_EVENT_BUTTON | JS_EVENT_INIT, 0, 0) + js_event(JS_EVENT_AXIS | JS_EVENT_INIT, 1, 0)
            + js_event(JS_EVENT_AXIS, 1, -32767) + js_event(JS_EVENT_BUTTON, 4, 1))
    assert dec.feed(data[:13]) == 1
    assert dec.feed(data[13:]) == 3
    assert dec.axes == [0.0, 1.0]  # stick pushed up = raw negative = +1
    assert dec.buttons == [0, 0, 0, 0, 1]
    dec.feed(js_event(JS_EVENT_AXIS, 0, -32768))
    assert dec.axes[0] == 1.0
    assert dec.feed(js_event(JS_EVENT_AXIS, 200, 5) + js_event(0x40, 1, 5)) == 0  # corrupt: ignored
