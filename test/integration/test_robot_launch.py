#!/usr/bin/env python3
"""rostest: the real robot's start-up refusals. robot.launch refuses simulators and unset drivers with
one message naming every setting to fix and the file that should hold it (check_drivers, a required
node); rosbridge_websocket refuses a non-loopback bind without authentication unless insecure."""
import os
import subprocess
import tempfile
import time
import unittest

import rostest

from inspection_robot.drivers import DEVICES

LAUNCH_TIMEOUT = 90.0  # s: roslaunch must have stopped by itself long before this


def run_robot_launch(*args):
    """roslaunch robot.launch on this test's master, in its own namespace; (exit code, output)."""
    cmd = ["roslaunch", "--disable-title", "inspection_robot", "robot.launch", "ns:=/robot_launch_test",
           "port:=0", "address:=127.0.0.1"] + list(args)
    proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=LAUNCH_TIMEOUT)
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
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)


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
    def assert_refused(self, output, count):
        self.assertIn("robot.launch refused to start, %d driver setting(s) to fix" % count, output)
        self.assertEqual(output.count("robot.launch refused to start"), 1, output[-4000:])
        self.assertIn("check_drivers", output)

    def test_no_robot_config_names_every_missing_driver_and_its_file(self):
        _code, output = run_robot_launch()
        self.assert_refused(output, len(DEVICES))
        for entry in DEVICES.values():
            self.assertIn("%s/driver is not set" % entry.node, output)
            self.assertIn(entry.config, output)

    def test_simulator_refused(self):
        drivers = {device: "none" for device in DEVICES}
        drivers["chassis"] = "sim"
        path = robot_config(drivers)
        try:
            _code, output = run_robot_launch("robot_config:=" + path)
        finally:
            os.unlink(path)
        self.assert_refused(output, 1)
        self.assertIn("robot_control/driver is sim: robot.launch drives real devices only", output)

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
            # Only cleanup: a loaded machine can take rospy more than 15 s to shut the bridge down.
            proc.terminate()
            try:
                proc.wait(LAUNCH_TIMEOUT)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_robot_launch", RobotLaunchTest)
