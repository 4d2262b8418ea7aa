"""status_control: heartbeat and robot_status (INTERFACE.md section 4, "Heartbeat").

Subscribes:  server_status (GeneralTopic) heartbeat from the backend
             control_status (ControlStatus), nav_status (NavStatus), robot_odom (nav_msgs/Odometry)
             diagnostics (diagnostic_msgs/DiagnosticArray): sensor alarms by hardware_id
Publishes:   robot_status (RobotStatus) at ~rate and at once on any change; its header names the
                 heartbeat session keeping the robot online: trans_id and receiver = the latest
                 server_status's trans_id and sender (0 and "" while offline; a session change alone
                 at once at most once per 1/~rate s: status.merge.PublishGate)
             diagnostics (diagnostic_updater, 1 Hz): hardware_id "robot", status "status_control: software"
                 with the version (git describe of the build, inspection_robot.version) and the site check
Parameters:  config/status_control.yaml: every setting, its default and meaning (read through
             ros.node.NodeSettings); site_check (namespace, written by robot.launch's site check: shown on
             diagnostics)
"""
import threading

import diagnostic_updater
import rospy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from nav_msgs.msg import Odometry

from inspection_robot.msg import ControlStatus, GeneralTopic, NavStatus, RobotStatus
from inspection_robot.ros.node import NodeSettings, init_node
from inspection_robot.version import version
from inspection_robot.status.merge import (CONTROL_FIELDS, Heartbeat, PublishGate, StatusMerger,
                                           heartbeat_text_problem)


class SoftwareStatus(diagnostic_updater.DiagnosticTask):
    """Which software runs: the build's version and what robot.launch's site check said (OK always:
    a robot that runs has passed it)."""

    def __init__(self, software_version, site_check):
        diagnostic_updater.DiagnosticTask.__init__(self, "status_control: software")
        self._values = (("version", software_version), ("site_check", site_check or "none (sim.launch)"))

    def run(self, stat):
        stat.summary(DiagnosticStatus.OK, "version %s" % self._values[0][1])
        for key, value in self._values:
            stat.add(key, value)
        return stat


class StatusControl(object):
    def __init__(self, merger, rate_hz, sensor_hardware_bits):
        self._merger = merger
        self._sensor_bits = dict(sensor_hardware_bits)
        self._gate = PublishGate(1.0 / rate_hz)
        # rospy runs each subscription's callbacks (and the timer) on its own thread: a status built
        # before another input's but published after it would put an old value on the wire
        # (offline_warn back on after the first heartbeat), so one input is merged and published at a time
        self._lock = threading.Lock()
        self._pub = rospy.Publisher("robot_status", RobotStatus, queue_size=10)
        rospy.Subscriber("server_status", GeneralTopic, self._on_server_status, queue_size=10)
        rospy.Subscriber("control_status", ControlStatus, self._on_control_status, queue_size=10)
        rospy.Subscriber("nav_status", NavStatus, self._on_nav_status, queue_size=10)
        rospy.Subscriber("robot_odom", Odometry, self._on_odom, queue_size=10)
        rospy.Subscriber("diagnostics", DiagnosticArray, self._on_diagnostics, queue_size=10)
        self._timer = rospy.Timer(rospy.Duration(1.0 / rate_hz), self._on_timer)

    @staticmethod
    def _now():
        """ROS time in seconds (the bag's clock during a replay), or None before the first /clock.

        Every timeout (heartbeat, staleness) is measured on this clock, never the wall clock. Under
        use_sim_time rospy says 0 until /clock arrives: an input then would be stamped 0 and read as
        decades old at the first tick (offline_warn flickering on at the start of a replay), so it
        is dropped.
        """
        now = rospy.get_time()
        if now == 0:
            rospy.logwarn_throttle(5.0, "status_control: no /clock yet (use_sim_time); input ignored")
            return None
        return now

    def _on_server_status(self, msg):
        problem = heartbeat_text_problem(msg.sender, msg.receiver, msg.data)
        if problem:
            rospy.logwarn_throttle(5.0, "server_status from %r malformed (%s); counted as heartbeat"
                                   % (msg.sender[:40], problem))
        self._merge(lambda now: self._merger.heartbeat.beat(now, msg.sender, msg.trans_id))

    def _on_control_status(self, msg):
        fields = {name: getattr(msg, name) for name in ("mode",) + CONTROL_FIELDS}

        def update(now):
            for problem in self._merger.update_control(now, fields):
                rospy.logwarn_throttle(5.0, "control_status: %s; padded/truncated" % problem)
        self._merge(update)

    def _on_nav_status(self, msg):
        def update(now):
            for problem in self._merger.update_nav(now, msg.nav_warn, msg.position, msg.orientation):
                rospy.logwarn_throttle(5.0, "nav_status: %s; keeping the last valid pose" % problem)
        self._merge(update)

    def _on_odom(self, msg):
        twist = msg.twist.twist
        self._merge(lambda now: self._merger.update_odometry(now, twist.linear.x, twist.angular.z))

    def _on_diagnostics(self, msg):
        def update(_now):
            for status in msg.status:
                bit = self._sensor_bits.get(status.hardware_id)
                if bit is not None:
                    self._merger.set_sensor_bit(1 << int(bit), status.level >= DiagnosticStatus.ERROR)
        self._merge(update)

    def _on_timer(self, _event):
        with self._lock:
            now = self._now()
            if now is not None:
                self._publish(now, self._merger.robot_status(now), self._merger.heartbeat.session(now))

    def _merge(self, update):
        """``update(now)`` applied to the merger, then robot_status published if it changed."""
        with self._lock:
            now = self._now()
            if now is None:
                return
            update(now)
            self._publish_if_changed(now)

    def _publish_if_changed(self, now):
        status = self._merger.robot_status(now)
        session = self._merger.heartbeat.session(now)
        if self._gate.due(now, status, session):
            self._publish(now, status, session)

    def _publish(self, now, status, session):
        self._gate.sent(now, status, session)
        msg = RobotStatus(sender="status_control", receiver=session[0], trans_id=session[1], **status)
        msg.header.stamp = rospy.Time.now()
        self._pub.publish(msg)


def main():
    init_node("status_control")
    settings = NodeSettings("status_control")
    timeout = float(settings.get("~heartbeat_timeout"))
    rate_hz = float(settings.get("~rate"))
    stale = {k: float(v) for k, v in settings.get("~stale_timeout").items()}
    sensor_bits = settings.get("~sensor_hardware_bits")
    if rate_hz <= 0 or timeout <= 0 or any(v <= 0 for v in stale.values()):
        raise ValueError("~rate, ~heartbeat_timeout and every ~stale_timeout must be positive")
    StatusControl(StatusMerger(Heartbeat(timeout), stale), rate_hz, sensor_bits)
    updater = diagnostic_updater.Updater()
    updater.setHardwareID("robot")
    updater.add(SoftwareStatus(version(), str(rospy.get_param("site_check", "")).strip()))
    rospy.Timer(rospy.Duration(1.0), lambda _event: updater.update())
    rospy.loginfo("status_control: version %s" % version())
    rospy.spin()
