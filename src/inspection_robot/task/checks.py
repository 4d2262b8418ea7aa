"""The two task checks that need the robot's world: does a preset exist (and is it calibrated),
and can a stop be reached on the map. Used by task_manager at submission, before anything moves."""
import os
import threading

import numpy as np

from inspection_robot.command import CommandError
from inspection_robot.files import confine_data_path, root_relative
from inspection_robot.inspection.calibration import check_references
from inspection_robot.inspection.preset import PRESET_INI, PresetError, load_preset
from inspection_robot.nav.costmap import Costmap
from inspection_robot.nav.gridmap import MapError, load_map
from inspection_robot.nav.planner import Planner, PlanningError
from inspection_robot.nav.tour import TourError
from inspection_robot.task.display import display_decimals
from inspection_robot.task.spec import ResolvedPreset
from inspection_robot.task.states import target_unit

THERMAL_TASK_KEYS = ("phase", "device", "equipment_class", "emissivity", "distance")   # what task.rows diagnoses with


def resolve_preset(preset_root, name, data_root=None):
    """``name`` = a preset directory or a preset id (its newest recording), relative to
    ``data_root`` (``presets/<preset_id>/<stamp>``, the form answers use) or to ``preset_root``
    (``<preset_id>/<stamp>``, the older form); returns a ResolvedPreset or raises CommandError."""
    root_names = None if data_root is None else [root_relative(os.path.realpath(preset_root),
                                                               os.path.realpath(data_root))]
    try:
        path = confine_data_path(name, [preset_root], data_root, root_names)
    except CommandError as err:
        raise CommandError("unknown preset directory '%s': %s" % (name, err))
    if os.path.isdir(path) and not os.path.isfile(os.path.join(path, PRESET_INI)):
        recordings = sorted(d for d in os.listdir(path)
                            if not d.startswith(".") and os.path.isfile(os.path.join(path, d, PRESET_INI)))
        if recordings:
            path = os.path.join(path, recordings[-1])
    try:
        preset = load_preset(path)
        check_references(preset)   # a file lost or damaged since calibration: refused now, not at the stop
    except PresetError as err:
        raise CommandError("unknown preset directory '%s': %s" % (name, err))
    targets = [_target_entry(t) for t in preset.targets]
    # a preset's own limits: ``normal = low,high`` (and ``alarm_band``) in a target's section, read and checked
    # with the rest of the calibration (inspection.calibration_schema)
    return ResolvedPreset(path, targets, dict((t.name, _limits(t.params)) for t in preset.targets
                                              if t.params.get("normal")))


def _limits(params):
    """A calibrated target's limits in a task's form (task.spec.parse_limits)."""
    if params.get("alarm_band"):
        return {"normal": list(params["normal"]), "alarm": list(params["alarm_band"])}
    return list(params["normal"])


def _target_entry(target):
    """A target as a task stores it: its name, kind, unit, decimals (the resolution its readings are
    shown with, task.display) and, for a thermal box, the diagnosis keys it has (task.rows); a
    counter says so."""
    entry = {"name": target.name, "kind": target.kind, "unit": target_unit(target.kind, target.params.get("unit", "")),
             "decimals": display_decimals(target.kind, target.params)}
    for key in THERMAL_TASK_KEYS:
        if target.kind == "thermal" and target.params.get(key) not in (None, ""):
            entry[key] = target.params[key]
    if target.params.get("counter"):
        entry["counter"] = True   # task.patrol stores its increment and flags a count that went down
    return entry


class Reachability(object):
    """A stop is reachable when its cell is free of the map and the virtual obstacles, both inflated
    by the robot's radius, and connected to the home pose's cell.

    The virtual layer is move_base's own: the cells it publishes on virtual_obstacle_map, handed to
    ``set_virtual`` (no second copy of the obstacles or of their rasterising). Until a layer came,
    a check waits up to ``virtual_wait_s`` for one and then answers that the obstacles are not
    known (None: no virtual layer is expected, for tools). Thread-safe: the layer changes in a
    subscriber thread while a submission is checked in a service thread.
    """

    def __init__(self, map_file, robot_radius, home_xy, virtual_wait_s=None):
        try:
            self.costmap = Costmap(load_map(map_file), robot_radius, 0.0)
        except (MapError, OSError, ValueError) as err:
            raise CommandError("cannot load the map %s: %s" % (map_file, err))
        self.home = self.costmap.grid.world_to_cell(*home_xy)
        # the static map alone, to tell a virtual obstacle's refusal from the map's
        self._static_free = np.isfinite(self.costmap.cost)
        self._static_home = None
        if self.costmap.free(*self.home):
            self._static_home = self.costmap.component_image() == self.costmap.component(*self.home)
        self._virtual_wait_s = virtual_wait_s
        self._virtual_known = threading.Event()
        if virtual_wait_s is None:
            self._virtual_known.set()
        self._lock = threading.Lock()
        self._planner = None  # made at the first path_length (planning shares the costmap and its lock)

    def set_virtual(self, cells):
        """The current virtual layer: a boolean array of the map's shape (ValueError otherwise)."""
        with self._lock:
            self.costmap.set_virtual_cells(cells)
        self._virtual_known.set()

    def path_length(self, start_xy, goal_xy):
        """The planner's path length (m) between two points on the current costmap (map and virtual
        obstacles, as move_base plans); TourError when there is none."""
        return self.path(start_xy, goal_xy).length

    def path(self, start_xy, goal_xy):
        """The planner's Plan (points: (N, 2) map metres, length m) between two points; TourError
        when there is none."""
        with self._lock:
            if self._planner is None:
                self._planner = Planner(self.costmap)
            try:
                return self._planner.plan(start_xy, goal_xy)
            except PlanningError as err:
                raise TourError(str(err))

    def __call__(self, x, y):
        if not self._virtual_known.wait(self._virtual_wait_s):
            return "virtual obstacles not known (no virtual_obstacle_map from move_base yet)"
        with self._lock:
            cell = self.costmap.grid.world_to_cell(x, y)
            if not self.costmap.grid.contains(*cell):
                return "outside the map"
            if not self._static_free[cell]:
                return "inside an obstacle or too close to one"
            if not self.costmap.free(*cell):
                return "inside a virtual obstacle or too close to one"
            if self.costmap.free(*self.home) and not self.costmap.connected(self.home, cell):
                if self._static_home is not None and self._static_home[cell]:
                    return "cut off from the home pose by virtual obstacles"
                return "no path from the home pose"
        return None
