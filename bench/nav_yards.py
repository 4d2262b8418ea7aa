"""Synthetic 200 m x 200 m substation yards at 5 cm for the navigation benchmark (bench_nav.py).

Four styles, each reproducible from a seed (occupancy 0 free / 100 occupied, row 0 at y = 0):

- ``bays``: equipment bays on a grid (transformers, breakers, gantry footings) with roads between;
- ``fences``: long internal fences, each with one or two gates;
- ``posts``: an open yard strewn with 1,500 small posts and a few equipment blocks;
- ``walls``: an open yard crossed by long straight and L-shaped walls.
"""
import cv2
import numpy as np

from inspection_robot.nav.gridmap import GridMap

RES = 0.05
SIZE_M = 200.0
STYLES = ("bays", "fences", "posts", "walls")


def _cells(metres):
    return int(round(metres / RES))


def _rect(occ, x, y, w, h):
    r0, c0 = _cells(y), _cells(x)
    occ[max(r0, 0):max(r0 + max(_cells(h), 1), 0), max(c0, 0):max(c0 + max(_cells(w), 1), 0)] = 100


def _line(occ, a, b, thickness_m=0.1):
    cv2.line(occ, (_cells(a[0]), _cells(a[1])), (_cells(b[0]), _cells(b[1])), 100,
             thickness=max(_cells(thickness_m), 1), lineType=cv2.LINE_8)


def _bays(occ, rng):
    bay, road = 24.0, 6.0
    y = 8.0
    while y + bay < SIZE_M - 8.0:
        x = 8.0
        while x + bay < SIZE_M - 8.0:
            kind = rng.integers(0, 4)
            if kind == 0:  # fenced bay with a gate on a random side
                _line(occ, (x, y), (x + bay, y))
                _line(occ, (x, y + bay), (x + bay, y + bay))
                _line(occ, (x, y), (x, y + bay))
                _line(occ, (x + bay, y), (x + bay, y + bay))
                gate = rng.uniform(x + 4.0, x + bay - 8.0)
                _clear(occ, gate, (y if rng.random() < 0.5 else y + bay) - 0.3, 4.0, 0.6)
                _rect(occ, x + 8.0, y + 8.0, 8.0, 6.0)  # transformer inside
            elif kind == 1:  # rows of breakers
                for i in range(4):
                    for j in range(3):
                        _rect(occ, x + 2.0 + i * 5.5, y + 3.0 + j * 7.0, 1.2, 2.5)
            elif kind == 2:  # gantry footings
                for i in range(5):
                    for j in range(2):
                        _rect(occ, x + 1.0 + i * 5.0, y + 4.0 + j * 14.0, 0.6, 0.6)
            else:
                _rect(occ, x + rng.uniform(1, 8), y + rng.uniform(1, 8), rng.uniform(4, 12), rng.uniform(4, 12))
            x += bay + road
        y += bay + road


def _clear(occ, x, y, w, h):
    r0, c0 = max(_cells(y), 0), max(_cells(x), 0)
    occ[r0:r0 + _cells(h), c0:c0 + _cells(w)] = 0


def _fences(occ, rng):
    for _ in range(10):
        horizontal = rng.random() < 0.5
        at = rng.uniform(15.0, SIZE_M - 15.0)
        lo, hi = sorted(rng.uniform(2.0, SIZE_M - 2.0, 2))
        if hi - lo < 60.0:
            lo, hi = 2.0, SIZE_M - 2.0
        a, b = ((lo, at), (hi, at)) if horizontal else ((at, lo), (at, hi))
        _line(occ, a, b, 0.15)
        for _gate in range(rng.integers(1, 3)):
            g = rng.uniform(lo + 2.0, hi - 6.0)
            if horizontal:
                _clear(occ, g, at - 0.3, 3.5, 0.6)
            else:
                _clear(occ, at - 0.3, g, 0.6, 3.5)
    for _ in range(150):
        _rect(occ, rng.uniform(2, SIZE_M - 8), rng.uniform(2, SIZE_M - 8), rng.uniform(1, 5), rng.uniform(1, 5))


def _posts(occ, rng):
    for x, y in rng.uniform(3.0, SIZE_M - 3.0, (1500, 2)):
        size = rng.uniform(0.15, 0.5)
        _rect(occ, x, y, size, size)
    for _ in range(40):
        _rect(occ, rng.uniform(2, SIZE_M - 12), rng.uniform(2, SIZE_M - 12), rng.uniform(2, 10), rng.uniform(2, 10))


def _walls(occ, rng):
    for _ in range(14):
        x, y = rng.uniform(10.0, SIZE_M - 10.0, 2)
        length = rng.uniform(30.0, 120.0)
        angle = rng.integers(0, 4) * np.pi / 2
        end = (x + length * np.cos(angle), y + length * np.sin(angle))
        _line(occ, (x, y), end, 0.3)
        if rng.random() < 0.5:  # L-shaped
            angle2 = angle + np.pi / 2
            _line(occ, end, (end[0] + 0.5 * length * np.cos(angle2), end[1] + 0.5 * length * np.sin(angle2)), 0.3)


def make_yard(style, seed):
    """GridMap of a 200 m yard of ``style`` (one of STYLES); the same seed gives the same yard."""
    rng = np.random.default_rng(seed)
    n = _cells(SIZE_M)
    occ = np.zeros((n, n), dtype=np.uint8)
    {"bays": _bays, "fences": _fences, "posts": _posts, "walls": _walls}[style](occ, rng)
    occ[:4, :] = occ[-4:, :] = occ[:, :4] = occ[:, -4:] = 100  # perimeter fence
    return GridMap(occ.astype(np.int8), RES, (0.0, 0.0, 0.0))


def pairs(costmap, rng, count, min_distance_m=40.0):
    """``count`` (start, goal) pairs in map metres, both free and connected, >= min_distance_m apart."""
    grid = costmap.grid
    free = np.argwhere(np.isfinite(costmap.cost))
    out = []
    while len(out) < count:
        a, b = free[rng.integers(0, len(free), 2)]
        xa, ya = grid.cell_to_world(a[0], a[1])
        xb, yb = grid.cell_to_world(b[0], b[1])
        if np.hypot(xa - xb, ya - yb) < min_distance_m or not costmap.connected(tuple(a), tuple(b)):
            continue
        out.append(((float(xa), float(ya)), (float(xb), float(yb))))
    return out
