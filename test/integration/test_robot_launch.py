#!/usr/bin/env python3
"""rostest: the real robot's start-up refusals. robot.launch's site check (tools/check_site, run while
roslaunch parses the file) refuses a missing site file, simulators, unset drivers and misspelt keys
with one message naming every setting, before any node starts; a site file switches pose_adapter on
(and is refused when move_base would not read it); rosbridge_websocket refuses a
non-loopback bind without authentication unless insecure."""
import os
import signal
import subprocess
import tempfile
import time
import unittest

import rostest
import yaml

from inspection_robot.drivers import DEVICES
from inspection_robot_testing.site_files import template_site

LAUNCH_TIMEOUT = 90.0  # s: roslaunch must have stopped by itself long before this
STOP_TIMEOUT = 20.0    # s for a node to stop on SIGINT (2 s unloaded)
PARSE_TIME_S = 20.0    # s: the refusal comes from the parse (~2 s), not from a node that had to start


def run_robot_launch(*args):
    """roslaunch robot.launch on this test's master, in its own namespace; (exit code, output)."""
    cmd = ["roslaunch", "--disable-title", "inspection_robot", "robot.launch", "ns:=/robot_launch_test",
           "port:=0", "address:=127.0.0.1"] + list(args)
    started = time.monotonic()
    proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=LAUNCH_TIMEOUT)
    return proc.returncode, proc.stdout.decode("utf-8", "replace"), time.monotonic() - started


def parse_robot_launch(option, *args):
    """roslaunch ``option`` (--nodes, --dump-params) of robot.launch: the parse, site check included, and
    nothing started; (exit code, output)."""
    proc = subprocess.run(["roslaunch", option, "inspection_robot", "robot.launch", "ns:=/robot_launch_test"]
                          + list(args), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=LAUNCH_TIMEOUT)
    return proc.returncode, proc.stdout.decode("utf-8", "replace")


def robot_config(drivers):
    """A robot_config file setting <node>/driver for each {device: driver}."""
    handle, path = tempfile.mkstemp(suffix=".yaml")
    with os.fdopen(handle, "w") as f:
        for device, spec in drivers.items():
            f.write("%s: {driver: %s}\n" % (DEVICES[device].node, spec))
    return path


def run_bridge(name, *params):
    """rosbridge_websocket ``name`` (its own private parameters) with ``params`` (``_param:=value``)."""
    return subprocess.Popen(["rosrun", "inspection_robot", "rosbridge_websocket", "__ns:=/bridge_refusal_test",
                             "__name:=" + name, "_port:=0"] + list(params),
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True)


def refusal_of(name, *params):
    proc = run_bridge(name, *params)
    try:
        output, _ = proc.communicate(timeout=LAUNCH_TIMEOUT)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return proc.returncode, output.decode("utf-8", "replace")


class RobotLaunchTest(unittest.TestCase):
    def assert_refused(self, result, count):
        code, output, took = result
        self.assertNotEqual(code, 0, output[-4000:])
        self.assertIn("robot.launch refused to start, %d site setting(s) to fix" % count, output)
        self.assertEqual(output.count("robot.launch refused to start"), 1, output[-4000:])
        self.assertIn("Cannot load command parameter [site_check]", output)   # roslaunch stopped while parsing
        self.assertNotIn("process[", output)                                  # ... so no node started
        self.assertLess(took, PARSE_TIME_S, output[-4000:])

    def test_no_robot_config_names_every_missing_setting(self):
        result = run_robot_launch()
        self.assert_refused(result, len(DEVICES) + 8)
        for entry in DEVICES.values():
            self.assertIn("%s/driver is not set" % entry.node, result[1])
        for name in ("robot_config", "move_base/map_file", "move_base/pose_topic", "charge_control/dock",
                     "task_manager/home_pose", "data_root", "rosbridge_websocket/auth_token_file"):
            self.assertIn("%s is not set" % name, result[1])

    def test_simulator_and_misspelt_key_refused(self):
        drivers = {device: "none" for device in DEVICES}
        drivers["chassis"] = "sim"
        path = robot_config(drivers)
        with open(path, "a") as f:
            f.write("move_base: {robot_radus: 0.5}\n")
        try:
            result = run_robot_launch("robot_config:=" + path, "data_root:=/tmp/robot_launch_test", "insecure:=true")
        finally:
            os.unlink(path)
        self.assert_refused(result, 7)
        self.assertIn("robot_control/driver is sim: robot.launch drives real devices only", result[1])
        self.assertIn("move_base/robot_radus: unknown setting (did you mean move_base/robot_radius?)", result[1])

    def test_pose_adapter_started_from_the_site_file_and_checked(self):
        """A TF-only localizer: the site file switches pose_adapter on and move_base reads its output;
        an adapter move_base would not read is refused by name before anything starts."""
        with tempfile.TemporaryDirectory() as folder:
            site = template_site(folder)
            site["pose_adapter"] = {"mode": "tf", "base_frame": "base_footprint"}
            site["move_base"]["pose_topic"] = "localization/pose"
            path = os.path.join(folder, "robot.yaml")
            with open(path, "w") as f:
                yaml.safe_dump(site, f)
            code, output = parse_robot_launch("--nodes", "robot_config:=" + path)
            self.assertEqual(code, 0, output[-4000:])
            self.assertIn("/robot_launch_test/pose_adapter", output.split())
            code, output = parse_robot_launch("--dump-params", "robot_config:=" + path)
            self.assertEqual(code, 0, output[-4000:])
            params = yaml.safe_load(output)
            self.assertEqual((params["/robot_launch_test/pose_adapter/mode"],
                              params["/robot_launch_test/pose_adapter/base_frame"],
                              params["/robot_launch_test/pose_adapter/output_topic"],
                              params["/robot_launch_test/move_base/pose_topic"]),
                             ("tf", "base_footprint", "localization/pose", "localization/pose"))
            site["move_base"]["pose_topic"] = "amcl_pose"
            with open(path, "w") as f:
                yaml.safe_dump(site, f)
            result = run_robot_launch("robot_config:=" + path)
        self.assert_refused(result, 1)
        self.assertIn("move_base/pose_topic is 'amcl_pose' but pose_adapter/mode is tf: move_base must read the "
                      "adapter's output, set move_base/pose_topic: localization/pose", result[1])

    def test_bridge_gets_the_cpu_first_on_the_robot_unless_the_site_file_says_otherwise(self):
        """robot.launch gives the bridge niceness -10 (the link's echo tail during a patrol,
        docs/development.md "Niceness and autogroup scheduling"); the site file, loaded after it, can change that."""
        with tempfile.TemporaryDirectory() as folder:
            site = template_site(folder)
            path = os.path.join(folder, "robot.yaml")
            niceness = []
            for bridge in (None, {"nice": 0}):
                if bridge is not None:
                    site["rosbridge_websocket"] = dict(site.get("rosbridge_websocket", {}), **bridge)
                with open(path, "w") as f:
                    yaml.safe_dump(site, f)
                code, output = parse_robot_launch("--dump-params", "robot_config:=" + path)
                self.assertEqual(code, 0, output[-4000:])
                niceness.append(yaml.safe_load(output)["/robot_launch_test/rosbridge_websocket/nice"])
        self.assertEqual(niceness, [-10, 0])

    def test_bridge_refuses_open_bind_without_auth(self):
        code, output = refusal_of("open_bridge", "_address:=0.0.0.0")
        self.assertNotEqual(code, 0)
        self.assertIn("refusing to listen on 0.0.0.0 without authentication: set ~auth_token_file", output)

    def test_bridge_refuses_token_file_others_can_read(self):
        handle, path = tempfile.mkstemp()
        os.write(handle, b"s3cret\n")
        os.close(handle)
        os.chmod(path, 0o644)
        try:
            code, output = refusal_of("shared_token_bridge", "_address:=0.0.0.0", "_auth_token_file:=" + path)
        finally:
            os.unlink(path)
        self.assertNotEqual(code, 0)
        self.assertIn("is accessible by group/others (mode 644): chmod 600 it", output)

    def test_bridge_insecure_starts_and_warns(self):
        proc = run_bridge("insecure_bridge", "_address:=0.0.0.0", "_insecure:=true")
        deadline = time.monotonic() + LAUNCH_TIMEOUT
        seen = []
        try:
            for line in iter(proc.stdout.readline, b""):
                seen.append(line.decode("utf-8", "replace"))
                if "INSECURE: the backend link listens on 0.0.0.0 without authentication" in seen[-1]:
                    break
                self.assertLess(time.monotonic(), deadline, "".join(seen))
            self.assertIn("INSECURE", seen[-1] if seen else "", "".join(seen))
            self.assertIsNone(proc.poll())
        finally:
            # Only cleanup. SIGINT to the whole group (rosrun's shell and the node, as roslaunch stops
            # nodes): SIGTERM reached only rosrun's shell and left the node holding the pipe (90 s).
            os.killpg(proc.pid, signal.SIGINT)
            try:
                proc.wait(STOP_TIMEOUT)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_robot_launch", RobotLaunchTest)
