"""The ROS side of motion.owners: a received safety input is admitted only from its owner's caller id.

One gate per node (robot_control, move_base, charge_control): it reads the caller id through
compat_rospy, counts a refusal and warns about it at most every REFUSAL_LOG_PERIOD s per input, the
caller id named, so a spoofing client neither moves the robot nor floods the log.
"""
import threading
import time

import rospy

from inspection_robot.motion.owners import OwnerCheck
from inspection_robot.ros.compat_rospy import caller_id
from inspection_robot.ros.data_root import startup_files

REFUSAL_LOG_PERIOD = 5.0  # s between two warnings about one refused input (each one counts)


class OwnerGate(object):
    def __init__(self, node_name, owners=None, namespace=None):
        self.node_name = node_name
        self.check = OwnerCheck(rospy.get_namespace() if namespace is None else namespace, owners)
        self._lock = threading.Lock()
        self._logged = {}   # owner key -> time.monotonic() of its last warning

    @classmethod
    def from_param(cls, node_name):
        """The gate of a node with the ``~owners`` setting ({key: node name} over the defaults). Under
        core.launch it is fixed at launch like the security settings (ros/data_root.startup_files: the
        defaults file, the site file, the command line), so a parameter written later and a respawn
        cannot make a client an owner; a node a test starts on its own reads the parameter."""
        files = startup_files()
        if files.launched:
            return cls(node_name, files.get("owners", {}) or {})
        return cls(node_name, rospy.get_param("~owners", {}))

    def refusal(self, topic, key, msg):
        """None when ``msg`` (received on ``topic``) may act; otherwise why not (already warned and counted)."""
        caller = caller_id(msg)
        if self.check.allows(key, caller):
            return None
        reason = self.check.refusal(key, caller)
        now = time.monotonic()
        with self._lock:
            due = now - self._logged.get(key, -REFUSAL_LOG_PERIOD) >= REFUSAL_LOG_PERIOD
            if due:
                self._logged[key] = now
        if due:
            rospy.logwarn("%s: %s: %s (%d refused so far)" % (self.node_name, topic, reason, self.check.refused()[key]))
        return reason

    def describe(self):
        """One line for the start-up log: whose message counts for each input."""
        return ", ".join("%s: %s" % item for item in sorted(self.check.owners.items()))
