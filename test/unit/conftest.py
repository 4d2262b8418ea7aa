"""Unit tests also run under Noetic's Python 3.8 + NumPy 1.17 / OpenCV 4.2 / SciPy 1.3 from PyPI
(scripts/test_noetic), where no ROS exists: a test module that imports ROS (rospy, genpy, message
packages, the package's generated msg/srv) cannot run there and is skipped, named in the header.
Everything else must run."""
import importlib.util
import os
import re

from hypothesis import settings

# Hypothesis' default 200 ms deadline per example is a wall-clock limit: a fresh-clone run's Noetic
# unit tests, beside the rostest suites, took 341 ms for one Pelco round trip and failed
# (test_standard_tilt_round_trips). Speed targets live in benchmarks; examples have no deadline.
settings.register_profile("no_deadline", deadline=None)
settings.load_profile("no_deadline")

ROS_IMPORT = re.compile(r"^\s*(?:import|from)\s+(rospy|genpy|roslib|rosgraph|rosservice|rostest|actionlib|tf2_ros|"
                        r"diagnostic_updater|\w+_msgs|inspection_robot\.(?:msg|srv|ros)\b|"
                        r"inspection_robot\.\w+\.ros_\w+|inspection_robot\.\w+\s+import\s+ros_\w+|"
                        r"inspection_robot_testing\.ros\b)", re.M)


def _ros_available():
    return importlib.util.find_spec("genpy") is not None and importlib.util.find_spec("rospy") is not None


LOCAL_IMPORT = re.compile(r"^\s*(?:import|from)\s+(\w+)", re.M)
HERE = os.path.dirname(os.path.abspath(__file__))


def _ros_import(name, seen=()):
    """The ROS module ``name``.py (or a helper module beside it that it imports) imports, or None."""
    with open(os.path.join(HERE, name)) as f:
        text = f.read()
    found = ROS_IMPORT.search(text)
    if found:
        return found.group(1)
    for helper in LOCAL_IMPORT.findall(text):
        if helper + ".py" in os.listdir(HERE) and helper not in seen:
            found = _ros_import(helper + ".py", seen + (helper,))
            if found:
                return "%s via %s" % (found, helper)
    return None


collect_ignore = []
skipped_reasons = []
if not _ros_available():
    for module in sorted(os.listdir(HERE)):
        if module.endswith(".py") and module != "conftest.py":
            ros = _ros_import(module)
            if ros:
                collect_ignore.append(module)
                skipped_reasons.append("%s (imports %s)" % (module, ros))


def pytest_terminal_summary(terminalreporter):
    if skipped_reasons:
        terminalreporter.write_line("SKIPPED, no ROS in this Python (%d test modules): %s"
                                    % (len(skipped_reasons), ", ".join(skipped_reasons)))
