"""A patrol's route: the order of its stops and the length the robot will drive.

With ``order: "shortest"`` the stops are put in the order that makes the path from the robot
through every stop to the home pose shortest, measured with the planner's path lengths along the
yard's free space (nav/tour.py), not straight lines. Either way the route's planned length is
measured and kept with the task, so a report can compare what was driven with what was planned.
Pure module: ``path_length(a_xy, b_xy)`` (metres, TourError when there is no path) is passed in.
"""
from inspection_robot.command import CommandError
from inspection_robot.nav.tour import TourError, order_points
from inspection_robot.task.spec import ORDER_SHORTEST

MAX_ROUTE_POINTS = 2000   # points of a planned route drawn by a client (task_control plan)


def plan_route(task, start_xy, end_xy, path_length):
    """Order ``task.stops`` (when its order is shortest) and set ``task.planned_length_m``: the length
    from ``start_xy`` (the robot) through every stop to ``end_xy`` (home), and ``task.home_leg_m``:
    its last leg, which a patrol does not drive (it ends at its last stop), so a report compares the
    distance driven with the rest. CommandError names the two places with no path between them."""
    points = [tuple(start_xy)] + [(stop["x"], stop["y"]) for stop in task.stops] + [tuple(end_xy)]
    names = ["the robot"] + ["stop '%s'" % stop["name"] for stop in task.stops] + ["the home pose"]
    lengths = {}

    def measure(i, j):
        key = (min(i, j), max(i, j))
        if key not in lengths:
            try:
                lengths[key] = float(path_length(points[key[0]], points[key[1]]))
            except TourError as err:
                raise CommandError("no path from %s to %s: %s" % (names[key[0]], names[key[1]], err))
        return lengths[key]

    if task.order == ORDER_SHORTEST:
        order, length, _planned = order_points(points, measure)
        task.stops = [task.stops[i - 1] for i in order[1:-1]]
    else:
        order = list(range(len(points)))
        length = sum(measure(i, i + 1) for i in range(len(points) - 1))
    task.planned_length_m = round(length, 2)
    task.home_leg_m = round(measure(order[-2], order[-1]), 2)
    return task


def route_points(task, start_xy, end_xy, plan_path, max_points=MAX_ROUTE_POINTS):
    """The planner's path from ``start_xy`` through the task's stops (in their order) to ``end_xy``:
    [[x, y], ...] map metres (cm), at most ``max_points``, thinned evenly and keeping every stop.
    ``plan_path(a_xy, b_xy)``: one leg's points ((N, 2), both ends included; TourError: none)."""
    points = [tuple(start_xy)] + [(stop["x"], stop["y"]) for stop in task.stops] + [tuple(end_xy)]
    names = ["the robot"] + ["stop '%s'" % stop["name"] for stop in task.stops] + ["the home pose"]
    path, joints = [list(points[0])], [0]
    for i in range(len(points) - 1):
        try:
            leg = plan_path(points[i], points[i + 1])
        except TourError as err:
            raise CommandError("no path from %s to %s: %s" % (names[i], names[i + 1], err))
        path.extend([float(x), float(y)] for x, y in list(leg)[1:])
        joints.append(len(path) - 1)
    if len(path) > max_points:
        spare = max(0, max_points - len(joints))
        keep = set(joints) | set(int(round(k * (len(path) - 1) / max(1, spare - 1))) for k in range(spare))
        path = [path[k] for k in sorted(keep)][:max_points]
    return [[round(x, 2), round(y, 2)] for x, y in path]
