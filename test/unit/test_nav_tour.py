"""nav.tour: the shortest visiting order, exact for small patrols, near-exact for large ones, planning
only the pairs the order needs."""
import itertools
import math
import random

import numpy as np
import pytest

from inspection_robot.nav.tour import EXACT_MAX_STOPS, TourError, order_points, path_length, shortest_order


def brute_force(d):
    n = len(d)
    best = min(itertools.permutations(range(1, n - 1)), key=lambda p: path_length(d, (0,) + p + (n - 1,)))
    return path_length(d, (0,) + best + (n - 1,))


def euclidean(points):
    xy = np.asarray(points, dtype=float)
    return np.hypot(*(xy[:, None, :] - xy[None, :, :]).transpose(2, 0, 1))


@pytest.mark.parametrize("seed", range(12))
def test_exact_for_small_patrols(seed):
    rng = random.Random(seed)
    n = rng.randint(3, 9)
    d = euclidean([(rng.uniform(0, 50), rng.uniform(0, 50)) for _ in range(n)])
    d = d * np.array([[rng.uniform(1.0, 1.6) for _ in range(n)] for _ in range(n)])  # roads, not lines
    order, length = shortest_order(d)
    assert order[0] == 0 and order[-1] == n - 1 and sorted(order) == list(range(n))
    assert length == pytest.approx(path_length(d, order))
    sym = (d + d.T) / 2
    assert path_length(sym, order) == pytest.approx(brute_force(sym))


def test_large_patrol_on_a_circle_finds_the_circle():
    """Stops on a circle, start and end together: the shortest closed tour walks round the circle."""
    n = 60
    angles = [2 * math.pi * k / n for k in range(n)]
    rng = random.Random(3)
    stops = [(50 + 40 * math.cos(a), 50 + 40 * math.sin(a)) for a in angles]
    rng.shuffle(stops)
    home = (90.0, 50.0)
    d = euclidean([home] + stops + [home])
    order, length = shortest_order(d)
    perimeter = n * 2 * 40 * math.sin(math.pi / n)
    assert n - 2 > EXACT_MAX_STOPS and length == pytest.approx(perimeter, rel=1e-6)


def test_same_stops_same_order():
    rng = random.Random(7)
    d = euclidean([(rng.uniform(0, 100), rng.uniform(0, 100)) for _ in range(40)])
    assert shortest_order(d) == shortest_order(d)


def test_order_points_plans_only_what_the_order_needs_and_every_leg_is_planned():
    rng = random.Random(11)
    points = [(rng.uniform(0, 200), rng.uniform(0, 200)) for _ in range(40)]
    true = euclidean(points) * 1.3 + 5.0   # every path longer than its straight line
    measured = []

    def measure(i, j):
        measured.append((min(i, j), max(i, j)))
        return true[i, j]
    order, length, planned = order_points(points, measure)
    assert len(set(measured)) == len(measured) == planned < 40 * 39 / 2 / 2
    assert all((min(a, b), max(a, b)) in set(measured) for a, b in zip(order, order[1:]))
    assert length == pytest.approx(path_length(true, order))
    full_order, full_length = shortest_order(true)
    assert length <= full_length * 1.05


def test_errors_name_what_is_wrong():
    with pytest.raises(TourError, match="square matrix"):
        shortest_order([[0.0, 1.0]])
    with pytest.raises(TourError, match="no path from point 1 to point 2"):
        shortest_order([[0, 1, 1], [1, 0, math.inf], [1, math.inf, 0]])
    with pytest.raises(TourError, match="non-negative"):
        shortest_order([[0, -1], [-1, 0]])

    def unreachable(i, j):
        return math.inf if 2 in (i, j) else 1.0
    with pytest.raises(TourError, match="no path from point"):
        order_points([(0, 0), (1, 0), (2, 0), (3, 0)], unreachable)
