"""Virtual obstacles: named polylines in map metres that the planner treats as walls.

Commands (virtual_obstacle_cmd, INTERFACE.md section 4), data JSON
``{"id": "...", "points": [[x, y], ...], "closed": true}``:

- ``add``: a new id (an existing id fails); ``modify``: replace an existing id's polyline;
- ``delete``: ``{"id": ...}`` of an existing id; ``clear``: removes all (data ignored);
- ``query``: data empty or ``{}`` gives every polyline, ``{"id": ...}`` only that one; the ack
  data is a JSON list of ``{"id", "points", "closed"}`` objects, sorted by id.

Every change is saved atomically before it is acknowledged; ``on_change`` then gets the list.

During a replay (docs/interface.md "Recording and replay") the list comes from the bag (move_base's
latched ``virtual_obstacles`` topic, the ``query`` answer) through :meth:`VirtualObstacles.replace`,
and ``replay_table`` answers ``query`` from it and refuses every change with REPLAY_REFUSAL.
"""
import json
import math

from inspection_robot.command import CommandError, CommandTable, parse_json
from inspection_robot.files import FileError, read_json, write_json_atomic

MAX_POINTS = 10000
# a polyline of MAX_POINTS points fits in far less; a bigger message (millions of points) is
# refused before it is parsed, so it cannot stall the node
MAX_DATA_CHARS = 100 * MAX_POINTS
MAX_ID_LENGTH = 128
# |x|, |y| at most 100 km: a substation map is far smaller, and larger values (a unit error, mm for
# m) would overflow the costmap's fixed-point rasteriser, which then drew the wall the wrong way.
MAX_COORDINATE_M = 1.0e5
REPLAY_REFUSAL = "not_allowed: replay (the virtual obstacles of a recorded run cannot be changed)"
NOT_REPLAYED = "unavailable: the replayed bag has given no virtual obstacle list yet (topic virtual_obstacles)"
CHANGING_COMMANDS = ("add", "modify", "delete", "clear")


def parse_obstacle(data, need_points=True):
    """Validate command JSON; return (id, points, closed). Raises CommandError with the reason."""
    if len(data) > MAX_DATA_CHARS:
        raise CommandError("data is %d characters, at most %d (%d points)" % (len(data), MAX_DATA_CHARS, MAX_POINTS))
    obj = parse_json(data)
    if not isinstance(obj, dict):
        raise CommandError("data must be a JSON object")
    ident = obj.get("id")
    if not isinstance(ident, str) or not ident or len(ident) > MAX_ID_LENGTH:
        raise CommandError("id must be a non-empty string of at most %d characters" % MAX_ID_LENGTH)
    if not need_points:
        return ident, None, None
    points = obj.get("points")
    if not isinstance(points, list) or not 1 <= len(points) <= MAX_POINTS:
        raise CommandError("points must be a list of 1..%d [x, y] pairs" % MAX_POINTS)
    clean = []
    for i, point in enumerate(points):
        if not isinstance(point, (list, tuple)) or len(point) != 2 or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in point):
            raise CommandError("points[%d] must be [x, y] with finite numbers, got %s" % (i, json.dumps(point)))
        if max(abs(point[0]), abs(point[1])) > MAX_COORDINATE_M:
            raise CommandError("points[%d] is %.6g m from the map origin (at most %.0f m; metres, not mm?)"
                               % (i, max(abs(point[0]), abs(point[1])), MAX_COORDINATE_M))
        clean.append([float(point[0]), float(point[1])])
    closed = obj.get("closed", False)
    if not isinstance(closed, bool):
        raise CommandError("closed must be true or false")
    if closed and len(clean) < 3:
        raise CommandError("a closed polyline needs at least 3 points")
    return ident, clean, closed


class VirtualObstacles(object):
    def __init__(self, path, on_change=None):
        """``path``: JSON file they persist in ("" = not persisted)."""
        self.path = path
        self.on_change = on_change
        self._items = {}
        self.table = CommandTable({"add": self._add, "modify": self._modify, "delete": self._delete,
                                   "query": self._query, "clear": self._clear})

    def load(self):
        """Load the persisted obstacles; a corrupt file raises ValueError (nothing is loaded)."""
        if not self.path:
            return
        stored = read_json(self.path)
        if stored is None:
            return
        self.replace(stored, self.path)

    def replace(self, entries, source):
        """Take ``entries`` (a list as ``query`` answers it) as the whole set, without saving it or
        calling on_change; ValueError naming ``source`` when an entry is malformed (nothing changes)."""
        if not isinstance(entries, list):
            raise ValueError("%s: expected a JSON list" % source)
        items = {}
        for entry in entries:
            try:
                ident, points, closed = parse_obstacle(json.dumps(entry))
            except CommandError as err:
                raise ValueError("%s: %s" % (source, err))
            items[ident] = {"id": ident, "points": points, "closed": closed}
        self._items = items

    def polylines(self):
        """[(points, closed), ...] for the costmap."""
        return [(o["points"], o["closed"]) for o in self.listing()]

    def listing(self):
        return [self._items[k] for k in sorted(self._items)]

    def _commit(self, items):
        if self.path:
            try:
                write_json_atomic(self.path, [items[k] for k in sorted(items)])
            except FileError as err:
                raise CommandError("cannot save virtual obstacles to %s: %s" % (self.path, err))
        self._items = items
        if self.on_change is not None:
            self.on_change(self.listing())

    def _add(self, data):
        ident, points, closed = parse_obstacle(data)
        if ident in self._items:
            raise CommandError("id '%s' already exists (use modify)" % ident)
        items = dict(self._items)
        items[ident] = {"id": ident, "points": points, "closed": closed}
        self._commit(items)

    def _modify(self, data):
        ident, points, closed = parse_obstacle(data)
        if ident not in self._items:
            raise CommandError("no virtual obstacle with id '%s'" % ident)
        items = dict(self._items)
        items[ident] = {"id": ident, "points": points, "closed": closed}
        self._commit(items)

    def _delete(self, data):
        ident = parse_obstacle(data, need_points=False)[0]
        if ident not in self._items:
            raise CommandError("no virtual obstacle with id '%s'" % ident)
        items = dict(self._items)
        del items[ident]
        self._commit(items)

    def _query(self, data):
        if data.strip() in ("", "{}"):
            return json.dumps(self.listing())
        ident = parse_obstacle(data, need_points=False)[0]
        if ident not in self._items:
            raise CommandError("no virtual obstacle with id '%s'" % ident)
        return json.dumps([self._items[ident]])

    def _clear(self, _data):
        self._commit({})


def replay_table(obstacles, known):
    """The virtual_obstacle_cmd table of a replay: ``query`` answered from ``obstacles`` (once
    ``known()`` says the bag gave the list, else NOT_REPLAYED), every change refused."""
    def query(data):
        if not known():
            raise CommandError(NOT_REPLAYED)
        return obstacles.table.dispatch("query", data)

    def refuse(_data):
        raise CommandError(REPLAY_REFUSAL)
    handlers = {name: refuse for name in CHANGING_COMMANDS}
    handlers["query"] = query
    return CommandTable(handlers)
