#!/usr/bin/env python3
"""rostest: robot.launch refuses to start on simulators or unset drivers, with one message naming
every setting to fix and the file that should hold it (check_drivers, a required node)."""
import os
import subprocess
import tempfile
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


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_robot_launch", RobotLaunchTest)
