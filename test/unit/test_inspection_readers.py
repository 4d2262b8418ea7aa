"""Readers on synthetic faces of every style: pointer gauges, lamps, switches, thermal boxes."""
import numpy as np
import pytest

from inspection_robot.sim import fixtures as S
from inspection_robot.inspection.gauge import GaugeScale
from inspection_robot.inspection.readers import LAMP_CODES, PointerReader, read_lamp, read_switch, \
    read_thermal_max, switch_patch


def _scene(patch, rng, centre=(200, 150), side=170, yaw=20.0, pitch=-10.0, roll=5.0, **degrade):
    scene = S.textured_background(400, 300, rng)
    quad = S.perspective_quad(centre, side, yaw, pitch, roll)
    S.paste(scene, patch, quad)
    return S.degrade(scene, rng, **degrade), quad


@pytest.mark.parametrize("style", sorted(S.GAUGE_STYLES))
def test_pointer_reader_every_style_within_half_percent(style):
    rng = np.random.default_rng(7)
    scale = S.style_scale(style, 0.0, 2.5)
    reader = PointerReader()
    for value in (0.0, 0.31, 1.25, 1.9, 2.5):
        image, quad = _scene(S.draw_gauge_face(scale, value, 300, style), rng, blur=0.7)
        reading = reader.read(image, quad, scale)
        assert scale.error_percent_fs(reading.value, value) < 0.5, (style, value, reading)
        assert reading.confidence > 50


def test_pointer_reader_survives_glare_and_dim_light():
    rng = np.random.default_rng(3)
    scale = S.style_scale("classic")
    image, quad = _scene(S.draw_gauge_face(scale, 0.4, 300), rng, gain=0.6,
                         glare=(170, 140, 12), noise=4.0)
    reading = PointerReader().read(image, quad, scale)
    assert scale.error_percent_fs(reading.value, 0.4) < 1.0


def test_pointer_reader_non_linear_scale():
    rng = np.random.default_rng(4)
    table = [(0, 225), (10, 270), (40, 0), (90, 90), (100, 135)]
    scale = GaugeScale(225, 135, 0, 100, table=table)
    image, quad = _scene(S.draw_gauge_face(scale, 63.0, 300), rng)
    assert PointerReader().read(image, quad, scale).value == pytest.approx(63.0, abs=0.5)


def test_pointer_confidence_drops_without_a_needle():
    rng = np.random.default_rng(5)
    scale = S.style_scale("classic")
    blank = np.full((300, 300, 3), 230, np.uint8)
    image, quad = _scene(blank, rng)
    good, quad2 = _scene(S.draw_gauge_face(scale, 1.0, 300), rng)
    reader = PointerReader()
    assert reader.read(image, quad, scale).confidence < reader.read(good, quad2, scale).confidence / 2


@pytest.mark.parametrize("name,bgr", [("red", (30, 30, 230)), ("green", (40, 210, 40)),
                                      ("yellow", (20, 220, 230)), ("blue", (230, 90, 20))])
def test_lamp_on_off_and_colour(name, bgr):
    rng = np.random.default_rng(9)
    on, quad = _scene(S.draw_lamp(bgr, True), rng, side=60, gain=0.8)
    off, quad_off = _scene(S.draw_lamp(bgr, False), rng, side=60, gain=1.2)
    reading = read_lamp(on, quad, name)
    assert reading.value == LAMP_CODES[name], reading
    assert reading.confidence > 50
    assert read_lamp(off, quad_off, name).value == 0.0


def test_switch_position_against_references():
    rng = np.random.default_rng(11)
    ref_scene_open, quad = _scene(S.draw_switch(False), rng, side=80, yaw=0, pitch=0, roll=0)
    ref_scene_closed, _ = _scene(S.draw_switch(True), rng, side=80, yaw=0, pitch=0, roll=0)
    open_ref, closed_ref = switch_patch(ref_scene_open, quad), switch_patch(ref_scene_closed, quad)
    for closed in (False, True):
        image, q = _scene(S.draw_switch(closed), rng, side=90, gain=0.7, offset=20)
        reading = read_switch(image, q, open_ref, closed_ref)
        assert reading.value == (1.0 if closed else 0.0)
        assert reading.confidence > 40


def test_thermal_max_inside_the_box_only():
    frame = np.full((120, 160), 25.0, np.float32)
    frame[40:50, 60:70] = 81.5
    frame[100:110, 5:10] = 300.0  # hotter, but outside the box
    quad = [[50, 30], [90, 30], [90, 70], [50, 70]]
    reading = read_thermal_max(frame, quad)
    assert reading.value == pytest.approx(81.5)
    assert reading.confidence > 90
    with pytest.raises(ValueError):
        read_thermal_max(frame, [[500, 500], [510, 500], [510, 510], [500, 510]])
