"""Imports go one way: only the ROS wing (nodes/, ros/ and each capability's ROS-side modules, named
ros_*.py beside the pure modules they serve) may import ROS, and no pure module imports a ROS-side
one; the layout holds; the robot's package never imports the test harness
(src/inspection_robot_testing) and setup.py never installs it; importing a production module neither
loads a simulator nor reads the environment (issue #43: a simulator is imported inside the branch
that chose it, configuration is read in main()).

The list of ROS modules is every ROS package that package.xml declares plus the client library's
own modules that a package gets without declaring them (genpy, roslib, rosgraph ...), so a new
dependency is covered the day it is declared.
"""
import ast
import os
import runpy
import sys
import types
import xml.etree.ElementTree as ElementTree
from unittest import mock

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SRC = os.path.join(ROOT, "src", "inspection_robot")
# The test harness: soak, fixtures, demo and test clients; its own ROS side lives in its ros/.
HARNESS = os.path.join(ROOT, "src", "inspection_robot_testing")
# Modules every rospy installation brings along, declared or not.
ROS_CLIENT_MODULES = {"rospy", "genpy", "genmsg", "roslib", "rosgraph", "rospkg", "rosservice",
                      "rostopic", "rosnode", "rosparam", "roslaunch", "rosmsg", "rosbag", "rostest",
                      "actionlib", "tf", "tf2_py", "tf2_ros", "diagnostic_updater", "message_filters"}
# nodes/ holds the nodes' entry points, ros/ the ROS helpers every capability shares, and a
# capability's own ROS side sits in its folder as ros_*.py (bridge/ros_backend.py, task/ros_steps.py).
# tools/ is command lines only: their ROS side (e.g. bag_report's reading) is a ros_*.py module.
ROS_WING = ("nodes", "ros")


def is_ros_side(rel):
    """Whether the module at ``rel`` (relative to the package) may import ROS."""
    parts = rel.split(os.sep)
    return parts[0] in ROS_WING or (len(parts) > 1 and parts[-1].startswith("ros_"))


def is_ros_side_module(module):
    """Whether an imported ``inspection_robot.…`` module is one of the ROS wing's."""
    parts = module.split(".")
    return parts[0] == "inspection_robot" and len(parts) > 1 and is_ros_side(os.path.join(*parts[1:]) + ".py")


def declared_ros_packages():
    """ROS package names in package.xml: rosdep keys of system packages carry a hyphen."""
    tree = ElementTree.parse(os.path.join(ROOT, "package.xml"))
    names = set()
    for element in tree.getroot():
        if element.tag.endswith("depend") and element.text and "-" not in element.text:
            names.add(element.text.strip())
    return names


def ros_modules():
    return (declared_ros_packages() | ROS_CLIENT_MODULES) - {"catkin"}


def imported_modules(path):
    with open(path) as f:
        tree = ast.parse(f.read(), path)
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.module


def import_time_nodes(tree):
    """The AST nodes that run when the module is imported: everything outside function bodies (class
    bodies, top-level if/try blocks and decorators included)."""
    stack = list(tree.body)
    while stack:
        node = stack.pop()
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            # only the decorators and default values run at import
            stack.extend(getattr(node, "decorator_list", []))
            stack.extend(node.args.defaults + [d for d in node.args.kw_defaults if d is not None])
            continue
        yield node
        stack.extend(ast.iter_child_nodes(node))


def import_time_imports(source, path="<source>"):
    """Modules imported when ``source`` is imported (``from inspection_robot import sim`` counts as
    inspection_robot.sim)."""
    for node in import_time_nodes(ast.parse(source, path)):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.module
            for alias in node.names:
                yield "%s.%s" % (node.module, alias.name)


def import_time_environment_reads(source, path="<source>"):
    """Line numbers where ``source`` reads the environment (os.environ, os.getenv, environ) at import."""
    for node in import_time_nodes(ast.parse(source, path)):
        if isinstance(node, ast.Attribute) and node.attr in ("environ", "getenv", "environb"):
            yield node.lineno
        elif isinstance(node, ast.Name) and node.id in ("environ", "getenv"):
            yield node.lineno
        elif isinstance(node, ast.ImportFrom) and node.module == "os" and \
                any(alias.name in ("environ", "getenv") for alias in node.names):
            yield node.lineno


def is_simulator(rel):
    """sim/ (with its ROS side sim/ros_view.py) and the simulators' own nodes (nodes/sim_*.py)."""
    return rel.split(os.sep)[0] == "sim" or os.path.basename(rel).startswith("sim_")


def is_sim_import(module):
    return module == "inspection_robot.sim" or module.startswith("inspection_robot.sim.")


def python_files(top=SRC):
    for folder, _dirs, files in os.walk(top):
        for name in files:
            if name.endswith(".py"):
                path = os.path.join(folder, name)
                yield os.path.relpath(path, top), path


def is_ros_import(module, ros_names):
    top = module.split(".")[0]
    return (top in ros_names or top.endswith("_msgs") or top.endswith("_srvs")
            or module.startswith("inspection_robot.msg") or module.startswith("inspection_robot.srv"))


def test_declared_ros_packages_are_read():
    assert {"rospy", "actionlib", "diagnostic_updater", "std_msgs"} <= declared_ros_packages()


def test_only_the_ros_wing_imports_ros():
    names = ros_modules()
    offenders = []
    for rel, path in python_files():
        if is_ros_side(rel):
            continue
        tool = rel.split(os.sep)[0] == "tools"   # a command line may use the ROS wing, never ROS itself
        offenders.extend("%s imports %s" % (rel, module) for module in imported_modules(path)
                         if is_ros_import(module, names) or (is_ros_side_module(module) and not tool))
    assert offenders == []


def test_ros_side_modules_sit_beside_their_pure_ones():
    """A capability's ros_*.py shares its folder with pure modules (else the folder belongs in ros/)."""
    lonely = []
    for folder in sorted(os.listdir(SRC)):
        path = os.path.join(SRC, folder)
        if folder in ROS_WING or not os.path.isdir(path):
            continue
        modules = [n for n in os.listdir(path) if n.endswith(".py") and n != "__init__.py"]
        if any(n.startswith("ros_") for n in modules) and all(n.startswith("ros_") for n in modules):
            lonely.append(folder)
    assert lonely == []


def test_the_side_rule_names_ros_modules():
    assert is_ros_side(os.path.join("bridge", "ros_backend.py")) and is_ros_side(os.path.join("ros", "node.py"))
    assert not is_ros_side(os.path.join("bridge", "protocol.py")) and not is_ros_side("interface.py")
    assert is_ros_side_module("inspection_robot.task.ros_steps")
    assert not is_ros_side_module("inspection_robot.task.patrol") and not is_ros_side_module("numpy")


def test_only_the_harness_ros_wing_imports_ros():
    names = ros_modules()
    offenders = []
    for rel, path in python_files(HARNESS):
        if rel.split(os.sep)[0] != "ros":
            offenders.extend("%s imports %s" % (rel, module) for module in imported_modules(path)
                             if is_ros_import(module, names))
    assert offenders == []


def test_the_robot_never_imports_the_harness():
    sources = [path for _rel, path in python_files()]
    sources += [os.path.join(ROOT, folder, name) for folder in ("nodes", "tools")
                for name in os.listdir(os.path.join(ROOT, folder))]
    offenders = ["%s imports %s" % (os.path.relpath(path, ROOT), module) for path in sources
                 for module in imported_modules(path) if module.split(".")[0] == "inspection_robot_testing"]
    assert offenders == []


def test_setup_installs_the_package_without_the_harness():
    """setup.py (what catkin_python_setup installs) names every inspection_robot package and no other."""
    captured = {}
    fake = types.ModuleType("catkin_pkg.python_setup")
    fake.generate_distutils_setup = lambda **kwargs: kwargs
    with mock.patch.dict(sys.modules, {"catkin_pkg": types.ModuleType("catkin_pkg"),
                                       "catkin_pkg.python_setup": fake}), \
            mock.patch("setuptools.setup", side_effect=captured.update):
        cwd = os.getcwd()
        os.chdir(ROOT)
        try:
            runpy.run_path(os.path.join(ROOT, "setup.py"))
        finally:
            os.chdir(cwd)
    expected = {os.path.relpath(folder, os.path.join(ROOT, "src")).replace(os.sep, ".")
                for folder, _dirs, files in os.walk(SRC) if "__init__.py" in files}
    assert set(captured["packages"]) == expected
    assert "inspection_robot.sim" in expected and "inspection_robot_testing" not in expected


def test_the_rule_catches_a_leak():
    names = ros_modules()
    for module in ("genpy.message", "roslib.message", "rospkg", "sensor_msgs.msg", "tf2_ros",
                   "inspection_robot.msg", "std_srvs.srv"):
        assert is_ros_import(module, names), module
    for module in ("numpy", "cv2", "tornado.web", "inspection_robot.nav.planner"):
        assert not is_ros_import(module, names), module


def test_nodes_holds_one_module_per_node():
    """nodes/<name>.py exists exactly for the executables nodes/<name>: helpers live in ros/ or as ros_*.py."""
    modules = {os.path.splitext(name)[0] for name in os.listdir(os.path.join(SRC, "nodes"))
               if name.endswith(".py") and name != "__init__.py"}
    executables = set(os.listdir(os.path.join(ROOT, "nodes")))
    assert modules == executables


def test_every_executable_is_installed():
    with open(os.path.join(ROOT, "CMakeLists.txt")) as f:
        cmake = f.read()
    missing = ["%s/%s" % (folder, name) for folder in ("nodes", "tools")
               for name in sorted(os.listdir(os.path.join(ROOT, folder)))
               if "%s/%s\n" % (folder, name) not in cmake]
    assert missing == []


def test_tools_have_their_module():
    modules = {os.path.splitext(name)[0] for name in os.listdir(os.path.join(SRC, "tools"))
               if name.endswith(".py") and name != "__init__.py"}
    assert modules == set(os.listdir(os.path.join(ROOT, "tools")))


def test_every_module_has_a_docstring():
    missing = []
    for rel, path in list(python_files()) + list(python_files(HARNESS)):
        with open(path) as f:
            if ast.get_docstring(ast.parse(f.read())) is None:
                missing.append(rel)
    assert missing == []


def test_no_production_module_loads_a_simulator_when_imported():
    """A device node or tool imports its simulator inside the branch that chose it (drivers.py: the
    builder of ``~driver: sim``; calibrate_preset --from-world), so a robot never loads sim/."""
    offenders = []
    for rel, path in python_files():
        if is_simulator(rel):
            continue
        with open(path) as f:
            offenders.extend("%s imports %s" % (rel, module) for module in import_time_imports(f.read(), path)
                             if is_sim_import(module))
    assert offenders == []


def test_no_module_reads_the_environment_when_imported():
    """Configuration from the environment is read in a node's main() and passed in (bridge/trace.py's
    from_environment), never into module globals at import."""
    offenders = []
    for rel, path in python_files():
        with open(path) as f:
            offenders.extend("%s line %d" % (rel, line) for line in import_time_environment_reads(f.read(), path))
    assert offenders == []


def test_the_import_time_rules_catch_a_leak():
    leak = ("import os\nfrom inspection_robot.sim.world import World\nfrom inspection_robot import sim\n"
            "TOPIC = os.environ.get('X')\n"
            "class A(object):\n    import inspection_robot.sim.render\n    FILE = os.getenv('Y')\n"
            "try:\n    from os import environ\nexcept ImportError:\n    pass\n")
    assert {m for m in import_time_imports(leak) if is_sim_import(m)} == {
        "inspection_robot.sim.world", "inspection_robot.sim.world.World", "inspection_robot.sim",
        "inspection_robot.sim.render"}
    assert sorted(set(import_time_environment_reads(leak))) == [4, 7, 9]
    deferred = ("import os\n\ndef main(environ=None):\n    from inspection_robot.sim.world import World\n"
                "    return os.environ.get('X'), World\n")
    assert [m for m in import_time_imports(deferred) if is_sim_import(m)] == []
    assert list(import_time_environment_reads(deferred)) == []
    assert is_simulator(os.path.join("nodes", "sim_world.py")) and is_simulator(os.path.join("ros", "sim_view.py"))
    assert not is_simulator(os.path.join("tools", "calibrate_preset.py"))
