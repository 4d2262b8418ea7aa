"""This robot's state directory for a node: the namespace parameter ``data_root``.

core.launch sets ``<ns>/data_root`` (see docs/operations.md); a node started on its own falls back
to ``$ROS_HOME/inspection_robot/<namespace>`` and says so. Path parameters of the nodes are relative
to the data root unless absolute (``files.under``).
"""
import os

import rospy

from inspection_robot.files import standalone_data_root, under


def data_root():
    """The absolute data root; read once in a node's main()."""
    root = rospy.get_param("data_root", "")
    if not root:
        root = standalone_data_root(os.environ, rospy.get_namespace())
        rospy.logwarn("%s: no data_root parameter, using %s" % (rospy.get_name(), root))
    return os.path.abspath(os.path.expanduser(root))


def path_param(name, default, root):
    """A private path parameter, relative to ``root`` unless absolute."""
    return under(root, rospy.get_param(name, default))


def path_list_param(name, default, root):
    return [under(root, p) for p in rospy.get_param(name, default)]
