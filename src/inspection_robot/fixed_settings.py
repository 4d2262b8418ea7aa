"""Security settings read from files at start-up only, never from the parameter server.

A node's parameters live on the ROS parameter server, which anything with ROS access can rewrite
while the robot runs; roslaunch respawns a node with the same command line but the parameter
server as it is *then*. A setting that decides who may reach the robot (authentication, TLS,
browser origins, the link's address, which names a client may use, the folders files are served
from) must not come back weaker after a restart than the site file says. So the nodes that hold
one take it from where only the launch decides:

1. the package's defaults file for the node (config/<node>.yaml),
2. the site file's section for the node (robot_config; ``--site-file PATH`` on the command line),
   and its top-level ``data_root``,
3. ``_key:=value`` on the node's command line (rospy's private-parameter syntax; the launch files
   put their arguments there, e.g. ``_address:=0.0.0.0``), last wins; but the site file's top-level
   ``data_root`` wins over the launch's, as core.launch loads it last.

roslaunch repeats the command line on every respawn, and a file is changed only by someone who
may change the robot anyway. The parameter server's copy of a fixed key is ignored (and a
difference logged by the node). Pure module: the node passes argv and the package's paths.
"""
import yaml

SITE_FILE_FLAG = "--site-file"
# node name -> the keys it takes only from files and its command line
FIXED_KEYS = {
    "rosbridge_websocket": ("address", "certfile", "keyfile", "client_ca", "auth_token", "auth_token_file",
                            "insecure", "allowed_origins", "surface"),
    "file_server": ("roots", "preset_roots", "data_root"),
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
        elif arg.startswith("_") and ":=" in arg:
            key, value = arg[1:].split(":=", 1)
            private[key] = value
        i += 1
    return site, private


def fixed_settings(node, argv, defaults_file):
    """{key: value} of ``node``'s :data:`FIXED_KEYS` (absent when no source sets it) and the site file's
    path under ``"site_file"``; FixedSettingsError when a named file cannot be read."""
    keys = FIXED_KEYS[node]
    site_path, private = split_argv(argv)
    values = {}
    defaults = _load(defaults_file, "defaults file") if defaults_file else {}
    site = _load(site_path, "site file") if site_path else {}
    section = site.get(node) or {}
    if not isinstance(section, dict):
        raise FixedSettingsError("site file %s: %s must be a mapping" % (site_path, node))
    for key in keys:
        if key in defaults:
            values[key] = defaults[key]
        if key in section:
            values[key] = section[key]
        if key in private:
            try:
                values[key] = yaml.safe_load(private[key])
            except yaml.YAMLError as err:
                raise FixedSettingsError("_%s:=%s on the command line is not YAML: %s" % (key, private[key], err))
        if key == "data_root" and site.get("data_root"):
            values[key] = site["data_root"]   # as core.launch: the site file's data_root is loaded last
    values["site_file"] = site_path
    return values


def overridden(fixed, current):
    """The keys whose parameter-server value ``current`` (a dict) differs from the fixed one: a write
    after launch, ignored."""
    return sorted(k for k, v in fixed.items() if k != "site_file" and k in current and current[k] != v)
