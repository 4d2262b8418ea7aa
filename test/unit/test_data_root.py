"""One robot, one state directory: node path parameters resolve under the data root, and the
launch gives every simulated robot (port, namespace) its own root."""
import os
import subprocess
import sys

import pytest

from inspection_robot.data_layout import DATA_SUBDIRS, standalone_data_root, under

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def test_relative_paths_go_under_the_root_absolute_ones_stay():
    assert under("/srv/r1", "nav/last_pose.json") == "/srv/r1/nav/last_pose.json"
    assert under("/srv/r1", "/tmp/x/y.json") == "/tmp/x/y.json"
    assert under("/srv/r1", "~/a") == os.path.join(os.path.expanduser("~"), "a")


def test_standalone_root_is_per_namespace():
    env = {"ROS_HOME": "/h"}
    assert standalone_data_root(env, "/") == "/h/inspection_robot/robot"
    assert standalone_data_root(env, "/robot_7/") == "/h/inspection_robot/robot_7"
    assert standalone_data_root(env, "/site/a/") == "/h/inspection_robot/site_a"


def test_deployment_doc_lists_every_sub_directory():
    text = open(os.path.join(ROOT, "docs", "deployment.md")).read()
    for sub in DATA_SUBDIRS:
        assert "`%s/" % sub in text, sub


def _data_root(*args):
    roslaunch = "/usr/bin/roslaunch"
    if not os.path.exists(roslaunch) or "ROS_PACKAGE_PATH" not in os.environ:
        pytest.skip("roslaunch not available (run through scripts/rosenv)")
    out = subprocess.run([sys.executable, roslaunch, "--dump-params", "inspection_robot"] + list(args),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=60, universal_newlines=True)
    assert out.returncode == 0, out.stderr
    lines = [line for line in out.stdout.splitlines() if line.split(":")[0].endswith("/data_root")]
    assert len(lines) == 1, out.stdout
    return lines[0].split(": ", 1)[1].strip()


def test_launch_gives_each_robot_its_own_root(monkeypatch):
    monkeypatch.setenv("ROS_HOME", "/h")
    roots = {_data_root("sim.launch", "port:=9091"), _data_root("sim.launch", "port:=9092"),
             _data_root("sim.launch", "port:=9091", "ns:=robot_7")}
    assert roots == {"/h/inspection_robot/sim_9091", "/h/inspection_robot/sim_9092",
                     "/h/inspection_robot/sim_robot_7_9091"}
    first, second = _data_root("sim.launch", "port:=0"), _data_root("sim.launch", "port:=0")
    assert first.startswith("/tmp/inspection_robot_data") and first != second
    # robot.launch = core.launch sim:=false after its site check (which needs a whole site file: test_check_site.py)
    assert _data_root("core.launch", "sim:=false") == "/var/lib/inspection_robot"
    assert _data_root("core.launch", "sim:=false", "data_root:=/srv/robot1") == "/srv/robot1"
