"""The site check: may robot.launch start with this site file? Every problem, in one message.

A site file (``robot_config``, template config/robot.example.yaml) is a YAML mapping keyed by node
name, loaded after the defaults of config/*.yaml; a top-level ``data_root`` names the state
directory. robot.launch runs tools/check_site while roslaunch parses it (a ``<param command=...>``,
before any process starts), and that tool calls :func:`site_problems` with:

- ``site``: the site file as parsed;
- ``defaults``: every parameter robot.launch gives its nodes without a site file, flattened to
  ``node/key/sub`` names (from roslaunch's own parse of core.launch, so a setting the launch files
  give a node is known here without a second list);
- ``sim_yard``: the simulated yard's site values (:func:`sim_yard`, read from config/sim_site.yaml,
  the one place sim.launch takes them from);
- ``data_root_arg`` / ``insecure``: robot.launch's arguments.

A problem is one line naming the setting (``move_base/map_file``) and how to fix it. Refused:
a key no node reads (a typo, with the nearest known name), a setting a real robot needs that is
unset (:data:`REQUIRED`, the drivers of drivers.DEVICES and what each built-in driver needs,
:data:`DRIVER_SETTINGS`), a value still pointing at the simulated yard (its map, dock, home or
initial pose, a ``sim/...`` topic), malformed values (a map that does not load, a dock
charge.dock refuses, a secret file others can read), and a pose_adapter that move_base would not
read (or a pose_topic nothing publishes: the adapter's output while the adapter is off). Pure
module: no rospy; files are read through the parsers the nodes use (nav.gridmap.load_map,
charge.dock.parse_dock, files.read_secret_file, nav.pose_adapter.AdapterParams).
"""
import difflib
import math
import os
from collections import OrderedDict, namedtuple

import yaml

from inspection_robot.bridge.access import AccessError, check_fixed
from inspection_robot.charge.dock import DockError, parse_dock
from inspection_robot.drivers import DEVICES, PARAM, PARAMS_PARAM, SIM, DriverConfigError, choose
from inspection_robot.files import read_secret_file
from inspection_robot.fixed_settings import FIXED_KEYS
from inspection_robot.i18n import LanguageError, check_language
from inspection_robot.nav.gridmap import MapError, load_map
from inspection_robot.nav.pose_adapter import ADAPTER_SETTINGS, MODE_NONE, MODE_TOPIC, MODES, AdapterParams

DATA_ROOT = "data_root"
LANGUAGE = "language"   # the operator's language: console, report, voice (inspection_robot.i18n)
TOP_LEVEL = (DATA_ROOT, LANGUAGE)
SIM_SITE_FILE = "config/sim_site.yaml"
TEMPLATE = "config/robot.example.yaml"

Setting = namedtuple("Setting", "name what")
"""name: ``node/key`` as in the site file; what: what it is, for the message."""

# Every site-specific setting without a package default: robot.launch needs each from the site file.
REQUIRED = OrderedDict((s.name, s) for s in (
    Setting("move_base/map_file", "the site's map (map_server YAML)"),
    Setting("move_base/pose_topic", "the localizer's geometry_msgs/PoseWithCovarianceStamped topic"),
    Setting("move_base/init_pose", "set_location init_pose, [x, y, yaw] on the site's map"),
    Setting("task_manager/home_pose", "return_home goal, [x, y, yaw] on the site's map"),
    Setting("charge_control/dock", "the charging dock {pose, approach_pose, tolerance_m, tolerance_yaw}"),
))
POSES = ("move_base/init_pose", "task_manager/home_pose")
DOCK = "charge_control/dock"
MAP = "move_base/map_file"
POSE_TOPIC = "move_base/pose_topic"
ADAPTER = "pose_adapter"
ADAPTER_MODE = ADAPTER + "/mode"
ADAPTER_PARAMS = ADAPTER_SETTINGS   # config/pose_adapter.yaml's settings besides mode
BRIDGE = "rosbridge_websocket"
TOKEN_FILE = "rosbridge_websocket/auth_token_file"
AUTH_ALTERNATIVES = ("rosbridge_websocket/auth_token", "rosbridge_websocket/client_ca")

# What a built-in driver needs from the site file besides its name (the defaults are examples).
DRIVER_SETTINGS = {
    ("chassis", "ros"): ("ros_base/cmd_vel_topic", "ros_base/odom_topic"),
    ("head", "pelco"): ("port",),
    ("camera", "isapi"): ("isapi/url",),
    ("thermal", "isapi"): ("isapi/host", "isapi/password_file"),
    ("sensor3d", "pointcloud"): ("cloud_topic",),
}
# Secret files checked like the nodes check them (present, private, not empty).
SECRET_FILES = ("infrared_imager/isapi/password_file",)


class SiteError(ValueError):
    """A site file that cannot even be read as a mapping."""


class _UniqueKeyLoader(yaml.SafeLoader):
    """yaml.SafeLoader refusing a key given twice in one mapping (plain YAML keeps the last one
    silently: a pasted second ``move_base:`` section would drop the first)."""

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _value in node.value:
            key = self.construct_object(key_node, deep=deep)
            if key in seen:
                raise yaml.constructor.ConstructorError(None, None, "%r given twice" % (key,), key_node.start_mark)
            seen.add(key)
        return yaml.SafeLoader.construct_mapping(self, node, deep)


def load_site_text(text, path):
    """The site file's mapping ({} for an empty file); SiteError naming the file and line otherwise."""
    try:
        site = yaml.load(text, Loader=_UniqueKeyLoader)
    except yaml.YAMLError as err:
        raise SiteError("site file %s is not valid YAML: %s" % (path, " ".join(str(err).split())))
    if site is None:
        return {}
    if not isinstance(site, dict):
        raise SiteError("site file %s must be a mapping keyed by node name, got %s" % (path, type(site).__name__))
    return site


def flatten(tree, prefix=""):
    """{``a/b/c``: leaf} of a nested mapping, as roslaunch sets parameters; an empty mapping is a leaf."""
    flat = OrderedDict()
    for key, value in tree.items():
        name = "%s%s" % (prefix, key)
        if isinstance(value, dict) and value:
            flat.update(flatten(value, name + "/"))
        else:
            flat[name] = value
    return flat


def sim_yard(sim_site):
    """{setting: value} of the simulated yard: config/sim_site.yaml (``$(find ...)`` already resolved);
    the dock is one setting, as in a site file."""
    yard = OrderedDict((name, value) for name, value in flatten(sim_site).items() if not name.startswith(DOCK + "/"))
    yard[DOCK] = sim_site["charge_control"]["dock"]
    return yard


def _free_form(name):
    """True for a name below a device node's ``driver_params`` (a plug-in's own keyword arguments)."""
    parts = name.split("/")
    return len(parts) > 2 and parts[1] == PARAMS_PARAM and parts[0] in {d.node for d in DEVICES.values()}


def _unknown_keys(site, defaults):
    """Lines for every site key that no node of robot.launch reads."""
    nodes = sorted({name.split("/")[0] for name in defaults if "/" in name})
    known = set(defaults) | set(REQUIRED) | set(TOP_LEVEL)
    problems = []
    for key, value in site.items():
        key = str(key)
        if key in TOP_LEVEL:
            continue
        if key not in nodes:
            near = difflib.get_close_matches(key, nodes, 1)
            problems.append("%s: unknown node in the site file%s (robot.launch runs %s)"
                            % (key, " (did you mean %s?)" % near[0] if near else "", ", ".join(nodes)))
            continue
        if not isinstance(value, dict):
            problems.append("%s: must be a mapping of that node's settings, got %r" % (key, value))
            continue
        for name in flatten(value, key + "/"):
            if name in known or _free_form(name) or name.startswith(DOCK + "/"):
                continue
            near = difflib.get_close_matches(name, [k for k in known if k.startswith(key + "/")], 1)
            problems.append("%s: unknown setting%s" % (name, " (did you mean %s?)" % near[0] if near else ""))
    return problems


def _is_sim_topic(value):
    name = str(value).strip().lstrip("/")
    return name.startswith("sim/") or "/sim/" in name


def _same_pose(a, b):
    try:
        return len(a) == len(b) == 3 and all(abs(float(x) - float(y)) < 1e-6 for x, y in zip(a, b))
    except (TypeError, ValueError):
        return False


def _pose_problem(name, value):
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        return "%s must be [x, y, yaw], got %r" % (name, value)
    try:
        if all(math.isfinite(float(v)) for v in value) and not any(isinstance(v, bool) for v in value):
            return None
    except (TypeError, ValueError):
        pass
    return "%s must be three finite numbers, got %r" % (name, value)


def _map_problems(path, sim_path, load=load_map):
    if not isinstance(path, str) or not os.path.isabs(path):
        return ["%s must be an absolute path to the site's map YAML, got %r" % (MAP, path)]
    try:
        site_map = load(path)
    except MapError as err:
        return ["%s: %s" % (MAP, err)]
    same = os.path.realpath(path) == os.path.realpath(sim_path)
    if not same:
        try:
            sim_map = load(sim_path)
        except MapError:
            sim_map = None
        same = sim_map is not None and _same_grid(site_map, sim_map)
    if same:
        return ["%s is the simulated yard's map (%s): give the site's map" % (MAP, sim_path)]
    return []


def _same_grid(a, b):
    return (a.resolution == b.resolution and list(a.origin) == list(b.origin)
            and a.occupancy.shape == b.occupancy.shape and bool((a.occupancy == b.occupancy).all()))


def _dock_problems(spec, sim_spec):
    try:
        dock = parse_dock(spec)
    except DockError as err:
        return ["%s: %s" % (DOCK, err)]
    sim = parse_dock(sim_spec)
    if _same_pose(dock.pose, sim.pose) or _same_pose(dock.approach, sim.approach):
        return ["%s is the simulated yard's dock (%s): measure the site's dock "
                "(docs/deployment.md, Charging dock)" % (DOCK, SIM_SITE_FILE)]
    return []


def _topic(name):
    return str(name).strip().lstrip("/")


def _adapter_problems(effective, given):
    """pose_adapter: a known mode and valid parameters (checked by AdapterParams, as the node checks
    them), and move_base/pose_topic its output exactly while it runs (none: the localizer's own topic)."""
    mode = effective.get(ADAPTER_MODE, MODE_NONE)
    if mode not in MODES:
        return ["%s must be one of %s, got %r (none: move_base reads the localizer's topic; tf: a localizer "
                "with TF map -> base_link only; topic: republish input_topic)" % (ADAPTER_MODE, "|".join(MODES), mode)]
    kwargs = {n: effective[ADAPTER + "/" + n] for n in ADAPTER_PARAMS if ADAPTER + "/" + n in effective}
    try:
        params = AdapterParams(mode, **kwargs)
    except ValueError as err:
        return [str(err).replace("~", ADAPTER + "/")]
    problems = []
    if mode == MODE_TOPIC and given.get(ADAPTER + "/input_topic") in (None, ""):
        problems.append("%s/input_topic is not set (pose_adapter/mode topic republishes it; the default %r is an "
                        "example)" % (ADAPTER, params.input_topic))
    pose_topic = given.get(POSE_TOPIC)
    if pose_topic in (None, ""):
        return problems   # REQUIRED names it
    reads_adapter = _topic(pose_topic) == _topic(params.output_topic)
    if mode != MODE_NONE and not reads_adapter:
        problems.append("%s is %r but %s is %s: move_base must read the adapter's output, set %s: %s "
                        "(%s/output_topic)" % (POSE_TOPIC, pose_topic, ADAPTER_MODE, mode, POSE_TOPIC,
                                               params.output_topic, ADAPTER))
    elif mode == MODE_NONE and reads_adapter:
        problems.append("%s is %r, pose_adapter's output, but %s is none: nothing publishes it (set %s: tf for a "
                        "localizer with TF only, or %s to the localizer's own topic)"
                        % (POSE_TOPIC, pose_topic, ADAPTER_MODE, ADAPTER_MODE, POSE_TOPIC))
    return problems


def _secret_problem(name, path, read_secret):
    if not isinstance(path, str) or not path:
        return "%s is not set" % name
    try:
        read_secret(path, name)
    except ValueError as err:
        return str(err)
    return None


def site_problems(site, defaults, sim_yard_values, data_root_arg="", insecure=False,
                  load=load_map, read_secret=read_secret_file):
    """Every reason robot.launch must not start with ``site``, as lines (empty: start).

    site: the parsed site file ({} when there is none); defaults: flattened parameters robot.launch
    sets without it; sim_yard_values: :func:`sim_yard`; data_root_arg: robot.launch's data_root;
    insecure: robot.launch's insecure (no token file needed then). load / read_secret: the map
    loader and secret-file reader (tests pass fakes).
    """
    if not isinstance(site, dict):
        raise SiteError("the site file must be a mapping keyed by node name, got %r" % (site,))
    problems = _unknown_keys(site, defaults)
    given = flatten(OrderedDict((k, v) for k, v in site.items() if isinstance(v, dict) or k == DATA_ROOT))
    charge = site.get("charge_control")
    if isinstance(charge, dict) and "dock" in charge:
        # the dock is one setting (parse_dock checks its fields), not four
        given = OrderedDict((n, v) for n, v in given.items() if not n.startswith(DOCK + "/"))
        given[DOCK] = charge["dock"]
    effective = OrderedDict(defaults)
    effective.update(given)

    for device, entry in DEVICES.items():
        name = "%s/%s" % (entry.node, PARAM)
        spec = effective.get(name)
        try:
            choice = choose(device, spec)
        except DriverConfigError as err:
            problems.append(str(err).replace("set it in %s or robot_config" % entry.config, "set it in the site file"))
            continue
        if choice.kind == SIM:
            problems.append("%s is sim: robot.launch drives real devices only (use sim.launch, or set a real "
                            "driver or none in the site file)" % name)
            continue
        for key in DRIVER_SETTINGS.get((device, choice.name), ()):
            setting = "%s/%s" % (entry.node, key)
            if given.get(setting) in (None, ""):
                problems.append("%s is not set (the %s driver %s needs it; the default %r is an example)"
                                % (setting, device, choice.name, defaults.get(setting)))

    for name, setting in REQUIRED.items():
        if given.get(name) in (None, ""):
            problems.append("%s is not set: %s" % (name, setting.what))
    for name in POSES:
        if given.get(name) in (None, ""):
            continue
        problem = _pose_problem(name, given[name])
        if problem:
            problems.append(problem)
        elif _same_pose(given[name], sim_yard_values.get(name)):
            problems.append("%s is the simulated yard's (%s): give the site's pose" % (name, SIM_SITE_FILE))
    if given.get(MAP) not in (None, ""):
        problems.extend(_map_problems(given[MAP], sim_yard_values[MAP], load))
    if given.get(DOCK) not in (None, ""):
        problems.extend(_dock_problems(given[DOCK], sim_yard_values[DOCK]))
    problems.extend(_adapter_problems(effective, given))

    for name, value in effective.items():
        if (name.endswith("_topic") or name.endswith("_topics")) and not _free_form(name):
            values = value if isinstance(value, (list, tuple)) else [value]
            for topic in values:
                if _is_sim_topic(topic):
                    problems.append("%s is %r, a simulator's topic: give the real robot's topic" % (name, topic))

    if LANGUAGE in site:
        try:
            check_language(site[LANGUAGE])
        except LanguageError as err:
            problems.append("%s (top-level in the site file: the console's, the report's and the voice's)" % err)
    root = str(given.get(DATA_ROOT) or data_root_arg or "")
    if not root:
        problems.append("%s is not set: the robot's state directory (e.g. /var/lib/inspection_robot), "
                        "top-level in the site file or data_root:=" % DATA_ROOT)
    elif not os.path.isabs(root):
        problems.append("%s must be an absolute path, got %r" % (DATA_ROOT, root))

    if not insecure and not any(given.get(name) for name in AUTH_ALTERNATIVES):
        problem = _secret_problem(TOKEN_FILE, given.get(TOKEN_FILE), read_secret)
        if problem:
            problems.append(problem + " (the backend link's shared secret; insecure:=true only on a bench)")
    elif given.get(TOKEN_FILE):
        problem = _secret_problem(TOKEN_FILE, given[TOKEN_FILE], read_secret)
        if problem:
            problems.append(problem)
    for name in SECRET_FILES:
        if given.get(name):
            problem = _secret_problem(name, given[name], read_secret)
            if problem:
                problems.append(problem)
    problems.extend(_bridge_problems(effective, insecure))
    return problems


def _bridge_problems(effective, insecure):
    """The bridge's own start-up check of its security settings (access.check_fixed), so a setting it
    would refuse at every respawn stops robot.launch instead; and no open surface on a robot."""
    prefix = BRIDGE + "/"
    settings = {name[len(prefix):]: value for name, value in effective.items()
                if name.startswith(prefix) and name[len(prefix):] in FIXED_KEYS[BRIDGE]}
    settings["insecure"] = bool(insecure)
    try:
        check_fixed(settings)
    except AccessError as err:
        return ["%s: %s" % (BRIDGE, str(err).replace("~", prefix))]
    if settings.get("surface", "robot") != "robot":
        return ["%ssurface is %r: a robot serves the backend surface only (surface: robot; sim and open are for "
                "the simulator and protocol tests)" % (prefix, settings["surface"])]
    return []


def format_problems(problems, site_path):
    """robot.launch's one start-up refusal for ``problems`` (site_problems)."""
    return ("robot.launch refused to start, %d site setting(s) to fix in %s (template: %s, "
            "docs/deployment.md \"Site configuration\"):\n  - %s"
            % (len(problems), site_path or "(no robot_config given)", TEMPLATE, "\n  - ".join(problems)))
