"""Pointer-gauge maths: angle <-> value, wrap-around, dead zone, non-linear tables."""
import pytest

from inspection_robot.inspection.gauge import GaugeScale, angle_diff, wrap360


def test_wrap_and_diff():
    assert wrap360(-90) == 270
    assert wrap360(720.5) == pytest.approx(0.5)
    assert angle_diff(10, 350) == pytest.approx(20)
    assert angle_diff(350, 10) == pytest.approx(-20)


def test_linear_270_degree_dial_wraps_through_12_oclock():
    scale = GaugeScale(225, 135, 0.0, 1.6)
    assert scale.sweep == pytest.approx(270)
    assert scale.value(225) == pytest.approx(0.0)
    assert scale.value(0) == pytest.approx(0.8)      # straight up is mid-scale
    assert scale.value(135) == pytest.approx(1.6)
    assert scale.value(270) == pytest.approx(0.8 * 45 / 135)
    for v in (0.0, 0.123, 0.8, 1.59, 1.6):
        assert scale.value(scale.angle(v)) == pytest.approx(v)
    assert scale.full_scale == pytest.approx(1.6)


def test_dead_zone_clamps_to_nearer_end():
    scale = GaugeScale(225, 135, 0.0, 1.6)
    assert scale.value(150) == pytest.approx(1.6)
    assert scale.value(210) == pytest.approx(0.0)
    assert not scale.in_sweep(180)
    assert scale.in_sweep(220, margin_deg=6)


def test_falling_scale_and_value_clamping():
    scale = GaugeScale(300, 60, 100.0, -20.0)
    assert scale.value(0) == pytest.approx(40.0)
    assert scale.angle(1000.0) == pytest.approx(300.0)   # above the start value: clamps to the start
    assert scale.angle(-1000.0) == pytest.approx(60.0)


def test_non_linear_table():
    # a square-root-like flow scale: marks crowd at the start
    table = [(0, 225), (10, 270), (40, 0), (90, 90), (100, 135)]
    scale = GaugeScale(225, 135, 0, 100, table=table)
    assert scale.value(270) == pytest.approx(10)
    assert scale.value(315) == pytest.approx(25)
    assert scale.value(45) == pytest.approx(65)
    for v in (0, 5, 10, 33, 40, 77, 100):
        assert scale.value(scale.angle(v)) == pytest.approx(v)


def test_bad_tables_and_ranges_raise():
    with pytest.raises(ValueError):
        GaugeScale(0, 90, 1, 1)
    with pytest.raises(ValueError):
        GaugeScale(225, 135, 0, 100, table=[(0, 225)])
    with pytest.raises(ValueError):
        GaugeScale(225, 135, 0, 100, table=[(0, 225), (50, 0), (40, 90)])
    with pytest.raises(ValueError):
        GaugeScale(225, 135, 0, 100, table=[(0, 225), (50, 90), (60, 0)])


def test_error_percent_of_full_scale():
    scale = GaugeScale(225, 135, 0.0, 1.6)
    assert scale.error_percent_fs(0.816, 0.8) == pytest.approx(1.0)
