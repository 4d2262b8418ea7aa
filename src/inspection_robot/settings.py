"""A node's settings, from its one source: config/<node>.yaml holds each default and its one-line comment.

A node reads a setting as the parameter server has it, else as the file has it (ros/node.py,
:class:`~inspection_robot.ros.node.NodeSettings`), so a node a test starts without loading its
file behaves as under a launch, and no default is written a second time in code. A name the file
does not define is an error: the file is the list of what the node reads.

The file's comments are part of it (PyYAML drops them): ``key: value  # comment`` gives ``key`` its
comment, and comment-only lines indented further than a key continue that key's comment. Nested
mappings are flattened as roslaunch sets them (``ros_base:`` / ``cmd_vel_topic:`` is
``ros_base/cmd_vel_topic``); every leaf is a setting, a mapping with keys below it is a group
(read whole, its leaves merged over the file's as a launch merges them). Pure module: no rospy.
"""
import os
import re
from collections import OrderedDict, namedtuple

import yaml

PACKAGE = "inspection_robot"
CONFIG = "config"
# Files a launch loads into more than one node, beside the node's own (launch/include/*.launch; a unit
# test checks this table against them): node -> file names without .yaml.
SHARED_FILES = {
    "camera_node": ("camera_optics",),
    "cloud_terrace": ("camera_optics",),
    "file_server": ("camera_optics",),
    "find_scale": ("camera_optics",),
    "preset_scale": ("camera_optics",),
}

Setting = namedtuple("Setting", "name default comment line")
"""name: ``key`` or ``group/key``; default: the file's value; comment: its one-line comment ("" when
the file gives none); line: 1-based line in the file."""

_KEY = re.compile(r"^([A-Za-z0-9_][A-Za-z0-9_\-]*)\s*:(?:\s+(.*)|\s*)$")


class SettingsError(ValueError):
    """A settings file that cannot be read, or a name it does not define; the text says which."""


def _split_comment(text):
    """(value text, comment) of what follows ``key:`` on one line; a ``#`` inside quotes is text."""
    quote = None
    for i, char in enumerate(text):
        if quote:
            if char == quote:
                quote = None
        elif char in "'\"":
            quote = char
        elif char == "#" and (i == 0 or text[i - 1] in " \t"):
            return text[:i].strip(), text[i + 1:].strip()
    return text.strip(), ""


def parse(text, path="<text>"):
    """(tree, settings, groups) of one settings file: the YAML mapping, an OrderedDict name ->
    :class:`Setting` of every leaf in file order, and the set of group names."""
    try:
        tree = yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise SettingsError("%s is not valid YAML: %s" % (path, " ".join(str(err).split())))
    if tree is None:
        tree = {}
    if not isinstance(tree, dict):
        raise SettingsError("%s is not a YAML mapping" % path)
    found = OrderedDict()   # name -> [comment parts, line, has a value on its line]
    stack = []              # (indent, key) of the keys enclosing the current line
    last, last_indent = None, 0
    for number, line in enumerate(text.splitlines(), 1):
        stripped = line.strip()
        indent = len(line) - len(line.lstrip())
        if not stripped:
            continue
        if stripped.startswith("#"):
            if last is not None and indent > last_indent:
                found[last][0].append(stripped.lstrip("#").strip())   # the comment goes on
            else:
                last = None   # a note of its own (a header, a site setting without a default)
            continue
        match = _KEY.match(stripped)
        if stripped.startswith("-") or not match:
            continue   # a list item or the rest of a flow value: part of the value above
        while stack and stack[-1][0] >= indent:
            stack.pop()
        name = "/".join([key for _, key in stack] + [match.group(1)])
        value, comment = _split_comment(match.group(2) or "")
        found[name] = [[comment] if comment else [], number, bool(value)]
        stack.append((indent, match.group(1)))
        last, last_indent = name, indent
    groups = {name.rsplit("/", 1)[0] for name in found if "/" in name}
    settings = OrderedDict()
    for name, (comment, number, _has_value) in found.items():
        if name in groups:
            continue
        value = _lookup(tree, name)
        if value is _MISSING:
            continue   # a key inside a list's mappings (a data file): not a setting
        settings[name] = Setting(name, value, " ".join(comment), number)
    return tree, settings, groups


_MISSING = object()


def _lookup(tree, name):
    node = tree
    for part in name.split("/"):
        if not isinstance(node, dict) or part not in node:
            return _MISSING
        node = node[part]
    return node


def merged(default, given):
    """``given`` over ``default`` as a launch merges them: mappings key by key (recursively), anything
    else replaced."""
    if isinstance(default, dict) and isinstance(given, dict):
        out = OrderedDict(default)
        for key, value in given.items():
            out[key] = merged(default.get(key, _MISSING), value) if key in default else value
        return dict(out)
    return given


class NodeDefaults(object):
    """One node's defaults: its config/<node>.yaml and the shared files (:data:`SHARED_FILES`) a launch
    loads beside it. ``default(name)`` (``rate``, ``ros_base``, ``ros_base/odom_timeout``) is the
    file's value; SettingsError for a name none of them defines."""

    def __init__(self, node, files):
        """``files``: [(path, text)], the node's own first."""
        self.node = node
        self.files = [path for path, _ in files]
        self.tree = OrderedDict()
        self.settings = OrderedDict()
        self.groups = set()
        self.source = {}   # top-level key -> the file defining it
        for path, text in files:
            tree, settings, groups = parse(text, path)
            for key in tree:
                if key in self.tree:
                    raise SettingsError("%s: %s is also in %s" % (path, key, self.source[key]))
                self.tree[key] = tree[key]
                self.source[key] = path
            self.settings.update(settings)
            self.groups |= groups

    def __contains__(self, name):
        return _lookup(self.tree, name.lstrip("~")) is not _MISSING

    def default(self, name):
        key = name.lstrip("~")
        value = _lookup(self.tree, key)
        if value is _MISSING:
            raise SettingsError("%s reads ~%s, which %s does not define (config/<node>.yaml is the one source "
                                "of a node's settings and their defaults)"
                                % (self.node, key, " nor ".join(self.files) or "no settings file"))
        return value

    def get(self, name, given=_MISSING):
        """The value a node runs with: ``given`` (the parameter server's, if any) merged over the default."""
        default = self.default(name)
        return default if given is _MISSING else merged(default, given)


def source_config_dir():
    """config/ of the source tree this module lies in (a checkout or a devel space), or None (installed)."""
    root = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
    config = os.path.join(root, CONFIG)
    if os.path.isfile(os.path.join(root, "package.xml")) and os.path.isdir(config):
        return config
    return None


def config_dir(share_dir=None):
    """The package's config/: the source tree's, else ``share_dir``/config (the installed package's share
    directory, which the ROS side finds through rospkg: ros/package_share.py). SettingsError when neither."""
    config = source_config_dir()
    if config:
        return config
    if share_dir and os.path.isdir(os.path.join(share_dir, CONFIG)):
        return os.path.join(share_dir, CONFIG)
    raise SettingsError("cannot find %s's config/ (not in a source tree, and the share directory %r has none)"
                        % (PACKAGE, share_dir))


def node_files(node, directory):
    """Paths of ``node``'s settings files in ``directory``: config/<node>.yaml, then its shared files."""
    return [os.path.join(directory, name + ".yaml") for name in (node,) + SHARED_FILES.get(node, ())]


def _read(path):
    try:
        with open(path) as handle:
            return handle.read()
    except OSError as err:
        raise SettingsError("cannot read %s: %s" % (path, err.strerror))


def node_defaults(node, directory):
    """:class:`NodeDefaults` of ``node`` from ``directory`` (:func:`config_dir`)."""
    return NodeDefaults(node, [(path, _read(path)) for path in node_files(node, directory)])


def node_names(directory):
    """Every node with a config/<node>.yaml: the node modules of the package (nodes/<node>.py) that have one."""
    nodes_dir = os.path.join(os.path.dirname(os.path.abspath(__file__)), "nodes")
    modules = {name[:-3] for name in os.listdir(nodes_dir) if name.endswith(".py")}
    return sorted(name[:-5] for name in os.listdir(directory) if name.endswith(".yaml") and name[:-5] in modules)
