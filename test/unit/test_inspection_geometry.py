"""Quad helpers: roi_vertex packing, inside/convex checks, IoU."""
import numpy as np
import pytest

from inspection_robot.inspection.geometry import flat_from_quads, quad_inside, quad_iou, quad_is_convex, \
    quads_from_flat


def test_flat_round_trip_and_bad_length():
    flat = [1, 2, 11, 2, 11, 12, 1, 12, 5, 5, 6, 5, 6, 6, 5, 6]
    quads = quads_from_flat(flat)
    assert len(quads) == 2
    assert flat_from_quads(quads) == flat
    with pytest.raises(ValueError):
        quads_from_flat([1, 2, 3])


def test_inside_convex_iou():
    square = np.array([[0, 0], [10, 0], [10, 10], [0, 10]], float)
    assert quad_inside(square, 11, 11)
    assert not quad_inside(square + 5, 11, 11)
    assert quad_is_convex(square)
    assert not quad_is_convex(square[[0, 2, 1, 3]])
    assert quad_iou(square, square) == pytest.approx(1.0)
    assert quad_iou(square, square + [5, 0]) == pytest.approx(1.0 / 3.0, abs=1e-6)


def test_quad_overlap_is_the_share_inside_the_picture():
    from inspection_robot.inspection.geometry import quad_overlap
    assert quad_overlap([[10, 10], [50, 10], [50, 50], [10, 50]], 100, 100) == pytest.approx(1.0)
    assert quad_overlap([[-40, 10], [40, 10], [40, 50], [-40, 50]], 100, 100) == pytest.approx(0.5, abs=0.02)
    assert quad_overlap([[200, 10], [240, 10], [240, 50], [200, 50]], 100, 100) == 0.0
