"""soak: a chaos soak of the simulated robot, seen from the backend (scripts/soak starts sim.launch).

A patrol-like loop drives the robot over the websocket the way a backend does (heartbeat, backend
control, move_cmd, PTZ, captures, thermal readings, virtual obstacles) while random faults are
injected: the serial head unplugged and back, the camera answering 401 / timing out (camera_node runs
the real ISAPI driver against a fake ISAPI camera served here, --isapi-port), a node killed (SIGKILL;
roslaunch respawns it; respawned = a new process registered with the master with every topic and
service the node had before), the backend link dropped and back, the heartbeat stopped during backend
control, a backend that disconnects while holding control and a new one that acquires at once (it
must keep control past the old heartbeat's expiry), a hard e-stop during motion, 100 websocket
clients plus one client that never reads, file_server killed while a second backend connection
calls file_control without pause, a spoofing client claiming the obstacle detector's clear and the
joystick's acquire while a box stops the robot.
Invariants (inspection_robot_testing.soak_invariants) are checked all along from ROS-side
observations: every command reaching the chassis driver (sim/chassis_cmd), robot_status, node pids
and resident memory (/proc), what the camera answers during its faults. Prints the table of faults
and invariants; exit status 0 only when every invariant was exercised and held.

Its command line is inspection_robot_testing/soak.py; this module is its ROS side (rospy, rosnode,
the message classes).
"""
import base64
import json
import math
import os
import random
import signal
import socket
import sys
import threading
import time
from collections import OrderedDict
from xmlrpc.client import ServerProxy

import rosgraph
import rosnode
import rospy
from geometry_msgs.msg import PoseWithCovarianceStamped, TwistStamped

from inspection_robot.interface import (ACK_FAILED, ACK_SUCCESS, MODE_CMD_ACQUIRE, MODE_NAMES, MODE_SERVER,
                                        SENDER_SERVER, STOP_OBSTACLE)
from inspection_robot.msg import ControlStatus, ObstacleStatus, RobotStatus
from inspection_robot.srv import ControlService
from inspection_robot_testing.bridge_client import RawClient
from inspection_robot_testing.fake_isapi import FakeIsapiCamera
from inspection_robot_testing.soak_invariants import (Availability, CallsAcrossRestart, ControlKept, FaultReasons,
                                                      Ledger, MemoryGrowth, MotionAuthority, NodeLiveness,
                                                      SpoofsRefused, held, table)

NODE_NAME = "soak"
CYCLE = 0.02            # s, robot_control's control cycle (config/robot_control.yaml rate 50 Hz)
TOPIC_ALLOWANCE = 0.05  # s a ROS topic may take from its stamp to robot_control on a loaded machine
KILLABLE = ("/cloud_terrace", "/camera_node", "/infrared_imager", "/status_control", "/move_base",
            "/obstacle_detector", "/robot_voice", "/preset_scale", "/find_scale", "/read_scale", "/robot_arm")
VO = "virtual obstacle"
ISAPI_USER, ISAPI_PASSWORD = "admin", "soak"   # launch/include/camera.launch, camera_isapi_url
HEARTBEAT_TIMEOUT = 3.0  # s, status_control's (config/status_control.yaml)
RECONNECT = "backend reconnecting, the new one acquiring at once"
SPOOF = "spoofed obstacle clear and joystick acquire while a box stops the robot"
RETRY_PAUSE = 0.02   # s a calling backend waits after a failed call before the next (kill_called_node)
SPOOF_BOX_M = 1.0   # m ahead and behind the robot: whichever way the backend drives, the box is in the way
CAMERA_FAULT_REASONS = {"401": ["refused the credentials (HTTP 401"], "timeout": ["unreachable", "timed out"]}


class Backend(object):
    """The backend's websocket session: publish, call services, a heartbeat thread. Each connection
    beats under a session number of its own (docs/interface.md, "Heartbeat and status", **Sessions**)."""

    def __init__(self, port, rng):
        self._rng = rng
        self.session = 0
        self._url = "ws://127.0.0.1:%d" % port
        self._lock = threading.Lock()
        self._ids = 0
        self._heartbeat = None
        self.client = None
        self.connect()

    def connect(self):
        self.client = RawClient(self._url, timeout=20.0)
        self.session = self._rng.randint(1, 2 ** 32 - 1)
        for topic, msg_type in (("/server_status", "inspection_robot/GeneralTopic"),
                                ("/mode_cmd", "inspection_robot/GeneralCmd"),
                                ("/move_cmd", "inspection_robot/MoveCmd")):
            self.client.send({"op": "advertise", "topic": topic, "type": msg_type})

    def close(self):
        self.stop_heartbeat()
        self.client.close()

    def publish(self, topic, msg):
        self.client.send({"op": "publish", "topic": topic, "msg": msg})

    def call(self, service, cmd, data="", timeout=30.0):
        with self._lock:
            self._ids += 1
            call_id = "soak%d" % self._ids
            self.client.send({"op": "call_service", "id": call_id, "service": service,
                              "args": {"sender": SENDER_SERVER, "trans_id": self._ids, "cmd": cmd, "data": data}})
            reply = self.client.recv_message(lambda m: m.get("op") == "service_response" and m.get("id") == call_id,
                                             timeout)
        if not reply.get("result"):
            return "error", str(reply.get("values"))
        return reply["values"]["ack"], reply["values"]["data"]

    def start_heartbeat(self, period=0.3):
        self.stop_heartbeat()
        stop = threading.Event()

        def beat():
            while not stop.wait(period):
                self.publish("/server_status", {"sender": SENDER_SERVER, "trans_id": self.session, "data": ""})
        thread = threading.Thread(target=beat, name="soak_heartbeat")
        thread.daemon = True
        thread.start()
        self._heartbeat = (stop, thread)

    def stop_heartbeat(self):
        if self._heartbeat is not None:
            self._heartbeat[0].set()
            self._heartbeat[1].join(2.0)
            self._heartbeat = None

    def drive(self, velocity_mm_s, seconds):
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.publish("/move_cmd", {"sender": SENDER_SERVER, "velocity_x": velocity_mm_s, "velocity_yaw": 0.0,
                                       "wheel_control": 0})
            time.sleep(0.05)  # the backend's command rate (20 Hz)


def silent_client(port, topic, msg_type):
    """A websocket client that subscribes to ``topic`` and never reads (tiny receive buffer)."""
    sock = socket.create_connection(("127.0.0.1", port), timeout=10.0)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall(("GET / HTTP/1.1\r\nHost: 127.0.0.1:%d\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                  "Sec-WebSocket-Key: %s\r\nSec-WebSocket-Version: 13\r\n\r\n" % (port, key)).encode())
    sock.recv(1024)  # the 101 answer; nothing is read after this
    payload = json.dumps({"op": "subscribe", "topic": topic, "type": msg_type}).encode()
    mask = os.urandom(4)
    header = bytes([0x81, 0x80 | len(payload)]) if len(payload) < 126 else \
        bytes([0x81, 0x80 | 126]) + len(payload).to_bytes(2, "big")
    sock.sendall(header + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(payload)))
    return sock


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


def _node_process(node):
    """Pids of processes started as ``node`` (roslaunch passes __name:=<name>)."""
    tag = ("__name:=" + node.rsplit("/", 1)[-1]).encode()
    pids = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open("/proc/%s/cmdline" % entry, "rb") as f:
                    if tag in f.read().split(b"\0"):
                        pids.append(int(entry))
            except OSError:
                continue   # gone meanwhile
    return pids


def _cpu_seconds(pid):
    """User + system CPU seconds ``pid`` has used so far (/proc/<pid>/stat), None if it is gone."""
    try:
        with open("/proc/%d/stat" % pid) as f:
            fields = f.read().rsplit(")", 1)[1].split()
    except (OSError, TypeError):
        return None
    return (int(fields[11]) + int(fields[12])) / float(os.sysconf("SC_CLK_TCK"))


def _rss(pid):
    try:
        with open("/proc/%d/status" % pid) as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        return None
    return None


class Soak(object):
    def __init__(self, backend, observer, checkers, rng, port, camera=None, only=()):
        self.b = backend
        self.o = observer
        self.ledger = checkers["ledger"]
        self.availability = checkers["availability"]
        self.liveness = checkers["liveness"]
        self.reasons = checkers["reasons"]
        self.restart_calls = checkers["restart_calls"]
        self.kept = checkers["kept"]
        self.spoofs = checkers["spoofs"]
        self.rng = rng
        self.port = port
        self.camera = camera
        self.faults = OrderedDict((name, 0) for name in (
            "head unplugged and back", "camera answering 401", "camera timing out",
            "node killed (SIGKILL), respawned", "backend link dropped and back",
            "heartbeat stopped during backend control", RECONNECT, "hard e-stop during motion",
            "100 websocket clients + 1 that never reads", "service node killed during a stream of calls",
            SPOOF)
            if (camera is not None or not name.startswith("camera"))
            and (not only or any(word in name for word in only)))
        self.respawn_times = []   # (node, {"process": s, "registered": s, "ready": s} after the kill)
        self.loops = 0
        self._captures = 0
        self._round = []
        self._direction = 1
        rospy.wait_for_service("sim/inject_fault", 60.0)
        self.inject = rospy.ServiceProxy("sim/inject_fault", ControlService)
        self.head = rospy.ServiceProxy("sim_pelco_head/sim_control", ControlService)
        self.yard = rospy.ServiceProxy("sim_obstacle_control", ControlService)
        # a ROS node that is not obstacle_detector claiming its clear (spoof_safety_inputs)
        self.spoof_pub = rospy.Publisher("obstacle_status", ObstacleStatus, queue_size=10)

    def wait(self, condition, timeout, what):
        return _wait(condition, timeout, what, period=0.05)

    def take_control(self, acquire_first=False):
        """Beat, wait for robot_status to answer this connection's heartbeat, acquire (trans_id = the
        session) until granted; ``acquire_first``: acquire even when mode 1 is already in force."""
        self.b.start_heartbeat()
        self.wait(lambda: self.o.offline is False and self.o.session == self.b.session, 30.0,
                  "robot online on our heartbeat")
        if acquire_first:
            self.acquire()
        # robot_control hears robot_status on its own: it may still take the link as offline for a
        # moment and refuse (mode_ack "offline: ..."), so ask again each second until granted.
        asked = [0.0]

        def granted():
            if self.mode() == 1:
                return True
            if time.monotonic() - asked[0] >= 1.0:
                asked[0] = time.monotonic()
                self.acquire()
            return False
        self.wait(granted, 15.0, "backend mode")
        self.o.authorise()

    def acquire(self):
        self.b.publish("/mode_cmd", {"sender": SENDER_SERVER, "trans_id": self.b.session, "cmd": MODE_CMD_ACQUIRE,
                                     "data": MODE_NAMES[MODE_SERVER]})

    def mode(self):
        return self.o.mode

    # --- the patrol ---------------------------------------------------------------------------
    def patrol(self):
        """One patrol step: drive, point the head, capture, read a temperature, store an obstacle.
        A device may still be coming back from the last fault: each answers within 15 s."""
        self.loops += 1
        if self.mode() != 1 or self.o.offline:
            self.take_control()
        self._direction = -self._direction
        self.b.drive(300.0 * self._direction, 1.0)
        target = "%d,%d" % (self.rng.randrange(-17000, 17000, 100), self.rng.randrange(-3000, 3000, 100))
        self.check(lambda: self.b.call("/terrace_control", "set_angle", target)[0] == ACK_SUCCESS
                   and self.b.call("/terrace_control", "get_angle") == (ACK_SUCCESS, target), "PTZ set/get angle")
        self.check(lambda: self.capture("soak")[0] == ACK_SUCCESS, "camera capture")
        self.check(lambda: self.b.call("/infrared_control", "get_max_temperature")[0] == ACK_SUCCESS,
                   "thermal reading")
        self.virtual_obstacles()

    def capture(self, what):
        """capture_picture to a fresh name (captures are never replaced) under the data root's
        captures/soak/; the picture is removed once taken, so a long soak does not fill the disk."""
        self._captures += 1
        ack, data = self.b.call("/camera_control", "capture_picture", "soak/%s_%d.jpg" % (what, self._captures))
        if ack == ACK_SUCCESS:
            try:
                os.unlink(data)   # the answer is the absolute path written (the soak runs on the robot)
            except OSError:
                pass
        return ack, data

    def check(self, request, what):
        self.availability.recovered("patrol loop %d: %s" % (self.loops, what), self.time_until(request, 15.0))

    def virtual_obstacles(self):
        key = "soak%d" % (self.loops % 10)
        points = [[40.0 + self.loops % 10, 40.0], [40.5 + self.loops % 10, 40.0 + 0.1 * self.rng.randrange(10)]]
        self.b.call_topic_vo("delete", json.dumps({"id": key}))
        self.ledger.removed(VO, key)
        ack, _ = self.b.call_topic_vo("add", json.dumps({"id": key, "points": points}))
        if ack == ACK_SUCCESS:
            self.ledger.stored(VO, key, points)
        ack, data = self.b.call_topic_vo("query", "")
        if ack == ACK_SUCCESS:
            self.ledger.listed(VO, {o["id"]: o["points"] for o in json.loads(data) if o["id"].startswith("soak")})

    def warm_up(self):
        """Before memory is measured: look all round once (the renderer's texture cache fills to
        its bound for the views the patrol will see), so growth after warm-up means a leak."""
        for tilt in (-2000, 0, 2000):
            for pan in range(-18000, 18000, 3000):
                self.b.call("/terrace_control", "set_angle", "%d,%d" % (pan, tilt))
                self.capture("soak_warmup")

    # --- the faults ---------------------------------------------------------------------------
    def fault(self):
        """The next fault: every kind once per round, in a random order each round."""
        if not self._round:
            self._round = list(self.faults)
            self.rng.shuffle(self._round)
        name = self._round.pop()
        self.faults[name] += 1
        {"head unplugged and back": self.head_unplug,
         "camera answering 401": lambda: self.camera_fault("401"),
         "camera timing out": lambda: self.camera_fault("timeout"),
         "node killed (SIGKILL), respawned": self.kill_node,
         "backend link dropped and back": self.drop_link,
         "heartbeat stopped during backend control": self.stop_heartbeat,
         RECONNECT: self.reconnect,
         "hard e-stop during motion": self.estop,
         "100 websocket clients + 1 that never reads": self.many_clients,
         "service node killed during a stream of calls": self.kill_called_node,
         SPOOF: self.spoof_safety_inputs}[name]()

    def every_fault_ran(self):
        return all(self.faults.values())

    def head_unplug(self):
        self.head(cmd="unplug", data="")
        self.wait(lambda: self.b.call("/terrace_control", "get_angle")[0] == ACK_FAILED, 10.0, "head reported lost")
        time.sleep(self.rng.uniform(0.5, 3.0))  # unplugged for a while
        self.head(cmd="replug", data="")
        self.availability.recovered("head after replug", self.time_until(
            lambda: self.b.call("/terrace_control", "get_angle")[0] == ACK_SUCCESS))

    def camera_fault(self, fault):
        """The camera refuses every login (401) or stops answering for a while: every request
        fails naming the cause, the camera works again once it clears, camera_node lives on."""
        pid = self.o.pid("/camera_node")
        self.camera.set_fault(fault)
        try:
            for _ in range(self.rng.randint(1, 3)):
                for cmd, request in (("capture_picture", lambda: self.capture("soak_fault")),
                                     ("get_zoom_level", lambda: self.b.call("/camera_control", "get_zoom_level"))):
                    ack, reason = request()
                    self.reasons.answered("%s during %s" % (cmd, fault), ack, reason, CAMERA_FAULT_REASONS[fault])
        finally:
            self.camera.set_fault(None)
        self.availability.recovered("camera after %s" % fault, self.time_until(
            lambda: self.capture("soak_fault")[0] == ACK_SUCCESS))
        self.liveness.unchanged("/camera_node", pid, self.o.pid("/camera_node"))

    def kill_node(self):
        """SIGKILL a node; respawned = a new process registered with the master, with every topic and
        service it had before the kill registered again (the node serves requests). Times each step."""
        node = self.rng.choice([n for n in KILLABLE if n in self.o.nodes])
        pid = self.o.pid(node)
        interface = self.o.interface(node)
        if not pid:
            return
        t0 = time.monotonic()
        os.kill(pid, signal.SIGKILL)
        marks = OrderedDict()

        def back():
            now = time.monotonic() - t0
            if "process" not in marks and [p for p in _node_process(node) if p != pid]:
                marks["process"] = now
            if "registered" not in marks and self.o.pid(node) not in (None, pid):
                marks["registered"] = now
            if "registered" in marks and interface <= self.o.interface(node):
                marks["ready"] = time.monotonic() - t0
                marks["cpu"] = _cpu_seconds(self.o.pid(node))   # what a load-independent start-up costs
                return True
            return False
        self.time_until(back, 30.0, period=0.05)
        self.respawn_times.append((node, marks))
        self.liveness.respawned(node, marks.get("ready"))

    def kill_called_node(self):
        """file_server SIGKILLed while a second backend connection calls file_control stat without
        pause (RETRY_PAUSE after a failed call): only calls made while it is away (until its respawn
        registered file_control) may fail, and they must say so (CallsAcrossRestart)."""
        node, service = "/file_server", "/file_control"
        pid = self.o.pid(node)
        if not pid:
            return
        master = rosgraph.Master("/" + NODE_NAME)
        before = master.lookupService(service)
        caller = RawClient("ws://127.0.0.1:%d" % self.port, timeout=20.0)
        calls, stop = [], threading.Event()

        def call_continuously():
            for n in range(1000000):
                if stop.is_set():
                    return
                start = time.monotonic()
                caller.send({"op": "call_service", "id": "restart%d" % n, "service": service,
                             "args": {"sender": SENDER_SERVER, "cmd": "stat", "data": json.dumps({"path": "tasks"})}})
                reply = caller.recv_message(lambda m, i="restart%d" % n: m.get("op") == "service_response"
                                            and m.get("id") == i, 30.0)
                calls.append((start, time.monotonic(), bool(reply.get("result")), str(reply.get("values"))))
                if not reply.get("result"):
                    # a backend asks again after a failure, not in a tight loop: unpaced, every failed call's
                    # lookup at the master (hundreds a second) delayed the respawn's own registration
                    time.sleep(RETRY_PAUSE)
        streaming = threading.Thread(target=call_continuously, name="soak_restart_calls")
        streaming.daemon = True
        streaming.start()
        try:
            self.wait(lambda: len(calls) >= 5, 30.0, "calls before the kill")
            killed = time.monotonic()
            os.kill(pid, signal.SIGKILL)

            def registered():
                try:
                    return master.lookupService(service) != before
                except rosgraph.MasterException:
                    return False
            self.wait(registered, 60.0, "%s registered again" % service)
            back = time.monotonic()
            count = len(calls)
            self.wait(lambda: len(calls) >= count + 10, 30.0, "calls after the respawn")
        finally:
            stop.set()
            streaming.join(30.0)
            caller.close()
        self.restart_calls.calls(service, killed, back, calls)
        self.liveness.respawned(node, back - killed)

    def drop_link(self):
        self.b.close()
        time.sleep(self.rng.uniform(0.2, 1.0))
        self.b.connect()
        self.take_control()

    def reconnect(self):
        """The backend drops its link while holding control and comes back as a new one 0 .. 3.2 s
        later (a restarted backend), which acquires at once: control kept = mode 1 and online until
        the old connection's last heartbeat has expired (HEARTBEAT_TIMEOUT + 0.5 s after the grant)."""
        if self.mode() != 1:
            self.take_control()
        self.b.close()
        time.sleep(self.rng.uniform(0.0, HEARTBEAT_TIMEOUT + 0.2))
        self.b.connect()
        self.take_control(acquire_first=True)
        lost = self.time_until(lambda: self.mode() != 1 or self.o.offline, HEARTBEAT_TIMEOUT + 0.5, period=0.02)
        self.kept.observed(RECONNECT, lost is None, "mode %s, offline %s" % (self.mode(), self.o.offline))

    def spoof_safety_inputs(self):
        """A box dropped ahead and behind stops the robot (stop_status bit 32). A spoofing client then
        claims the detector's clear and the joystick's acquire, over the link (the backend surface
        refuses the obstacle_status publish; robot_control's owner check refuses mode_cmd from sender
        joy_control through the bridge) and as a ROS node that is not the detector (its
        obstacle_status is dropped by caller id), while the backend keeps commanding a drive. Held:
        no robot_status without the obstacle bit while the box is there, the mode stays server mode,
        and no motion at the driver (MotionAuthority) until the real detector clears the stop."""
        if self.mode() != 1:
            self.take_control()
        pose = rospy.wait_for_message("sim/true_pose", PoseWithCovarianceStamped, 10.0).pose.pose
        yaw = 2.0 * math.atan2(pose.orientation.z, pose.orientation.w)
        boxes = {}
        for name, sign in (("soak_spoof_ahead", 1.0), ("soak_spoof_behind", -1.0)):
            boxes[name] = (pose.position.x + sign * SPOOF_BOX_M * math.cos(yaw),
                           pose.position.y + sign * SPOOF_BOX_M * math.sin(yaw))
            self.yard(cmd="drop", data="%s,%.3f,%.3f" % ((name,) + boxes[name]))
        try:
            self.wait(lambda: self.o.stop_status & STOP_OBSTACLE, 15.0, "the boxes stop the robot")
            now = time.time()
            self.o.stop_cause(now, now + TOPIC_ALLOWANCE + CYCLE, "obstacle ahead (spoofing follows)")
            self.o.obstacle_lifted, self.o.hold_obstacle = 0, True
            spoofer = Backend(self.port, self.rng)   # connected: a second client, never beating
            try:
                end = time.monotonic() + 1.5
                while time.monotonic() < end:
                    clear = {"sender": "obstacle_detector", "obstacle": False}
                    spoofer.publish("/obstacle_status", clear)
                    self.spoof_pub.publish(ObstacleStatus(**clear))
                    spoofer.publish("/mode_cmd", {"sender": "joy_control", "cmd": MODE_CMD_ACQUIRE, "data": "joy"})
                    self.b.drive(300.0 * self._direction, 0.1)   # the holder keeps commanding meanwhile
            finally:
                spoofer.close()
            time.sleep(0.5)   # a spoofed input that got through would show in robot_status by now
            self.o.hold_obstacle = False
            state = "%d robot_status without the obstacle bit, mode %s" % (self.o.obstacle_lifted, self.mode())
            self.spoofs.observed(SPOOF, self.o.obstacle_lifted == 0 and self.mode() == 1, state)
        finally:
            self.o.hold_obstacle = False
            for name in boxes:
                self.yard(cmd="remove", data=name)
        self.wait(lambda: not self.o.stop_status & STOP_OBSTACLE, 15.0, "the detector clears the stop")
        self.take_control()

    def stop_heartbeat(self):
        self.o.expect_offline_stop = True
        self.b.stop_heartbeat()
        self.b.drive(300.0 * self._direction, 5.0)   # a careless backend keeps commanding
        self.wait(lambda: self.o.offline, 10.0, "offline after the heartbeat stopped")
        self.b.drive(300.0 * self._direction, 1.0)
        self.o.expect_offline_stop = False
        self.take_control()

    def estop(self):
        stop = threading.Event()

        def keep_driving():
            while not stop.is_set():
                self.b.drive(300.0 * self._direction, 0.1)
        driver = threading.Thread(target=keep_driving, name="soak_drive")
        driver.start()
        time.sleep(0.5)
        t0 = time.time()
        self.inject(cmd="hard_estop", data="1")
        self.o.stop_cause(t0, time.time() + CYCLE, "hard e-stop")
        time.sleep(1.0)
        stop.set()
        driver.join()
        self.inject(cmd="hard_estop", data="0")
        self.o.authorise()

    def many_clients(self):
        clients = [RawClient("ws://127.0.0.1:%d" % self.port, timeout=30.0) for _ in range(100)]
        for c in clients:
            c.send({"op": "subscribe", "topic": "/control_status", "type": "inspection_robot/ControlStatus"})
        silent = silent_client(self.port, "/terrace_state", "sensor_msgs/JointState")
        try:
            for _ in range(3):
                self.patrol()
        finally:
            silent.close()
            for c in clients:
                c.close()

    def time_until(self, condition, timeout=30.0, period=0.1):
        t0 = time.monotonic()
        deadline = t0 + timeout
        while time.monotonic() < deadline:
            if condition():
                return time.monotonic() - t0
            time.sleep(period)
        return None

    def respawn_table(self):
        """Per killed node: kills and the slowest kill-to-process, -to-registered, -to-ready (s)."""
        lines = ["%-20s %5s %10s %13s %8s %12s"
                 % ("respawn after SIGKILL", "kills", "process s", "registered s", "ready s", "ready CPU s")]
        for node in sorted({n for n, _ in self.respawn_times}):
            marks = [m for n, m in self.respawn_times if n == node]
            worst = ["%.2f" % max(m[k] for m in marks) if all(m.get(k) is not None for m in marks) else "never"
                     for k in ("process", "registered", "ready", "cpu")]
            lines.append("%-20s %5d %10s %13s %8s %12s" % ((node, len(marks)) + tuple(worst)))
        return "\n".join(lines)


def _call_topic_vo(backend):
    """virtual_obstacle_cmd/ack is a topic pair: publish a command, wait for its ack by trans_id."""
    state = {"id": 0, "subscribed": False}

    def call(cmd, data):
        client = backend.client
        if state.get("client") is not client:
            client.send({"op": "advertise", "topic": "/virtual_obstacle_cmd", "type": "inspection_robot/GeneralCmd"})
            client.send({"op": "subscribe", "topic": "/virtual_obstacle_ack", "type": "inspection_robot/GeneralAck"})
            state["client"] = client
            time.sleep(0.5)  # the subscription must exist before the first command's ack
        state["id"] += 1
        trans_id = 50000 + state["id"]
        backend.publish("/virtual_obstacle_cmd", {"sender": SENDER_SERVER, "trans_id": trans_id, "cmd": cmd,
                                                  "data": data})
        try:
            msg = client.recv_message(lambda m: m.get("op") == "publish" and m.get("topic") == "/virtual_obstacle_ack"
                                      and m["msg"]["trans_id"] == trans_id, 15.0)
        except Exception:  # boundary: a lost ack is reported as such, the soak goes on
            return "no ack", ""
        return msg["msg"]["ack"], msg["msg"]["data"]
    return call


def run(args):
    """The soak with the command line's ``args`` (soak.py); exits with 0 only when every invariant held."""
    camera = None
    if args.isapi_port is not None:   # first: camera_node is already trying to reach it
        camera = FakeIsapiCamera(user=ISAPI_USER, password=ISAPI_PASSWORD, port=args.isapi_port).start()
    rospy.init_node(NODE_NAME, disable_signals=True)
    duration = args.minutes * 60.0
    motion, liveness = MotionAuthority(), NodeLiveness(args.respawn_limit)
    memory = MemoryGrowth(args.warmup if args.warmup is not None else min(max(0.2 * duration, 30.0), 0.5 * duration))
    ledger, availability, reasons = Ledger(), Availability(15.0), FaultReasons()
    restart_calls, kept, spoofs = CallsAcrossRestart(), ControlKept(), SpoofsRefused()
    observer = Observer(motion, liveness, memory)
    rospy.Subscriber("control_status", ControlStatus, lambda m: setattr(observer, "mode", m.mode), queue_size=10)
    port = int(_wait(lambda: rospy.get_param("/rosbridge_websocket/actual_port", None), 120.0, "bridge port"))
    _wait(lambda: set(KILLABLE) <= set(rosnode.get_node_names()), 120.0, "every node up")
    observer.nodes = sorted(n for n in rosnode.get_node_names() if n not in ("/rosout", "/" + NODE_NAME))
    backend = Backend(port, random.Random(args.seed + 1))
    backend.call_topic_vo = _call_topic_vo(backend)
    soak = Soak(backend, observer, {"ledger": ledger, "availability": availability, "liveness": liveness,
                                    "reasons": reasons, "restart_calls": restart_calls, "kept": kept,
                                    "spoofs": spoofs},
                random.Random(args.seed), port, camera, [w for w in args.faults.split(",") if w])

    soak.warm_up()
    stop = threading.Event()

    def sampler():
        while not stop.wait(1.0):
            observer.sample()
    sampling = threading.Thread(target=sampler, name="soak_sampler")
    sampling.daemon = True
    sampling.start()
    end = time.monotonic() + duration
    try:
        soak.take_control()
        # at least the given minutes, and at least one of every fault: on a slow machine an invariant
        # left unexercised would fail the soak for want of time, not for a fault
        while time.monotonic() < end or not soak.every_fault_ran():
            soak.patrol()
            if time.monotonic() < end or not soak.every_fault_ran():
                soak.fault()
                soak.patrol()
        time.sleep(2.0)
        soak.virtual_obstacles()
    finally:
        stop.set()
        sampling.join(5.0)
        backend.close()
        if camera is not None:
            camera.stop()
    memory.finish()
    checkers = [motion, liveness, memory, ledger, availability] + ([reasons] if camera is not None else [])
    if "service node killed during a stream of calls" in soak.faults:
        checkers.append(restart_calls)
    if RECONNECT in soak.faults:
        checkers.append(kept)
    if SPOOF in soak.faults:
        checkers.append(spoofs)
    print("soak: %.1f min, %d patrol loops, %d respawns, stop latency max %.3f s (n=%d), load average %.1f"
          % (args.minutes, soak.loops, liveness.respawns, max(motion.stop_latencies or [0.0]),
             len(motion.stop_latencies), os.getloadavg()[1]))
    print(table(soak.faults, checkers))
    print(soak.respawn_table())
    sys.exit(0 if held(checkers) else 1)


def _wait(condition, timeout, what, period=0.2):
    """``condition()``'s first truthy value, polled every ``period`` s; RuntimeError after ``timeout`` s."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(period)
    raise RuntimeError("soak: timed out after %.0f s waiting for %s" % (timeout, what))
