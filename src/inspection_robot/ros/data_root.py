"""This robot's state directory for a node, and its path parameters, as the launch fixed them.

Under core.launch (which sets ``INSPECTION_ROBOT_DATA_ROOT`` and ``INSPECTION_ROBOT_SITE_FILE`` for
every node) the data root and every path parameter come from the files and the command line only
(fixed_settings.StartupFiles: config/<node type>.yaml, the site file, ``_key:=``), never from the
parameter server: a parameter written while the robot runs cannot move where a respawned node reads
and writes (docs/interface.md, "Backend link access"). A node started on its own (a test's launch
file) reads the namespace parameter ``data_root`` and its private path parameters as before, and
falls back to ``$ROS_HOME/inspection_robot/<namespace>``, saying so. Path parameters are relative to
the data root unless absolute (``data_layout.under``).
"""
import os
import sys

import rospy

from inspection_robot.data_layout import standalone_data_root, under
from inspection_robot.fixed_settings import StartupFiles
from inspection_robot.ros.package_share import share_file

_startup = []   # this process's StartupFiles, read once


def startup_files():
    """This node's fixed sources (read on first use)."""
    if not _startup:
        node_type = os.path.basename(sys.argv[0]) if sys.argv and sys.argv[0] else ""
        defaults = share_file("config", node_type + ".yaml") if node_type else None
        if defaults and not os.path.isfile(defaults):
            defaults = None
        _startup.append(StartupFiles(rospy.get_name().rsplit("/", 1)[-1], sys.argv[1:], defaults, os.environ))
    return _startup[0]


def _warn_if_changed(name, fixed_value):
    if rospy.has_param(name) and rospy.get_param(name) != fixed_value:
        rospy.logwarn("%s: ignoring the parameter server's %s (%r): paths come only from the launch's files and "
                      "command line (%r)", rospy.get_name(), rospy.resolve_name(name), rospy.get_param(name),
                      fixed_value)


def data_root():
    """The absolute data root; read once in a node's main()."""
    files = startup_files()
    root = files.data_root() if files.launched else ""
    if root:
        _warn_if_changed("data_root", root)
    else:
        root = rospy.get_param("data_root", "")
    if not root:
        root = standalone_data_root(os.environ, rospy.get_namespace())
        rospy.logwarn("%s: no data_root parameter, using %s" % (rospy.get_name(), root))
    return os.path.abspath(os.path.expanduser(root))


def _path_value(name, default):
    files = startup_files()
    if not files.launched:
        return rospy.get_param(name, default)
    value = files.get(name.lstrip("~"), default)
    _warn_if_changed(name, value)
    return value


def fixed_list(name, default):
    """A private list parameter fixed at launch like the paths (file_server's roots, relative as given)."""
    return _path_value(name, default)


def path_param(name, default, root):
    """A private path parameter, relative to ``root`` unless absolute."""
    return under(root, _path_value(name, default))


def path_list_param(name, default, root):
    return [under(root, p) for p in _path_value(name, default)]
