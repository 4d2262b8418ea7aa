"""Localisation of target boxes in a moved/zoomed view with known truth."""
import cv2
import numpy as np
import pytest

from inspection_robot_testing import fixtures as S
from inspection_robot.inspection.geometry import quad_iou, transform_quad
from inspection_robot.inspection.locate import LocateError, Locator
from inspection_robot.inspection.pointer import PointerReader

W, H = 640, 360


def _pair(rng, value, angle_deg=2.0, scale=1.1, shift=(30, -20)):
    style = "classic"
    gauge = S.style_scale(style)
    bg = S.textured_background(W, H, rng)
    quad = S.perspective_quad((W / 2 - 40, H / 2), 150, 20, -10, 3)
    ref = S.paste(bg.copy(), S.draw_gauge_face(gauge, 0.3, 300, style), quad)
    a = np.radians(angle_deg)
    move = np.array([[scale * np.cos(a), -scale * np.sin(a), 0], [scale * np.sin(a), scale * np.cos(a), 0],
                     [0, 0, 1.0]])
    centre = np.array([[1, 0, -W / 2], [0, 1, -H / 2], [0, 0, 1]])
    move = np.linalg.inv(centre).dot(move).dot(centre)
    move[:2, 2] += shift
    new = cv2.warpPerspective(bg, move, (W, H), borderMode=cv2.BORDER_REFLECT)
    true_quad = transform_quad(move, quad)
    S.paste(new, S.draw_gauge_face(gauge, value, 300, style), true_quad)
    return ref, S.degrade(new, rng, gain=0.8, blur=0.6), quad, true_quad, gauge


@pytest.mark.parametrize("detector", ["orb", "akaze", "sift"])
def test_locate_and_read_after_a_ptz_move(detector):
    rng = np.random.default_rng(21)
    ref, new, quad, true_quad, gauge = _pair(rng, 1.1)
    located = Locator(detector).locate(ref, new, [quad])
    assert quad_iou(located.quads[0], true_quad) > 0.97
    assert np.abs(located.quads[0] - true_quad).max() < 3.0
    reading = PointerReader().read(new, located.quads[0], gauge)
    assert gauge.error_percent_fs(reading.value, 1.1) < 0.5


def test_locate_fails_with_a_reason_on_an_unrelated_picture():
    rng = np.random.default_rng(22)
    ref, _new, quad, _t, _g = _pair(rng, 1.0)
    other = S.textured_background(W, H, np.random.default_rng(99))
    with pytest.raises(LocateError) as err:
        Locator("orb").locate(ref, other, [quad])
    assert "reference" in str(err.value) or "degenerate" in str(err.value)


def test_locate_fails_on_a_blank_picture():
    rng = np.random.default_rng(23)
    ref, _new, quad, _t, _g = _pair(rng, 1.0)
    with pytest.raises(LocateError):
        Locator("orb").locate(ref, np.full((H, W, 3), 128, np.uint8), [quad])
