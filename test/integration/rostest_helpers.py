"""Shared helpers for the rostest scripts: waiting for conditions with a deadline, never sleeping blind."""
import itertools
import math
import os
import signal
import socket
import subprocess
import threading
import time
import xmlrpc.client

import rosgraph
import rospy
from geometry_msgs.msg import PoseWithCovarianceStamped

from inspection_robot.angles import wrap_angle, yaw_from_quaternion
from inspection_robot.msg import GeneralAck, GeneralCmd
from inspection_robot.ros import compat_rospy
from inspection_robot.srv import ControlService

# the tests' own nodes (rospy.init_node in each test) get the nodes' repair of rospy's lost
# publisher list too (ros/node.init_node; compat_rospy.merge_publisher_updates says why)
compat_rospy.merge_publisher_updates()


def wait_for(condition, timeout, message="condition", period=0.01):
    """Return as soon as ``condition()`` is truthy; fail the test after ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and not rospy.is_shutdown():
        value = condition()
        if value:
            return value
        time.sleep(period)
    raise AssertionError("timed out after %.1f s waiting for %s" % (timeout, message))


def rosapi_names(getter):
    """``getter()`` (a roslibpy Ros.get_services / get_topics), or [] when rosapi did not answer
    within roslibpy's own 3 s (a loaded machine): a wait_for condition that asks again."""
    import roslibpy   # the test venv's; rospy-only suites never call this
    try:
        return getter()
    except roslibpy.core.RosTimeoutError:
        return []


class _ShortTransport(xmlrpc.client.Transport):
    """XML-RPC with a 2 s socket timeout (a node that stopped answering must not hang a test's set-up)."""

    def make_connection(self, host):
        connection = super(_ShortTransport, self).make_connection(host)
        connection.timeout = 2.0
        return connection


def outbound_connections(master, node):
    """{(subscriber, topic)} of the connections ``node`` publishes on, from its getBusInfo (slave
    API): what its publishers have added, not only what subscribers count; None when it does not answer."""
    try:
        code, _, info = xmlrpc.client.ServerProxy(master.lookupNode(node),
                                                  transport=_ShortTransport()).getBusInfo(master.caller_id)
    except (rosgraph.MasterError, OSError, xmlrpc.client.Error):
        return None
    return {(c[1], c[4]) for c in info if c[2] == "o"} if code == 1 else None


class Latest(object):
    """Subscribes to a topic and keeps every message (and the latest) for assertions."""

    def __init__(self, topic, msg_type, queue_size=100):
        self.messages = []
        self._lock = threading.Lock()
        self._sub = rospy.Subscriber(topic, msg_type, self._on_msg, queue_size=queue_size)

    def _on_msg(self, msg):
        with self._lock:
            self.messages.append((time.monotonic(), msg))

    @property
    def last(self):
        with self._lock:
            return self.messages[-1][1] if self.messages else None

    def clear(self):
        with self._lock:
            del self.messages[:]

    def wait(self, predicate=lambda msg: True, timeout=5.0, what="message"):
        """Wait for a message (received from now on or already the latest) that satisfies predicate."""
        return wait_for(lambda: self.last is not None and predicate(self.last) and self.last,
                        timeout, what)

    def wait_any(self, predicate, timeout=5.0, what="message"):
        """Wait for any message kept so far or from now on that satisfies predicate (e.g. the ack of one
        trans_id): unlike wait, one reply among a stream of others is not missed between two polls."""
        def found():
            with self._lock:
                return next((msg for _t, msg in reversed(self.messages) if predicate(msg)), None)
        return wait_for(found, timeout, what)

    def wait_connected(self, timeout=5.0):
        """Until a publisher is connected and every publisher of the topic has added this node.

        A subscriber counts its connection once it has read the publisher's header, before the
        publisher adds the connection to its list: what it publishes in between (the ack of a
        test's first request) is lost. A publisher's getBusInfo (slave API) lists its connections.
        """
        wait_for(lambda: self._sub.get_num_connections() > 0, timeout, "publisher of " + self._sub.name)
        wait_for(self._publishers_added_me, timeout, "publishers of %s to add this subscriber" % self._sub.name)

    def _publishers_added_me(self):
        me = rospy.get_name()
        master = rosgraph.Master(me)
        topic = self._sub.resolved_name
        for node in next((nodes for name, nodes in master.getSystemState()[0] if name == topic), []):
            connections = outbound_connections(master, node)
            # None: gone or not answering, it publishes nothing to wait for
            if connections is not None and (me, topic) not in connections:
                return False
        return True

    def handshake(self, send, predicate, timeout=10.0, period=0.5):
        """Repeat ``send()`` until a reply satisfying ``predicate`` arrives.

        A subscriber counts its connection before the publisher has added it, so the first reply
        after wait_connected can still be lost; one confirmed round trip closes that window.
        """
        deadline = time.monotonic() + timeout
        while True:
            send()
            try:
                return self.wait(predicate, min(period, max(deadline - time.monotonic(), 0.01)), "handshake")
            except AssertionError:
                if time.monotonic() >= deadline:
                    raise AssertionError("no reply on %s within %.1f s" % (self._sub.name, timeout))


# The localizer's pose agrees with ground truth within this many standard deviations of sim_localizer's
# noise (a 2-D gaussian error exceeds 5 sigma once in ~270000 poses), and never less than the floor.
AGREE_SIGMAS = 5.0
AGREE_FLOOR = (0.002, 0.002)   # m, rad: float32 and rounding on the way through nav_status


def planar_pose(pose):
    """(x, y, yaw) of a geometry_msgs/Pose."""
    q = pose.orientation
    return pose.position.x, pose.position.y, yaw_from_quaternion(q.x, q.y, q.z, q.w)


def pose_error(a, b):
    """(distance m, |heading difference| rad) between two (x, y, yaw)."""
    return math.hypot(a[0] - b[0], a[1] - b[1]), abs(wrap_angle(a[2] - b[2]))


def localizer_tolerance():
    """(m, rad) within which the robot's reported pose (nav_status, robot_status: the localizer's)
    agrees with ground truth: AGREE_SIGMAS of the running sim_localizer's noise (its parameters), the
    floor when move_base drives on ground truth (no sim_localizer)."""
    sigma_xy = float(rospy.get_param("sim_localizer/sigma_xy", 0.0))
    sigma_yaw = float(rospy.get_param("sim_localizer/sigma_yaw", 0.0))
    return max(AGREE_SIGMAS * sigma_xy, AGREE_FLOOR[0]), max(AGREE_SIGMAS * sigma_yaw, AGREE_FLOOR[1])


class GroundTruth(Latest):
    """Where the simulated robot really is: the chassis simulator's sim/true_pose. A test asserting that
    the robot *is* somewhere (arrived, docked, did not move) reads this; nav_status and robot_status carry
    what the robot *reports*, the localizer's pose (in simulation sim_localizer's noisy copy of this one,
    docs/interface.md "Simulated localizer")."""

    def __init__(self, queue_size=100):
        super(GroundTruth, self).__init__("sim/true_pose", PoseWithCovarianceStamped, queue_size)

    def pose(self, timeout=10.0):
        """The latest (x, y, yaw), waiting up to ``timeout`` for the first one."""
        return planar_pose(self.wait(timeout=timeout, what="sim/true_pose").pose.pose)

    def wait_at(self, pose, tol_m, tol_rad=None, timeout=10.0):
        """Wait until the robot is within ``tol_m`` (and ``tol_rad`` of heading, unless None) of (x, y, yaw)."""
        def there(msg):
            distance, heading = pose_error(planar_pose(msg.pose.pose), pose)
            return distance < tol_m and (tol_rad is None or heading < tol_rad)
        return planar_pose(self.wait(there, timeout, "the robot within %.3f m of %s" % (tol_m, tuple(pose)))
                           .pose.pose)

    def wait_still(self, window_s=0.3, tol_m=0.001, tol_rad=math.radians(0.05), timeout=10.0):
        """The pose once the robot has moved less than ``tol_m`` / ``tol_rad`` for ``window_s`` (a goal
        ends while the final turn may still be braking)."""
        def still():
            with self._lock:
                recent = list(self.messages[-200:])
            if not recent:
                return None
            now_t, now = recent[-1][0], planar_pose(recent[-1][1].pose.pose)
            old = [planar_pose(m.pose.pose) for t, m in recent if t <= now_t - window_s]
            if old:
                distance, heading = pose_error(now, old[-1])
                if distance < tol_m and heading < tol_rad:
                    return now
            return None
        return wait_for(still, timeout, "the robot at rest (sim/true_pose)", period=0.05)


def set_pose_when_at_rest(inject, pose, sender="rostest", timeout=10.0):
    """Teleport the simulated chassis with ``sim/inject_fault set_pose`` (``inject`` is its service proxy).

    robot_control refuses set_pose while the chassis still moves (a goal, or a back-off from the
    dock, may just have ended), so the request is repeated until it is accepted.
    """
    replies = []
    wait_for(lambda: replies.append(inject(sender=sender, cmd="set_pose", data="%.4f,%.4f,%.5f" % tuple(pose)))
             or replies[-1].ack == "success", timeout, "set_pose %s accepted" % (tuple(pose),), period=0.1)


def control_proxy(name, timeout=30.0, persistent=False):
    """A ControlService proxy once the service is offered (fails the test after ``timeout``)."""
    rospy.wait_for_service(name, timeout)
    return rospy.ServiceProxy(name, ControlService, persistent=persistent)


def wait_subscribed(publisher, timeout=5.0):
    wait_for(lambda: publisher.get_num_connections() > 0, timeout, "subscriber of " + publisher.name)


_TRANS_IDS = itertools.count(1000)


class TwinClient(object):
    """Reaches one device node through both twins: its ControlService and its cmd/ack topics.

    Every request gets a fresh trans_id; the reply must echo it (and, on the topic, be
    addressed back to the sender and signed by ``node``).
    """

    def __init__(self, service, cmd_topic, ack_topic, node, timeout=10.0):
        self.proxy = control_proxy(service, timeout)
        self.node = node
        self.acks = Latest(ack_topic, GeneralAck, queue_size=200)
        self.publisher = rospy.Publisher(cmd_topic, GeneralCmd, queue_size=10)
        wait_subscribed(self.publisher, timeout)
        self.acks.wait_connected(timeout)
        ping_id = next(_TRANS_IDS)
        self.acks.handshake(lambda: self.publisher.publish(GeneralCmd(sender="rostest", cmd="ping", trans_id=ping_id)),
                            lambda m: m.trans_id == ping_id, timeout)

    def call(self, cmd, data="", sender="server"):
        """Service twin: returns the ControlService response."""
        trans_id = next(_TRANS_IDS)
        reply = self.proxy(sender=sender, cmd=cmd, data=data, trans_id=trans_id)
        if reply.trans_id != trans_id:
            raise AssertionError("%s: trans_id %d echoed as %d" % (cmd, trans_id, reply.trans_id))
        return reply

    def topic(self, cmd, data="", sender="server", timeout=10.0):
        """Topic twin: publishes the command and returns its GeneralAck."""
        trans_id = next(_TRANS_IDS)
        self.publisher.publish(GeneralCmd(sender=sender, cmd=cmd, data=data, trans_id=trans_id))
        ack = self.acks.wait(lambda m: m.trans_id == trans_id, timeout, "ack %d of %s" % (trans_id, cmd))
        if (ack.receiver, ack.sender) != (sender, self.node):
            raise AssertionError("ack of %s addressed %r from %r" % (cmd, ack.receiver, ack.sender))
        return ack

    def both(self):
        """(name, callable) for the service twin and the topic twin; both return .ack/.data."""
        return (("service", self.call), ("topic", self.topic))


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def replay_bag(bag, out, log_path, at_end="hold", timeout=300.0):
    """Plays ``bag`` with replay.launch (no bridge, paused until status_control and a capture are
    subscribed) on a second ROS master and records the replayed robot_status into ``out``.

    ``at_end`` hold: waits until the player has gone, then stops the launch; exit: waits for the
    launch to end by itself. Returns the launch's exit status (None when this helper stopped it);
    its output is in ``log_path``."""
    port = free_port()
    env = dict(os.environ, ROS_MASTER_URI="http://127.0.0.1:%d" % port)
    # our own master, which outlives the launch: the capture below must close its bag while the
    # master still answers (a launch that ends by itself would take its master along)
    core = subprocess.Popen(["rosmaster", "--core", "-p", str(port)], env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.STDOUT, start_new_session=True)
    launch = capture = code = None
    try:
        master = rosgraph.Master("/replay_probe", master_uri=env["ROS_MASTER_URI"])

        def graph():
            try:
                return master.getSystemState()
            except (socket.error, OSError, rosgraph.MasterException):
                return None
        wait_for(graph, 60.0, "replay master")
        with open(log_path, "wb") as log:
            launch = subprocess.Popen(["roslaunch", "inspection_robot", "replay.launch", "bag:=" + bag, "bridge:=false",
                                       "pause:=true", "at_end:=" + at_end, "delay:=0.5"],
                                      env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        capture = subprocess.Popen(["rosbag", "record", "-O", out, "/robot_status", "__name:=replay_capture"],
                                   env=env, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)

        def subscribed(topic, node):
            state = graph()
            return state and any(t == topic and node in nodes for t, nodes in state[1])
        wait_for(lambda: all(subscribed(t, n) for t, n in (
            ("/control_status", "/status_control"), ("/nav_status", "/status_control"),
            ("/robot_odom", "/status_control"), ("/recorded/server_status", "/status_control"),
            ("/robot_status", "/replay_capture"))), 60.0, "replay nodes subscribed")
        subprocess.check_call(["rosservice", "call", "/replay_player/pause_playback", "false"], env=env,
                              stdout=subprocess.DEVNULL, timeout=30)
        if at_end == "exit":
            code = wait_for(lambda: launch.poll() is not None and (launch.returncode,), timeout,
                            "the replay to end by itself", period=0.5)[0]
        else:
            def player_done():
                state = graph()
                return state and not any("/replay_player" in nodes for _t, nodes in state[0])
            wait_for(player_done, timeout, "the end of the replay", period=0.5)
    finally:
        for proc in (capture, launch, core):
            if proc is not None and proc.poll() is None:
                proc.send_signal(signal.SIGINT)
                try:
                    proc.wait(30)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()
    return code
