"""What the chaos soak watches on the ROS side: every command reaching the chassis driver
(sim/chassis_cmd) and robot_status, fed to the motion checker under one lock; node pids and
interfaces from the master; resident memory from /proc, sampled into the liveness and memory checkers.

Apart from the patrol loop (ros/soak.py) and the faults (ros/soak_faults.py), which both ask it:
the observations and the bounds they are judged by (the control cycle, a topic's allowance) read
on their own. NODE_NAME is the soak's node name, under which it asks the master.
"""
import threading
import time
from xmlrpc.client import ServerProxy

import rosgraph
import rospy
from geometry_msgs.msg import TwistStamped

from inspection_robot.interface import STOP_OBSTACLE
from inspection_robot.msg import RobotStatus

NODE_NAME = "soak"
CYCLE = 0.02            # s, robot_control's control cycle (config/robot_control.yaml rate 50 Hz)
TOPIC_ALLOWANCE = 0.05  # s a ROS topic may take from its stamp to robot_control on a loaded machine


class Observer(object):
    """ROS side: driver commands and robot_status into the motion checker; node pids and RSS."""

    def __init__(self, motion, liveness, memory):
        self.motion = motion
        self.liveness = liveness
        self.memory = memory
        self.lock = threading.Lock()
        self.offline = None
        self.session = None   # the heartbeat session robot_status names
        self.mode = None
        self.expect_offline_stop = False
        self.stop_status = 0
        self.hold_obstacle = False   # a box is ahead: every robot_status must carry the obstacle bit
        self.obstacle_lifted = 0
        rospy.Subscriber("sim/chassis_cmd", TwistStamped, self._on_command, queue_size=1000)
        rospy.Subscriber("robot_status", RobotStatus, self._on_status, queue_size=100)
        self.nodes = []

    def _on_command(self, msg):
        with self.lock:
            self.motion.command(msg.header.stamp.to_sec(), msg.twist.linear.x, msg.twist.angular.z)

    def _on_status(self, msg):
        with self.lock:
            offline = msg.offline_warn != 0
            if offline and not self.offline and self.expect_offline_stop:
                t = msg.header.stamp.to_sec()
                self.motion.stop_cause(t, t + TOPIC_ALLOWANCE + CYCLE, "heartbeat lost (offline_warn)")
            self.offline = offline
            self.session = msg.trans_id
            self.stop_status = msg.stop_status
            if self.hold_obstacle and not msg.stop_status & STOP_OBSTACLE:
                self.obstacle_lifted += 1   # a robot_status without the obstacle bit while the box is there

    def authorise(self):
        with self.lock:
            self.motion.authorise(time.time())

    def stop_cause(self, t_cause, t_deadline, cause):
        with self.lock:
            self.motion.stop_cause(t_cause, t_deadline, cause)

    def pid(self, node):
        try:  # a Master (an XML-RPC proxy) per call: the sampler and the soak thread both ask
            return ServerProxy(rosgraph.Master("/" + NODE_NAME).lookupNode(node)).getPid("/" + NODE_NAME)[2]
        except (rosgraph.MasterError, OSError):
            return None

    def interface(self, node):
        """{(kind, name)} of the topics and services ``node`` has registered with the master."""
        try:
            state = rosgraph.Master("/" + NODE_NAME).getSystemState()
        except (rosgraph.MasterError, OSError):
            return set()
        return {(kind, name) for kind, entries in zip(("pub", "sub", "srv"), state)
                for name, nodes in entries if node in nodes}

    def sample(self):
        now = time.time()
        for node in self.nodes:
            pid = self.pid(node)
            rss = _rss(pid) if pid else None
            if rss is None:
                self.liveness.missing(now, node)
            else:
                self.liveness.seen(now, node, pid)
                self.memory.sample(now, node, pid, rss)
        with self.lock:
            self.motion.tick(now)


def _rss(pid):
    try:
        with open("/proc/%d/status" % pid) as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        return None
    return None
