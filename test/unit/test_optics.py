"""Zoom -> FOV model shared by camera, preset_rotate and find_scale."""
import math

import pytest

from inspection_robot.camera.optics import ZoomOptics

TABLE = [[1.0, 59.8], [2.0, 31.6], [4.0, 16.2], [8.0, 8.2], [16.0, 4.1], [30.0, 2.2]]


def test_table_rows_are_exact_and_clamped():
    optics = ZoomOptics(TABLE, 1920, 1080)
    assert optics.hfov_deg(1.0) == pytest.approx(59.8)
    assert optics.hfov_deg(30.0) == pytest.approx(2.2)
    assert optics.hfov_deg(100.0) == pytest.approx(2.2)
    assert optics.hfov_deg(1.5) < 59.8 and optics.hfov_deg(1.5) > 31.6


def test_pixel_to_angles_edge_of_picture_is_half_fov():
    optics = ZoomOptics(TABLE, 1920, 1080)
    pan, tilt = optics.pixel_to_angles(1.0, 960, 0, 1920, 1080)
    assert pan == pytest.approx(-59.8 / 2)
    assert tilt == pytest.approx(0.0)
    pan, tilt = optics.pixel_to_angles(4.0, 0, 540, 1920, 1080)
    assert tilt == pytest.approx(-optics.vfov_deg(4.0) / 2)
    # a scaled-down picture of the same view gives the same angles
    assert optics.pixel_to_angles(2.0, 100, 50, 1920, 1080) == pytest.approx(
        optics.pixel_to_angles(2.0, 50, 25, 960, 540))


def test_rejects_bad_tables():
    with pytest.raises(ValueError):
        ZoomOptics([[1.0, 60.0]], 1920, 1080)
    with pytest.raises(ValueError):
        ZoomOptics([[1.0, 60.0], [2.0, 190.0]], 1920, 1080)
    assert math.isfinite(ZoomOptics(TABLE, 640, 480).focal_px(3.3))
