"""Security settings and data paths read from files at start-up only, never from the parameter server.

A node's parameters live on the ROS parameter server, which anything with ROS access can rewrite
while the robot runs; roslaunch respawns a node with the same command line and environment but the
parameter server as it is *then*. A setting that decides who may reach the robot (authentication,
TLS, browser origins, the link's address, which names a client may use) or where it reads and
writes files (the data root, the folders files are served from and captured into, every path
parameter) must not come back weaker after a restart than the site file says. So nodes take them
from where only the launch decides, in this order (last wins):

1. the package's defaults file for the node (config/<node type>.yaml),
2. the site file's section for the node (robot_config): its path is ``--site-file PATH`` on the
   command line or ``INSPECTION_ROBOT_SITE_FILE`` in the environment (core.launch sets it for
   every node of the robot),
3. ``_key:=value`` on the node's command line (rospy's private-parameter syntax; e.g. robot.launch's
   ``address`` and ``insecure`` reach the bridge as ``_address:=0.0.0.0``).

The data root is the site file's top-level ``data_root`` when it has one (core.launch loads the site
file last), else ``_data_root:=`` on the command line, else ``INSPECTION_ROBOT_DATA_ROOT`` from
core.launch. roslaunch repeats the command line and the environment on every respawn, and a file
is changed only by someone who may change the robot anyway. The parameter server's copy is ignored
(the node logs a difference). Pure module: the node passes argv, the environment and the paths.
"""
import yaml

SITE_FILE_FLAG = "--site-file"
SITE_FILE_ENV = "INSPECTION_ROBOT_SITE_FILE"
DATA_ROOT_ENV = "INSPECTION_ROBOT_DATA_ROOT"
DATA_ROOT = "data_root"
# node name -> its security settings (path parameters are fixed for every node: ros/data_root.py)
FIXED_KEYS = {
    "rosbridge_websocket": ("address", "certfile", "keyfile", "client_ca", "auth_token", "auth_token_file",
                            "insecure", "allowed_origins", "surface"),
}


class FixedSettingsError(ValueError):
    """A file or command-line value the node cannot start with; the text says which."""


def _load(path, what):
    try:
        with open(path) as f:
            data = yaml.safe_load(f)
    except (OSError, yaml.YAMLError) as err:
        raise FixedSettingsError("cannot read %s %s: %s" % (what, path, err))
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise FixedSettingsError("%s %s is not a YAML mapping" % (what, path))
    return data


def split_argv(argv):
    """(site file path or "", {key: YAML text} of every ``_key:=value``) from a node's command line."""
    site, private = "", {}
    args = list(argv)
    i = 0
    while i < len(args):
        arg = args[i]
        if arg == SITE_FILE_FLAG and i + 1 < len(args):
            site = args[i + 1]
            i += 1
        elif arg.startswith(SITE_FILE_FLAG + "="):
            site = arg[len(SITE_FILE_FLAG) + 1:]
        elif arg.startswith("_") and not arg.startswith("__") and ":=" in arg:
            key, value = arg[1:].split(":=", 1)
            private[key] = value
        i += 1
    return site, private


class StartupFiles(object):
    """One node's fixed sources, read once: ``get(key)`` and ``data_root()``.

    ``node``: its name in the site file; ``argv``: its command line without the program;
    ``defaults_file``: config/<type>.yaml (None: none); ``environ``: its environment.
    """

    def __init__(self, node, argv, defaults_file, environ):
        site_path, self._private = split_argv(argv)
        self.site_file = site_path or environ.get(SITE_FILE_ENV, "")
        self._env_root = environ.get(DATA_ROOT_ENV, "")
        self._defaults = _load(defaults_file, "defaults file") if defaults_file else {}
        self._site = _load(self.site_file, "site file") if self.site_file else {}
        self._section = self._site.get(node) or {}
        if not isinstance(self._section, dict):
            raise FixedSettingsError("site file %s: %s must be a mapping" % (self.site_file, node))

    @property
    def launched(self):
        """True under core.launch (or with a site file): the paths are fixed. A node a test starts on
        its own keeps reading its parameters."""
        return bool(self.site_file or self._env_root or DATA_ROOT in self._private)

    def has(self, key):
        return key in self._defaults or key in self._section or key in self._private

    def get(self, key, default=None):
        value = default
        if key in self._defaults:
            value = self._defaults[key]
        if key in self._section:
            value = self._section[key]
        if key in self._private:
            try:
                value = yaml.safe_load(self._private[key])
            except yaml.YAMLError as err:
                raise FixedSettingsError("_%s:=%s on the command line is not YAML: %s"
                                         % (key, self._private[key], err))
        return value

    def data_root(self):
        """The data root as the launch gave it, or "" when it gave none."""
        if self._site.get(DATA_ROOT):
            return str(self._site[DATA_ROOT])   # as core.launch: the site file's data_root is loaded last
        if DATA_ROOT in self._private:
            return str(self.get(DATA_ROOT))
        return self._env_root


def fixed_settings(node, argv, defaults_file, environ=None):
    """{key: value} of ``node``'s :data:`FIXED_KEYS` that some source sets, plus ``site_file`` (its
    path or "") and ``data_root`` (or ""); FixedSettingsError when a named file cannot be read."""
    files = StartupFiles(node, argv, defaults_file, environ or {})
    values = {key: files.get(key) for key in FIXED_KEYS[node] if files.has(key)}
    values["site_file"] = files.site_file
    values[DATA_ROOT] = files.data_root()
    return values


def overridden(fixed, current):
    """The keys whose parameter-server value ``current`` (a dict) differs from the fixed one: a write
    after launch, ignored."""
    return sorted(k for k, v in fixed.items() if k not in ("site_file", DATA_ROOT) and k in current
                  and current[k] != v)
