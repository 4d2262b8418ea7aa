"""One source per setting: config/<node>.yaml holds each node setting's default and its comment.

Checked here, without a roscore: every setting in the files has a comment; the nodes read their
settings through ros.node.NodeSettings (no ``get_param("~name", default)`` writes a default again),
and every top-level key of a node's file is read by that node; site/check.py's and fixed_settings.py's
lists of node settings name keys the files define; the launch files load a node's shared files as
settings.SHARED_FILES says; and a default the docs quote (``~name`` then a number) is the file's.
"""
import ast
import glob
import os
import re
import xml.etree.ElementTree as ElementTree

import pytest

from inspection_robot import settings
from inspection_robot.drivers import DEVICES
from inspection_robot.fixed_settings import FIXED_KEYS
from inspection_robot.motion.base_inputs import PARAM as ROS_BASE_PARAM
from inspection_robot.nav.pose_adapter import ADAPTER_SETTINGS
from inspection_robot.site.check import ADAPTER, ADAPTER_PARAMS, DRIVER_SETTINGS, REQUIRED, SECRET_FILES

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SRC = os.path.join(ROOT, "src", "inspection_robot")
CONFIG = os.path.join(ROOT, "config")
# config/sim_world.yaml is the simulated yard, data a launch loads into ~sim_world (robot_control)
# or ~world (sim_obstacle_cloud); the node sim_world reads the file named by ~world_file.
DATA_FILES = {"sim_world"}
# Nodes still reading settings with literal defaults: none.
NOT_YET = set()
NODES = [n for n in settings.node_names(CONFIG) if n not in DATA_FILES]
# get_param with a default that stays: none of these is a setting with a package default.
ALLOWED_DEFAULTS = {
    ("robot_control", "~sim_world/world"): "the simulated yard, loaded only in simulation",
    ("sim_localizer", "~seed"): "unset = unseeded noise; the parameter server cannot hold YAML null",
    ("status_control", "site_check"): "a namespace parameter robot.launch writes, not a node setting",
}
# Top-level keys a node reads under a name built elsewhere (a module's constant).
READ_AS = {
    "pose_adapter": set(ADAPTER_SETTINGS),
    "robot_control": {ROS_BASE_PARAM},
}
# The bridge's ~address is a launch argument on its command line (bridge.launch), not a file setting.
COMMAND_LINE_ONLY = {"rosbridge_websocket": {"address"}}
# Docs quoting a number after a ~name that is not that setting's default (name, number): why.
SECURITY_TEST = "the security suite's second bridge (security.test), not a default"
DOC_ALLOWED = {
    ("auth_max_failures", "3"): SECURITY_TEST,
    ("handshake_timeout", "2"): SECURITY_TEST,
    ("max_message_size", "100"): SECURITY_TEST + " (100 kB)",
}


def defaults(node):
    return settings.node_defaults(node, CONFIG)


def node_source(node):
    with open(os.path.join(SRC, "nodes", node + ".py")) as handle:
        return handle.read()


def _calls(tree, name):
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            func = node.func
            called = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
            if called == name:
                yield node


def _literal_name(call):
    first = call.args[0] if call.args else None
    if isinstance(first, ast.Constant) and isinstance(first.value, str):
        return first.value
    if isinstance(first, ast.BinOp) and isinstance(first.left, ast.Constant):
        return "%s<...>" % first.left.value
    return None


def _has_default(call):
    return len(call.args) > 1 or any(k.arg == "param_default" for k in call.keywords)


# --- the parser ------------------------------------------------------------------------------------
def test_parse_reads_inline_and_continued_comments_and_flattens_groups():
    text = ("# header\n"
            "rate: 10.0          # Hz\n"
            "topic: \"a#b\"      # quoted # stays text\n"
            "long: 1             # first line\n"
            "                    # second line\n"
            "# a note of its own\n"
            "base:               # the group\n"
            "  odom_topic: odom  # in\n"
            "  list:\n"
            "    - [1, 2]\n"
            "bare: 3\n")
    tree, found, groups = settings.parse(text, "x.yaml")
    assert list(found) == ["rate", "topic", "long", "base/odom_topic", "base/list", "bare"]
    assert found["rate"].comment == "Hz" and found["rate"].default == 10.0
    assert found["topic"].default == "a#b" and found["topic"].comment == "quoted # stays text"
    assert found["long"].comment == "first line second line"
    assert found["base/list"].default == [[1, 2]] and found["bare"].comment == ""
    assert groups == {"base"} and tree["base"]["odom_topic"] == "odom"


def test_defaults_and_merge():
    nd = settings.NodeDefaults("n", [("n.yaml", "a: 1  # x\ng:\n  b: 2  # y\n  c: 3  # z\n")])
    assert nd.default("~a") == 1 and nd.default("g/b") == 2 and nd.default("g") == {"b": 2, "c": 3}
    assert nd.get("g", {"b": 5, "d": 6}) == {"b": 5, "c": 3, "d": 6}
    assert nd.get("a", 4) == 4 and nd.get("a") == 1
    with pytest.raises(settings.SettingsError, match="~missing"):
        nd.default("missing")


def test_config_dir_is_the_source_tree_here():
    assert os.path.samefile(settings.config_dir(), CONFIG)


# --- (a) every setting has a comment ----------------------------------------------------------------
@pytest.mark.parametrize("node", NODES)
def test_every_setting_has_a_comment(node):
    uncommented = [s.name for s in defaults(node).settings.values() if not s.comment]
    assert not uncommented, "config/%s.yaml: give these a one-line comment: %s" % (node, uncommented)


# --- (b) the nodes read their settings through NodeSettings ------------------------------------------
@pytest.mark.parametrize("node", [n for n in NODES if n not in NOT_YET])
def test_node_writes_no_default_of_its_own(node):
    tree = ast.parse(node_source(node))
    found = []
    for call in _calls(tree, "get_param"):
        name = _literal_name(call)
        if _has_default(call) and (node, name) not in ALLOWED_DEFAULTS:
            found.append("line %d: get_param(%s, <default>)" % (call.lineno, name))
        elif name and name.startswith("~") and name in defaults(node):
            found.append("line %d: get_param(%r) of a file setting" % (call.lineno, name))
    for helper in ("path_param", "path_list_param", "fixed_list"):   # data_root's, given a default
        for call in _calls(tree, helper):
            if isinstance(call.func, ast.Name) or getattr(call.func.value, "id", None) == "data_root":
                found.append("line %d: data_root.%s(%s, <default>)" % (call.lineno, helper, _literal_name(call)))
    assert not found, ("nodes/%s.py: read settings with NodeSettings.get/path/path_list/fixed_list, the default "
                       "in config/%s.yaml:\n  %s" % (node, node, "\n  ".join(found)))


@pytest.mark.parametrize("node", [n for n in NODES if n not in NOT_YET])
def test_node_asks_only_for_settings_its_file_defines(node):
    nd = defaults(node)
    tree = ast.parse(node_source(node))
    unknown = []
    for method in ("get", "path", "path_list", "fixed_list", "default"):
        for call in _calls(tree, method):
            if isinstance(call.func, ast.Attribute) and getattr(call.func.value, "id", None) == "settings":
                name = _literal_name(call)
                if name and "<...>" not in name and name not in nd:
                    unknown.append(name)
    assert not unknown, "nodes/%s.py reads %s, not in config/%s.yaml" % (node, unknown, node)


@pytest.mark.parametrize("node", [n for n in NODES if n not in NOT_YET])
def test_every_key_of_the_file_is_read_by_its_node(node):
    strings = {c.value for c in ast.walk(ast.parse(node_source(node)))
               if isinstance(c, ast.Constant) and isinstance(c.value, str)}
    read = {s.lstrip("~") for s in strings} | READ_AS.get(node, set())
    unread = [key for key in defaults(node).tree if key not in read]
    assert not unread, "config/%s.yaml defines %s, which nodes/%s.py never reads" % (node, unread, node)


def test_ros_modules_write_no_default_of_a_file_setting():
    every = set()
    for node in NODES:
        every |= {"~" + name for name in defaults(node).settings} | {"~" + key for key in defaults(node).tree}
    found = []
    for path in sorted(glob.glob(os.path.join(SRC, "ros", "*.py"))):
        with open(path) as handle:
            tree = ast.parse(handle.read())
        for call in _calls(tree, "get_param"):
            if _has_default(call) and _literal_name(call) in every:
                found.append("%s:%d %s" % (os.path.relpath(path, ROOT), call.lineno, _literal_name(call)))
    assert not found, "defaults written again outside config/: %s" % found


# --- (c) lists of node settings elsewhere name keys the files define -----------------------------------
def test_site_lists_name_settings_of_the_files():
    assert tuple(ADAPTER_PARAMS) == tuple(k for k in defaults(ADAPTER).tree if k != "mode")
    for (device, _driver), keys in DRIVER_SETTINGS.items():
        node = DEVICES[device].node
        assert all(key in defaults(node) for key in keys), (device, keys)
    for name in SECRET_FILES:
        node, key = name.split("/", 1)
        assert key in defaults(node), name
    for name in REQUIRED:   # site settings have no package default
        node, key = name.split("/", 1)
        assert key not in defaults(node).tree, "%s is a site setting: no default in config/%s.yaml" % (name, node)


def test_fixed_keys_are_settings_of_the_file():
    for node, keys in FIXED_KEYS.items():
        missing = [k for k in keys if k not in defaults(node) and k not in COMMAND_LINE_ONLY.get(node, ())]
        assert not missing, "fixed_settings.FIXED_KEYS[%s] names %s, not in config/%s.yaml" % (node, missing, node)


def test_shared_files_are_what_the_launch_files_load():
    loaded = {}
    launches = glob.glob(os.path.join(ROOT, "launch", "*.launch")) + glob.glob(os.path.join(ROOT, "launch", "include",
                                                                                            "*.launch"))
    for path in launches:
        for node in ElementTree.parse(path).getroot().iter("node"):
            for rosparam in node.iter("rosparam"):
                match = re.search(r"/config/(\w+)\.yaml$", rosparam.get("file", ""))
                if match and match.group(1) not in DATA_FILES and match.group(1) != node.get("type"):
                    loaded.setdefault(node.get("type"), set()).add(match.group(1))
    assert loaded == {node: set(files) for node, files in settings.SHARED_FILES.items()}


# --- (d) defaults quoted in the docs are the files' ------------------------------------------------------
_QUOTED = re.compile(r"`~([A-Za-z_][\w/]*)`?\s*(?:\(([^()\d-]*?),\s*)?(?:=\s*)?(-?\d+(?:\.\d+)?)(?![\w./])")


def quoted_defaults(text):
    """(name, number text) of each ``~name`` followed by a number: "`~x` 60", "`~x` (s, 3.0)", "`~x` = 2"."""
    return [(m.group(1), m.group(3)) for m in _QUOTED.finditer(text)]


def test_quoted_defaults_pattern():
    text = "`~server_timeout_s` 60 and `~rate` (Hz, 10.0), `~nice` = -10, `~mode` tf, `~x` 5 s, `~y` 2.5.x"
    assert quoted_defaults(text) == [("server_timeout_s", "60"), ("rate", "10.0"), ("nice", "-10"), ("x", "5")]


def test_docs_quote_the_files_defaults():
    by_name = {}
    for node in settings.node_names(CONFIG):
        for name, setting in defaults(node).settings.items():
            by_name.setdefault(name, []).append((node, setting.default))
    mismatches = []
    docs = sorted(glob.glob(os.path.join(ROOT, "docs", "**", "*.md"), recursive=True))
    docs.append(os.path.join(ROOT, "README.md"))
    for path in docs:
        with open(path) as handle:
            text = handle.read()
        for name, number in quoted_defaults(text):
            if name not in by_name or (name, number) in DOC_ALLOWED:
                continue
            values = [v for _node, v in by_name[name] if isinstance(v, (int, float)) and not isinstance(v, bool)]
            if values and not any(abs(float(number) - v) < 1e-9 for v in values):
                mismatches.append("%s: ~%s %s, but %s" % (os.path.relpath(path, ROOT), name, number,
                                                          ", ".join("config/%s.yaml has %r" % nv
                                                                    for nv in by_name[name])))
    assert not mismatches, "\n".join(mismatches)
