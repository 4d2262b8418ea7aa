"""Imports go one way: only inspection_robot.nodes (ROS wiring) may import rospy or ROS types."""
import ast
import os

SRC = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))),
                   "src", "inspection_robot")
ROS_MODULES = ("rospy", "actionlib", "tf2_ros", "diagnostic_updater", "rosgraph")
# Message conversion lives in one place outside nodes/ only where a pure module must name types.
ALLOWED_OUTSIDE_NODES = {"bridge/ros_types.py", "bridge/ros_adapter.py"}


def imported_modules(path):
    with open(path) as f:
        tree = ast.parse(f.read(), path)
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.module


def test_only_nodes_import_rospy():
    offenders = []
    for folder, _dirs, files in os.walk(SRC):
        rel_folder = os.path.relpath(folder, SRC)
        if rel_folder.split(os.sep)[0] == "nodes":
            continue
        for name in files:
            if not name.endswith(".py"):
                continue
            rel = os.path.normpath(os.path.join(rel_folder, name))
            if rel in ALLOWED_OUTSIDE_NODES:
                continue
            for module in imported_modules(os.path.join(folder, name)):
                if module.split(".")[0] in ROS_MODULES or module == "inspection_robot.msg" \
                        or module == "inspection_robot.srv":
                    offenders.append("%s imports %s" % (rel, module))
    assert offenders == []


def test_every_module_has_a_docstring():
    missing = []
    for folder, _dirs, files in os.walk(SRC):
        for name in files:
            if name.endswith(".py"):
                path = os.path.join(folder, name)
                with open(path) as f:
                    if ast.get_docstring(ast.parse(f.read())) is None:
                        missing.append(os.path.relpath(path, SRC))
    assert missing == []
