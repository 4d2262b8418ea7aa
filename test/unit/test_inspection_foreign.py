"""Foreign-object detection with and without an injected object, under a lighting change."""
import cv2
import numpy as np

from inspection_robot_testing import fixtures as S
from inspection_robot.inspection.foreign import detect_foreign
from inspection_robot.inspection.geometry import quad_iou, transform_quad
from inspection_robot.inspection.locate import Locator

W, H = 640, 360


def _views(rng, with_object):
    bg = S.textured_background(W, H, rng)
    move = np.array([[1.05, 0.01, 20], [-0.01, 1.05, -12], [0, 0, 1.0]])
    new = cv2.warpPerspective(bg, move, (W, H), borderMode=cv2.BORDER_REFLECT)
    truth = None
    if with_object:  # a bird's nest: a brown tangle of strokes
        x0, y0 = 300, 150
        cv2.ellipse(new, (x0 + 40, y0 + 25), (42, 26), 0, 0, 360, (30, 60, 90), -1)
        for _ in range(40):
            p = (int(x0 + rng.integers(0, 80)), int(y0 + rng.integers(0, 50)))
            q = (p[0] + int(rng.integers(-15, 15)), p[1] + int(rng.integers(-8, 8)))
            cv2.line(new, p, q, (20, 90, 130), 2)
        truth = np.array([[x0 - 2, y0], [x0 + 82, y0], [x0 + 82, y0 + 51], [x0 - 2, y0 + 51]], float)
    new = S.degrade(new, rng, gain=0.75, offset=10, noise=3.0)
    return bg, new, move, truth


def test_no_false_alarm_without_an_object():
    rng = np.random.default_rng(31)
    ref, new, _move, _ = _views(rng, False)
    located = Locator("orb").locate(ref, new, [[[10, 10], [20, 10], [20, 20], [10, 20]]])
    assert detect_foreign(ref, new, located.homography) == []


def test_injected_object_is_found_where_it_is():
    rng = np.random.default_rng(32)
    ref, new, _move, truth = _views(rng, True)
    located = Locator("orb").locate(ref, new, [[[10, 10], [20, 10], [20, 20], [10, 20]]])
    found = detect_foreign(ref, new, located.homography)
    assert found, "nest not found"
    assert quad_iou(found[0].quad, truth) > 0.5
    assert found[0].confidence > 50


def test_region_limits_the_search():
    rng = np.random.default_rng(32)
    ref, new, move, _truth = _views(rng, True)
    region = transform_quad(move, [[0, 0], [200, 0], [200, 120], [0, 120]])
    assert detect_foreign(ref, new, move, region=region) == []
