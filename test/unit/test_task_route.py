"""task.route: stops ordered by path length when asked, the planned length kept either way."""
import os

import pytest

from inspection_robot.command import CommandError
from inspection_robot.nav.tour import TourError
from inspection_robot.task.checks import Reachability
from inspection_robot.task.route import plan_route, route_points
from inspection_robot.task.spec import ORDER_GIVEN, ORDER_SHORTEST, Task

MAP = os.path.join(os.path.dirname(__file__), "..", "..", "config", "maps", "substation.yaml")


def stop(name, x, y):
    return {"name": name, "x": x, "y": y, "yaw": 0.0, "precision": 0, "presets": []}


def manhattan(a, b):
    """Roads along the axes: the order by straight lines is not the order by roads."""
    return abs(a[0] - b[0]) + abs(a[1] - b[1])


def test_shortest_reorders_the_stops_given_keeps_them():
    stops = [stop("far", 10, 0), stop("near", 1, 0), stop("middle", 5, 0)]
    shortest = plan_route(Task("t", "routine", 1, list(stops), ORDER_SHORTEST), (0, 0), (0, 0), manhattan)
    assert [s["name"] for s in shortest.stops] == ["near", "middle", "far"]
    assert (shortest.planned_length_m, shortest.home_leg_m) == (20.0, 10.0)   # home from "far"
    given = plan_route(Task("t", "routine", 1, list(stops), ORDER_GIVEN), (0, 0), (0, 0), manhattan)
    assert [s["name"] for s in given.stops] == ["far", "near", "middle"]
    assert (given.planned_length_m, given.home_leg_m) == (10 + 9 + 4 + 5, 5.0)


def test_a_stop_without_path_is_named():
    def blocked(a, b):
        if (5, 5) in (tuple(a), tuple(b)):
            raise TourError("goal (5.00, 5.00) is not reachable (enclosed by obstacles)")
        return manhattan(a, b)
    task = Task("t", "routine", 1, [stop("a", 1, 0), stop("island", 5, 5)], ORDER_SHORTEST)
    with pytest.raises(CommandError, match="no path from .*stop 'island'.*enclosed by obstacles"):
        plan_route(task, (0, 0), (0, 0), blocked)


def test_stored_tasks_round_trip_and_old_ones_load():
    task = plan_route(Task("t", "routine", 1, [stop("a", 1, 0)], ORDER_SHORTEST), (0, 0), (0, 0), manhattan)
    again = Task.from_dict(task.to_dict())
    assert (again.order, again.planned_length_m, again.home_leg_m) == (ORDER_SHORTEST, 2.0, 1.0)
    old = Task.from_dict({"id": "o", "priority": "routine", "retries": 1, "stops": []})
    assert (old.order, old.planned_length_m, old.home_leg_m) == (ORDER_GIVEN, None, None)


def test_planner_lengths_on_the_yard_follow_the_free_space():
    reach = Reachability(MAP, 0.4, (5.0, 5.0))
    straight = ((5.0 - 15.5) ** 2 + (5.0 - 10.0) ** 2) ** 0.5
    length = reach.path_length((5.0, 5.0), (15.5, 10.0))
    assert straight <= length < straight * 1.5
    with pytest.raises(TourError, match="outside the map"):
        reach.path_length((5.0, 5.0), (-500.0, 5.0))


def test_route_points_join_the_legs_and_keep_every_stop_when_thinned():
    def legs(a, b):   # 101 points a leg
        return [(a[0] + (b[0] - a[0]) * k / 100.0, a[1] + (b[1] - a[1]) * k / 100.0) for k in range(101)]
    stops = [stop("s%d" % i, float(i), 10.0 * (i % 2)) for i in range(1, 40)]
    task = Task("t", "routine", 1, stops)
    full = route_points(task, (0, 0), (0, 0), legs, max_points=10 ** 6)
    assert len(full) == 40 * 100 + 1 and full[0] == [0.0, 0.0] and full[-1] == [0.0, 0.0]
    thin = route_points(task, (0, 0), (0, 0), legs, max_points=500)
    assert len(thin) <= 500 and thin[0] == [0.0, 0.0] and thin[-1] == [0.0, 0.0]
    for s in stops:
        assert [s["x"], s["y"]] in thin


def test_route_points_on_the_yard_name_a_stop_without_path():
    reach = Reachability(MAP, 0.4, (5.0, 5.0))
    task = Task("t", "routine", 1, [stop("a", 15.5, 10.0)])
    path = route_points(task, (5.0, 5.0), (5.0, 5.0), lambda a, b: reach.path(a, b).points)
    assert [15.5, 10.0] in path and path[0] == [5.0, 5.0]
    with pytest.raises(CommandError, match="no path from the robot to stop 'far': .*outside the map"):
        route_points(Task("t", "routine", 1, [stop("far", -500.0, 5.0)]), (5.0, 5.0), (5.0, 5.0),
                     lambda a, b: reach.path(a, b).points)
