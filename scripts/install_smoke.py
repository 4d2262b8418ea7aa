#!/usr/bin/env python3
"""Runs the INSTALLED robot (scripts/check-install calls it with only the install space sourced):

1. the package, its Python modules and its version come from the install space, not the source tree;
   the test harness (inspection_robot_testing, the soak) is not there;
2. a site file with a misspelt key: robot.launch stops at parse time naming the key, no master, no node;
3. install-service --print makes the boot unit for a good site file; its ExecStart (the command
   systemd runs) starts robot.launch (chassis driver ros, other devices none, a map of its own),
   roslaunch starting its own master as at boot;
4. time from that start to a backend goal accepted: websocket connected and authenticated (the token,
   from the robot itself), move_action/status subscribed, a move goal published over the link and
   listed in move_action/status. Prints one JSON line with the figures; exit 1 on any failure.
"""
import argparse
import importlib.util
import json
import os
import shlex
import signal
import socket
import stat
import subprocess
import sys
import tempfile
import time

import numpy as np
import yaml
from tornado import gen, ioloop, websocket

import rospkg

TOKEN = "smoke-test-token-0123456789"
READY_TIMEOUT_S = 120.0


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def fail(message):
    sys.stderr.write("install_smoke: FAILED: %s\n" % message)
    sys.exit(1)


def check_installed(prefix):
    share = rospkg.RosPack().get_path("inspection_robot")
    if not share.startswith(prefix):
        fail("inspection_robot found at %s, not in the install space %s" % (share, prefix))
    import inspection_robot
    from inspection_robot.version import UNKNOWN, version
    if not os.path.realpath(inspection_robot.__file__).startswith(os.path.realpath(prefix)):
        fail("Python package from %s, not the install space" % inspection_robot.__file__)
    if version() == UNKNOWN:
        fail("no build version in the install space")
    harness = importlib.util.find_spec("inspection_robot_testing")
    if harness is not None:
        fail("the test harness is installed (%s)" % harness.origin)
    if os.path.exists(os.path.join(prefix, "lib", "inspection_robot", "soak")):
        fail("the soak is installed (%s/lib/inspection_robot/soak)" % prefix)
    return share, version()


def write_site(folder, port):
    """A good site file: its own 30 x 20 m map, poses on it, ros chassis, other devices not fitted."""
    from inspection_robot.nav.gridmap import GridMap, save_map
    occupancy = np.zeros((200, 300), dtype=np.int8)
    occupancy[80:120, 140:160] = 100
    save_map(GridMap(occupancy, 0.1, (0.0, 0.0, 0.0)), os.path.join(folder, "site_map.yaml"))
    token = os.path.join(folder, "token")
    with open(token, "w") as f:
        f.write(TOKEN + "\n")
    os.chmod(token, stat.S_IRUSR | stat.S_IWUSR)
    site = {
        "data_root": os.path.join(folder, "data"),
        "move_base": {"map_file": os.path.join(folder, "site_map.yaml"), "pose_topic": "amcl_pose",
                      "init_pose": [3.0, 3.0, 0.0]},
        "task_manager": {"home_pose": [3.0, 3.0, 0.0]},
        "charge_control": {"dock": {"pose": [1.5, 3.0, 3.1416], "approach_pose": [3.0, 3.0, 3.1416]}},
        "robot_control": {"driver": "ros", "ros_base": {"cmd_vel_topic": "base/cmd_vel", "odom_topic": "base/odom"}},
        "cloud_terrace": {"driver": "none"}, "robot_arm": {"driver": "none"}, "camera_node": {"driver": "none"},
        "infrared_imager": {"driver": "none"}, "obstacle_detector": {"driver": "none"},
        "rosbridge_websocket": {"auth_token_file": token, "port": port, "address": "127.0.0.1"},
        "bag_recorder": {"enabled": False},
    }
    path = os.path.join(folder, "robot.yaml")
    with open(path, "w") as f:
        yaml.safe_dump(site, f)
    return path, site


def check_typo_refused(folder, site, env):
    bad = dict(site, move_base=dict(site["move_base"], robot_radus=0.5))
    path = os.path.join(folder, "typo.yaml")
    with open(path, "w") as f:
        yaml.safe_dump(bad, f)
    started = time.monotonic()
    out = subprocess.run(["roslaunch", "--disable-title", "inspection_robot", "robot.launch", "robot_config:=" + path],
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=env, timeout=60,
                         universal_newlines=True)
    took = time.monotonic() - started
    if out.returncode == 0 or "move_base/robot_radus: unknown setting (did you mean move_base/robot_radius?)" \
            not in out.stdout:
        fail("a misspelt key was not refused by name:\n" + out.stdout[-3000:])
    if "started core service" in out.stdout or "process[" in out.stdout:
        fail("something started before the refusal:\n" + out.stdout[-3000:])
    return took


def exec_start(unit):
    for line in unit.splitlines():
        if line.startswith("ExecStart="):
            return shlex.split(line[len("ExecStart="):])
    fail("no ExecStart in the unit:\n" + unit)


@gen.coroutine
def wait_for_goal(port, deadline):
    """Seconds (monotonic) when the link answered and when the goal was listed in move_action/status."""
    url = "ws://127.0.0.1:%d/" % port
    while True:
        if time.monotonic() > deadline:
            raise RuntimeError("no websocket on %s before the deadline" % url)
        try:
            conn = yield websocket.websocket_connect(url)
            break
        except (OSError, websocket.WebSocketClosedError, Exception):  # not listening yet
            yield gen.sleep(0.1)
    connected = time.monotonic()
    conn.write_message(json.dumps({"op": "auth", "mac": TOKEN, "client": "backend", "dest": "robot", "rand": "",
                                   "t": 0, "level": "", "end": 0}))
    conn.write_message(json.dumps({"op": "subscribe", "topic": "move_action/status",
                                   "type": "actionlib_msgs/GoalStatusArray"}))
    goal = {"header": {}, "goal_id": {"id": "install_smoke"},
            "goal": {"sender": "server", "receiver": "", "trans_id": 1, "type": "move",
                     "data": json.dumps({"goal_pose": {"position": {"x": 10.0, "y": 3.0, "z": 0},
                                                       "orientation": {"x": 0, "y": 0, "z": 0, "w": 1}},
                                         "with_direction": 1, "precision": 0})}}
    sent = False
    while time.monotonic() < deadline:
        message = yield conn.read_message()
        if message is None:
            raise RuntimeError("the link closed")
        data = json.loads(message)
        if data.get("op") == "status" and data.get("level") == "error":
            raise RuntimeError("the link refused: %s" % data)
        if data.get("op") != "publish":
            continue
        if not sent:   # move_action's server is up: send the goal as a backend does
            conn.write_message(json.dumps({"op": "advertise", "topic": "move_action/goal",
                                           "type": "inspection_robot/GeneralActionGoal"}))
            conn.write_message(json.dumps({"op": "publish", "topic": "move_action/goal", "msg": goal}))
            sent = time.monotonic()
        if any(s["goal_id"]["id"] == "install_smoke" for s in data["msg"]["status_list"]):
            conn.close()
            return connected, sent, time.monotonic()
    raise RuntimeError("the goal never appeared in move_action/status")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("prefix", help="the install space")
    args = parser.parse_args()
    prefix = os.path.realpath(args.prefix)
    _share, version = check_installed(prefix)
    folder = tempfile.mkdtemp(prefix="inspection_robot_install_")
    port = free_port()
    site_path, site = write_site(folder, port)
    env = dict(os.environ, ROS_MASTER_URI="http://127.0.0.1:%d" % free_port(), ROS_HOME=os.path.join(folder, "ros"))
    typo_s = check_typo_refused(folder, site, env)
    unit = subprocess.run([os.path.join(prefix, "lib", "inspection_robot", "install-service"), "--print",
                           "--site", site_path, "--ros-home", env["ROS_HOME"]],
                          stdout=subprocess.PIPE, universal_newlines=True, env=env, check=True).stdout
    command = exec_start(unit)
    if os.path.join(prefix, "setup.bash") not in " ".join(command):
        fail("the unit does not start the install space:\n" + unit)
    started = time.monotonic()
    proc = subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            start_new_session=True)
    try:
        connected, sent, accepted = ioloop.IOLoop.current().run_sync(
            lambda: wait_for_goal(port, started + READY_TIMEOUT_S), timeout=READY_TIMEOUT_S + 5)
    except Exception as err:  # boundary: report what roslaunch said
        os.killpg(proc.pid, signal.SIGINT)
        output = proc.communicate(timeout=60)[0].decode("utf-8", "replace")
        fail("%s\n%s" % (err, output[-4000:]))
    os.killpg(proc.pid, signal.SIGINT)
    try:
        proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
    print(json.dumps({"check": "install_smoke", "version": version, "typo_refused_s": round(typo_s, 2),
                      "start_to_link_s": round(connected - started, 2),
                      "start_to_move_action_s": round(sent - started, 2),
                      "start_to_goal_accepted_s": round(accepted - started, 2)}))


if __name__ == "__main__":
    main()
