#!/usr/bin/env python3
"""Benchmark of robot_control (simulated chassis): prints one JSON line per figure.

- move_cmd_to_driver: a move_cmd published -> the command reaching the driver (sim/chassis_cmd
  stamp, taken inside robot_control when the driver is called), p50/p99 over 1000 commands.
- safety_stop: obstacle_status=true published while moving -> zero velocity at the driver.
- robot_control_cpu_idle / robot_control_cpu_50hz: CPU time of the robot_control process per
  wall second (percent of one core), idle and with a 50 Hz move_cmd stream.

Starts its own roscore (free port) and robot_control; runs in ~30 s. Run inside scripts/rosenv.
"""
import os
import subprocess
import sys
import threading
import time

from benchlib import latency_figures, report, start_roscore  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EVENTS = 1000
CPU_WINDOW = 5.0  # s


def report_latencies(name, latencies_s):
    report(bench=name, **latency_figures(latencies_s))


def cpu_seconds(pid):
    with open("/proc/%d/stat" % pid) as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / float(os.sysconf("SC_CLK_TCK"))


class Echo(object):
    """Collects sim/chassis_cmd and wakes a waiter when a matching command arrives."""

    def __init__(self):
        self.cond = threading.Condition()
        self.predicate = None
        self.match = None

    def on_msg(self, msg):
        with self.cond:
            if self.predicate is not None and self.match is None and self.predicate(msg):
                self.match = msg
                self.cond.notify()

    def expect(self, predicate):
        with self.cond:
            self.predicate, self.match = predicate, None

    def wait(self, timeout=1.0):
        with self.cond:
            self.cond.wait_for(lambda: self.match is not None, timeout)
            match, self.predicate = self.match, None
            return match


def main():
    os.environ["ROS_HOSTNAME"] = "127.0.0.1"
    procs = [start_roscore()]   # sets ROS_MASTER_URI for this process and its children
    env = dict(os.environ)
    try:
        subprocess.check_call(["rosparam", "load", os.path.join(ROOT, "config", "robot_control.yaml"),
                               "/robot_control"], env=env)
        subprocess.check_call(["rosparam", "set", "/robot_control/driver", "sim"], env=env)
        subprocess.check_call(["rosparam", "set", "/robot_control/sim", "{max_accel_x: 10.0, max_accel_yaw: 10.0}"],
                              env=env)
        node = subprocess.Popen([sys.executable, "-c", "from inspection_robot.nodes.robot_control import main; main()",
                                 "__name:=robot_control"], env=env, stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL)
        procs.append(node)
        run(node.pid)
    finally:
        for proc in reversed(procs):
            proc.terminate()
            try:
                proc.wait(10.0)
            except subprocess.TimeoutExpired:
                proc.kill()


def run(pid):
    import rospy
    from geometry_msgs.msg import TwistStamped

    from inspection_robot.msg import ControlStatus, MoveCmd, ObstacleStatus

    rospy.init_node("bench_motion", disable_signals=True)
    echo = Echo()
    status = {"stop": None}
    status_cond = threading.Condition()

    def on_status(msg):
        with status_cond:
            status["stop"] = msg.stop_status
            status_cond.notify_all()

    rospy.Subscriber("sim/chassis_cmd", TwistStamped, echo.on_msg, queue_size=100, tcp_nodelay=True)
    rospy.Subscriber("control_status", ControlStatus, on_status, queue_size=100, tcp_nodelay=True)
    move = rospy.Publisher("move_cmd", MoveCmd, queue_size=100, tcp_nodelay=True)
    obstacle = rospy.Publisher("obstacle_status", ObstacleStatus, queue_size=10, tcp_nodelay=True)
    deadline = time.monotonic() + 20.0
    while (move.get_num_connections() == 0 or obstacle.get_num_connections() == 0 or status["stop"] is None) \
            and time.monotonic() < deadline:
        time.sleep(0.05)

    # CPU idle first (nothing published)
    c0, t0 = cpu_seconds(pid), time.monotonic()
    time.sleep(CPU_WINDOW)
    idle = (cpu_seconds(pid) - c0) / (time.monotonic() - t0)

    # move_cmd -> driver
    latencies = []
    for k in range(1, EVENTS + 1):
        value = k % 900 + 50  # 0.05 .. 0.949 m/s, never the same twice in a row
        echo.expect(lambda m, v=value: abs(m.twist.linear.x - v / 1000.0) < 1e-9)
        sent = rospy.get_time()
        move.publish(MoveCmd(sender="move_base", velocity_x=value))
        msg = echo.wait()
        if msg is not None:
            latencies.append(msg.header.stamp.to_sec() - sent)
    report_latencies("move_cmd_to_driver", latencies)

    # obstacle -> zero velocity at the driver
    stops = []
    for _ in range(EVENTS):
        echo.expect(lambda m: abs(m.twist.linear.x - 0.5) < 1e-9)
        move.publish(MoveCmd(sender="move_base", velocity_x=500))
        if echo.wait() is None:
            continue
        echo.expect(lambda m: m.twist.linear.x == 0.0)
        sent = rospy.get_time()
        obstacle.publish(ObstacleStatus(obstacle=True))
        msg = echo.wait()
        if msg is not None:
            stops.append(msg.header.stamp.to_sec() - sent)
        with status_cond:  # the alarm must be seen before clearing it, or the next move may meet it
            status_cond.wait_for(lambda: status["stop"] != 0, 1.0)
        obstacle.publish(ObstacleStatus(obstacle=False))
        with status_cond:
            status_cond.wait_for(lambda: status["stop"] == 0, 1.0)
    report_latencies("safety_stop", stops)

    # CPU at a 50 Hz move_cmd stream
    rate = rospy.Rate(50)
    c0, t0 = cpu_seconds(pid), time.monotonic()
    while time.monotonic() - t0 < CPU_WINDOW:
        move.publish(MoveCmd(sender="move_base", velocity_x=300))
        rate.sleep()
    busy = (cpu_seconds(pid) - c0) / (time.monotonic() - t0)
    report(bench="robot_control_cpu_idle", cpu_percent=round(idle * 100, 1))
    report(bench="robot_control_cpu_50hz", cpu_percent=round(busy * 100, 1))
    rospy.signal_shutdown("done")


if __name__ == "__main__":
    main()
