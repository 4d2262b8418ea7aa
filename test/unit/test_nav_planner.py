"""Planner and costmap on synthetic grids: optimality, blocked goals, virtual walls."""
import math

import numpy as np
import pytest

from inspection_robot.nav.costmap import Costmap, rasterise_polylines
from inspection_robot.nav.gridmap import GridMap
from inspection_robot.nav.planner import Planner, PlanningError
from inspection_robot.nav.virtual_obstacles import MAX_COORDINATE_M

RES = 0.05


def empty_grid(width_m=20.0, height_m=20.0):
    occ = np.zeros((int(height_m / RES), int(width_m / RES)), dtype=np.int8)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = 100
    return GridMap(occ, RES, (0.0, 0.0, 0.0))


def polyline_length(points):
    return float(np.hypot(*np.diff(np.asarray(points), axis=0).T).sum())


def assert_path_clear(costmap, plan):
    """No point along the path lies deeper than one cell inside the lethal (inflated) zone."""
    for a, b in zip(plan.points[:-1], plan.points[1:]):
        for t in np.linspace(0, 1, 200):
            row, col = costmap.grid.world_to_cell(*(a + (b - a) * t))
            assert np.isfinite(costmap.cost[row - 1:row + 2, col - 1:col + 2]).any(), (a, b, t)


@pytest.mark.parametrize("goal", [(17.0, 3.0), (15.3, 11.7), (3.0, 17.0), (9.1, 4.4)])
def test_free_space_path_is_nearly_straight(goal):
    costmap = Costmap(empty_grid(), robot_radius=0.4, safety_margin=0.0)
    plan = Planner(costmap).plan((2.0, 2.0), goal)
    straight = math.hypot(goal[0] - 2.0, goal[1] - 2.0)
    assert plan.length == pytest.approx(polyline_length(plan.points))
    # a straight plan's length may differ from math.hypot in the last bit (NumPy 1.17 sums differently)
    assert straight * (1.0 - 1e-12) <= plan.length <= straight * 1.05
    assert tuple(plan.points[0]) == (2.0, 2.0) and tuple(plan.points[-1]) == goal


def test_detour_around_wall_within_5_percent_of_shortest():
    grid = empty_grid()
    costmap = Costmap(grid, robot_radius=0.5, safety_margin=0.0)
    # wall from (10, 0) to (10, 15): the shortest path bends around the inflated end (10, 15.5)
    costmap.set_virtual([([[10.0, 0.0], [10.0, 15.0]], False)])
    start, goal = (5.0, 5.0), (15.0, 5.0)
    plan = Planner(costmap).plan(start, goal)
    corner = (10.0, 15.0 + 0.5)
    # true shortest: tangent lines to the inflation circle of radius 0.5 around the wall end
    shortest = math.hypot(corner[0] - start[0], corner[1] - start[1]) * 2
    assert plan.length <= shortest * 1.05
    assert plan.length >= shortest * 0.98
    assert max(y for _x, y in plan.points) > 15.0
    assert_path_clear(costmap, plan)


def test_safety_margin_keeps_path_off_the_wall_when_room():
    costmap = Costmap(empty_grid(), robot_radius=0.4, safety_margin=0.5)
    costmap.set_virtual([([[4.0, 10.5], [16.0, 10.5]], False)])
    plan = Planner(costmap).plan((2.0, 9.0), (18.0, 9.0))
    assert_path_clear(costmap, plan)
    # the margin cost pushes the path at least radius + part of the margin away from the wall
    for x, y in plan.points[1:-1]:
        assert abs(y - 10.5) > 0.6


def test_closed_polygon_around_goal_fails():
    costmap = Costmap(empty_grid(), robot_radius=0.4, safety_margin=0.2)
    costmap.set_virtual([([[12.0, 12.0], [16.0, 12.0], [16.0, 16.0], [12.0, 16.0]], True)])
    with pytest.raises(PlanningError, match="not reachable"):
        Planner(costmap).plan((3.0, 3.0), (14.0, 14.0))


def test_open_polyline_with_gap_is_passable():
    costmap = Costmap(empty_grid(), robot_radius=0.4, safety_margin=0.0)
    # wall across the map with a 2 m gap between y=9 and y=11
    costmap.set_virtual([([[10.0, 0.0], [10.0, 9.0]], False), ([[10.0, 11.0], [10.0, 20.0]], False)])
    plan = Planner(costmap).plan((3.0, 3.0), (17.0, 3.0))
    assert_path_clear(costmap, plan)
    crossing = [y for (x0, y), (x1, _y) in zip(plan.points[:-1], plan.points[1:]) if (x0 - 10) * (x1 - 10) <= 0]
    assert crossing


def test_blocked_and_invalid_goals():
    costmap = Costmap(empty_grid(), robot_radius=0.4, safety_margin=0.0)
    costmap.set_virtual([([[10.0, 0.0], [10.0, 20.0]], False)])
    planner = Planner(costmap)
    with pytest.raises(PlanningError, match="not reachable"):
        planner.plan((3.0, 3.0), (17.0, 3.0))
    with pytest.raises(PlanningError, match="outside the map"):
        planner.plan((3.0, 3.0), (30.0, 3.0))
    with pytest.raises(PlanningError, match="obstacle"):
        planner.plan((3.0, 3.0), (10.1, 5.0))


def test_start_inside_inflation_escapes():
    costmap = Costmap(empty_grid(), robot_radius=0.4, safety_margin=0.0)
    costmap.set_virtual([([[5.0, 0.0], [5.0, 8.0]], False)])
    plan = Planner(costmap).plan((5.2, 4.0), (15.0, 4.0))
    assert tuple(plan.points[0]) == (5.2, 4.0)
    assert_path_clear(costmap, Planner(costmap).plan((5.6, 4.0), (15.0, 4.0)))


def test_costmap_change_is_seen_by_planner():
    costmap = Costmap(empty_grid(), robot_radius=0.4, safety_margin=0.0)
    planner = Planner(costmap)
    direct = planner.plan((3.0, 10.0), (17.0, 10.0))
    assert direct.length == pytest.approx(14.0, abs=0.1)
    costmap.set_virtual([([[10.0, 5.0], [10.0, 15.0]], False)])
    detour = planner.plan((3.0, 10.0), (17.0, 10.0))
    assert detour.length > 15.0


def test_rasterised_polyline_cells():
    mask = rasterise_polylines((40, 40), [([[0.5, 0.5], [1.5, 0.5]], False)], RES, (0.0, 0.0))
    rows, cols = np.nonzero(mask)
    assert set(rows) == {10} and cols.min() == 10 and cols.max() == 30
    closed = rasterise_polylines((40, 40), [([[0.5, 0.5], [1.5, 0.5], [1.5, 1.5], [0.5, 1.5]], True)],
                                 RES, (0.0, 0.0))
    assert closed[10, 10:31].all() and closed[30, 10:31].all() and closed[10:31, 10].all() and closed[10:31, 30].all()
    assert not closed[20, 20]
    diagonal = rasterise_polylines((40, 40), [([[0.1, 0.1], [1.9, 1.7]], False)], RES, (0.0, 0.0))
    # 8-connected without holes: every column between the ends holds at least one cell
    cols = np.nonzero(diagonal.any(axis=0))[0]
    assert list(cols) == list(range(cols.min(), cols.max() + 1))


@pytest.mark.parametrize("resolution", [0.05, 0.01])
def test_wall_to_the_farthest_accepted_point_goes_the_right_way(resolution):
    # beyond int32 the fixed-point rasteriser wrapped and drew the wall towards -x instead
    mask = rasterise_polylines((100, 100), [([[2 * resolution * 20, 0.5], [MAX_COORDINATE_M, 0.5]], False)],
                               resolution, (0.0, 0.0))
    cols = np.nonzero(mask.any(axis=0))[0]
    assert cols.min() == 40 and cols.max() == 99


def test_virtual_obstacles_never_touch_the_static_map():
    grid = empty_grid()
    before = grid.occupancy.copy()
    costmap = Costmap(grid, robot_radius=0.4, safety_margin=0.0)
    costmap.set_virtual([([[5.0, 5.0], [6.0, 6.0]], False)])
    assert (grid.occupancy == before).all()
    assert not np.isfinite(costmap.cost[grid.world_to_cell(5.5, 5.5)])


def test_bad_input_fails_clearly():
    costmap = Costmap(empty_grid(), robot_radius=0.4, safety_margin=0.3)
    planner = Planner(costmap)
    with pytest.raises(PlanningError, match="outside the map"):
        planner.plan((2.0, 2.0), (500.0, 2.0))
    with pytest.raises(PlanningError, match="finite"):
        planner.plan((2.0, 2.0), (float("nan"), 2.0))
    with pytest.raises(PlanningError, match="inside an obstacle"):
        planner.plan((2.0, 2.0), (0.1, 0.1))


def test_map_without_free_cell_fails_clearly():
    occ = np.full((200, 200), 100, dtype=np.int8)
    costmap = Costmap(GridMap(occ, RES, (0.0, 0.0, 0.0)), robot_radius=0.4, safety_margin=0.3)
    planner = Planner(costmap)
    with pytest.raises(PlanningError, match="inside an obstacle"):
        planner.plan((5.0, 5.0), (6.0, 6.0))


def test_huge_virtual_polygon_is_a_full_window_not_a_stall():
    grid = empty_grid()
    costmap = Costmap(grid, robot_radius=0.4, safety_margin=0.3)
    planner = Planner(costmap)
    # a polygon far larger than the map with 10,000 points (the most the command accepts)
    t = np.linspace(0.0, 2.0 * math.pi, 10000, endpoint=False)
    ring = np.stack([10.0 + 5e4 * np.cos(t), 10.0 + 5e4 * np.sin(t)], axis=1).tolist()
    window = costmap.set_virtual([(ring, True)])
    assert (window.r1 - window.r0, window.c1 - window.c0) == costmap.shape  # it spans the map: full rebuild
    assert not costmap.virtual.any()  # its outline lies off the map
    fence = [[-1e3, 10.0], [1e3, 10.0]]  # crosses the whole map: a wall from edge to edge
    costmap.set_virtual([(ring, True), (fence, False)])
    with pytest.raises(PlanningError, match="not reachable"):
        planner.plan((5.0, 5.0), (5.0, 15.0))
