"""bag_recorder: records the robot's interface topics with rosbag into split bags under a disk budget.

Runs rosbag's ``record`` executable as a child process (recording.recorder builds its command
line): every interface topic by name (interface.INTERFACE_TOPICS, subscribed at its start, so nothing
a backend sends in its first second is lost), split every ~split_size_mb, lz4
compressed, latched topics (map, virtual obstacles, plan...) repeated at the start of every split.
Every ~check_period it deletes the oldest closed bags until the folder fits ~budget_mb (never the
bag being written) and checks the free space: below ~min_free_mb it stops the recorder cleanly
(SIGINT: the bag is closed and indexed) and reports ERROR on diagnostics; it starts again once
twice that space is free. A recorder that dies is restarted (at most every ~check_period).

Records:     <image topic>/compressed of each ~image_topics (sensor_msgs/CompressedImage, JPEG, as the camera
             or thermal node publishes it, at its ~image_rate) only when ~record_images
Publishes:   diagnostics (diagnostic_msgs/DiagnosticArray, hardware_id "bag_recorder")
Parameters:  config/bag_recorder.yaml: every setting, its default and meaning (read through ros.node.NodeSettings);
             data_root (namespace: this robot's state directory, ros.data_root)
"""
import os
import shutil
import signal
import subprocess
import threading

import roslib.packages
import rospy

from inspection_robot.recording.recorder import RecorderError, disk_verdict, enforce_budget, list_bags, record_command
from inspection_robot.ros.data_root import data_root
from inspection_robot.ros.diagnostics import DeviceDiagnostics
from inspection_robot.ros.node import NodeSettings, init_node

HARDWARE_ID = "bag_recorder"
MB = 1000 * 1000
STOP_TIMEOUT_S = 15.0


class BagRecorder(object):
    def __init__(self, argv, directory, budget_bytes, min_free_bytes, check_period, diagnostics):
        self._argv = argv
        self._dir = directory
        self._budget = budget_bytes
        self._min_free = min_free_bytes
        self._diag = diagnostics
        self._child = None
        self._disk_full = None   # reason while stopped for lack of space
        self._problem = None
        self._lock = threading.Lock()   # a check (timer thread) and the shutdown never interleave
        self._closed = False
        self._timer = rospy.Timer(rospy.Duration(check_period), self._on_timer)

    def begin(self):
        """Check the folder, the budget and the disk, then record unless the disk is already full."""
        self.check()

    def close(self):
        """Node shutdown: stop the recorder (bag closed and indexed); no later check starts it again."""
        with self._lock:
            self._closed = True
            self.stop()

    def start(self):
        rospy.loginfo("bag_recorder: recording into %s", self._dir)
        self._child = subprocess.Popen(self._argv, start_new_session=True)

    def stop(self):
        child, self._child = self._child, None
        if child is None or child.poll() is not None:
            return
        child.send_signal(signal.SIGINT)   # rosbag closes and indexes the bag on SIGINT
        try:
            child.wait(STOP_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            rospy.logerr("bag_recorder: recorder did not stop within %.0f s; killed (bag left .active)"
                         % STOP_TIMEOUT_S)
            child.kill()
            child.wait()

    def _on_timer(self, _event):
        try:
            self.check()
        except Exception as exc:  # boundary: a timer tick never kills the node
            rospy.logerr_throttle(30.0, "bag_recorder: check failed: %r" % (exc,))

    def check(self):
        with self._lock:
            if not self._closed:
                self._check()

    def _check(self):
        try:
            os.makedirs(self._dir, exist_ok=True)
        except OSError as exc:   # e.g. a read-only or unmounted data disk: report, try again next check
            reason = "cannot create the bag directory %s: %s; not recording" % (self._dir, exc.strerror or exc)
            rospy.logerr_throttle(60.0, "bag_recorder: %s" % reason)
            self.stop()
            self._diag.publish(False, reason, [("directory", self._dir)])
            return
        deleted, errors = enforce_budget(self._dir, self._budget)
        for path in deleted:
            rospy.loginfo("bag_recorder: budget %.0f MB reached, deleted %s", self._budget / MB, path)
        for error in errors:
            rospy.logwarn_throttle(60.0, "bag_recorder: %s" % error)
        try:
            free = shutil.disk_usage(self._dir).free
        except OSError as exc:
            free = 0
            self._problem = "cannot read free space of %s: %s" % (self._dir, exc)
        reason = disk_verdict(free, self._min_free)
        if reason:
            if self._disk_full is None:
                rospy.logerr("bag_recorder: %s on %s; recording stopped", reason, self._dir)
            self.stop()
            self._disk_full = reason
        elif self._disk_full and free >= 2 * self._min_free:
            rospy.loginfo("bag_recorder: %.0f MB free again on %s; recording resumes", free / MB, self._dir)
            self._disk_full = None
            self.start()
        elif not self._disk_full and self._child is None:
            self.start()
        elif not self._disk_full and self._child.poll() is not None:
            self._problem = "recorder exited with status %s; restarted" % self._child.returncode
            rospy.logerr("bag_recorder: %s", self._problem)
            self.start()
        self._report(free, errors)

    def _report(self, free, errors):
        bags = list_bags(self._dir)
        active = [os.path.basename(b[0]) for b in bags if b[3]]
        values = [("directory", self._dir), ("bags", len(bags)),
                  ("total_mb", "%.1f" % (sum(b[1] for b in bags) / MB)), ("budget_mb", "%.0f" % (self._budget / MB)),
                  ("free_mb", "%.0f" % (free / MB)), ("min_free_mb", "%.0f" % (self._min_free / MB)),
                  ("recording", active[0] if active else "")]
        if self._disk_full:
            self._diag.publish(False, self._disk_full + "; recording stopped", values)
        elif errors or self._problem:
            self._diag.publish(False, (errors + [self._problem])[0] if errors else self._problem, values)
            self._problem = None
        else:
            self._diag.publish(True, "recording", values)


def main():
    init_node("bag_recorder")
    settings = NodeSettings("bag_recorder")
    if not settings.get("~enabled"):
        rospy.loginfo("bag_recorder: ~enabled is false; not recording")
        DeviceDiagnostics("bag recorder", HARDWARE_ID).publish(True, "disabled (~enabled false)", [])
        rospy.spin()
        return
    directory = settings.path("~directory", data_root())
    prefix = settings.get("~prefix")
    split_mb = float(settings.get("~split_size_mb"))
    budget_mb = float(settings.get("~budget_mb"))
    min_free_mb = float(settings.get("~min_free_mb"))
    check_period = float(settings.get("~check_period"))
    record_images = bool(settings.get("~record_images"))
    image_topics = list(settings.get("~image_topics")) if record_images else []
    extra = list(settings.get("~extra_topics"))
    if budget_mb < 2 * split_mb or check_period <= 0:
        raise RecorderError("need ~budget_mb >= 2 * ~split_size_mb and ~check_period > 0 (got %s, %s, %s)"
                            % (budget_mb, split_mb, check_period))
    found = roslib.packages.find_node("rosbag", "record")
    if not found:
        raise RecorderError("rosbag's record executable not found (install python3-rosbag / ros-noetic-rosbag)")
    namespace = rospy.get_namespace()
    argv = record_command(directory, prefix, namespace, split_mb, min_free_mb, image_topics, extra, found[0])
    recorder = BagRecorder(argv, directory, budget_mb * MB, min_free_mb * MB, check_period,
                           DeviceDiagnostics("bag recorder", HARDWARE_ID))
    rospy.on_shutdown(recorder.close)
    recorder.begin()
    rospy.spin()
