"""inspection_robot.angles: the one wrap / yaw <-> quaternion / focal helper set."""
import math

import pytest

from inspection_robot.angles import quaternion_from_yaw, wrap_angle, yaw_from_quaternion
from inspection_robot.camera.optics import focal_for_hfov


@pytest.mark.parametrize("angle,expected", [(0.0, 0.0), (3 * math.pi / 2, -math.pi / 2), (-7.0, -7.0 + 2 * math.pi),
                                            (2 * math.pi + 0.25, 0.25)])
def test_wrap_angle(angle, expected):
    assert wrap_angle(angle) == pytest.approx(expected)


@pytest.mark.parametrize("yaw", [-3.0, -1.0, 0.0, 0.5, 2.9])
def test_quaternion_round_trip(yaw):
    x, y, z, w = quaternion_from_yaw(yaw)
    assert (x, y) == (0.0, 0.0)
    assert x * x + y * y + z * z + w * w == pytest.approx(1.0)
    assert yaw_from_quaternion(x, y, z, w) == pytest.approx(yaw)


def test_focal_for_hfov():
    # 90 deg across 384 px: the edge is 192 px off-axis at 45 deg, so f = 192 px
    assert focal_for_hfov(384, 90.0) == pytest.approx(192.0)
