"""The faults the chaos soak injects, one method each of SoakFaults, which ros/soak.py's Soak mixes in:
the serial head unplugged and back, the camera answering 401 or timing out, a node SIGKILLed
(each step of its respawn timed, respawn_table), file_server killed during a stream of calls, the
backend link dropped, a backend reconnecting while it holds control, the heartbeat stopped, a hard
e-stop during motion, a hundred clients and one that never reads, spoofed safety inputs.

A fault uses what Soak holds: the backend session (``self.b``), the observer (``self.o``), the
checkers, the simulator's services (``self.inject``, ``self.head``, ``self.yard``,
``self.spoof_pub``) and the patrol's helpers (``wait``, ``time_until``, ``take_control``,
``patrol``, ``capture``, ``mode``). Apart from the patrol loop because the faults are most of the
soak's code and each reads on its own.
"""
import json
import math
import os
import signal
import threading
import time
from collections import OrderedDict

import rosgraph
import rospy
from geometry_msgs.msg import PoseWithCovarianceStamped

from inspection_robot.interface import ACK_FAILED, ACK_SUCCESS, MODE_CMD_ACQUIRE, SENDER_SERVER, STOP_OBSTACLE
from inspection_robot.msg import ObstacleStatus
from inspection_robot_testing.bridge_client import RawClient
from inspection_robot_testing.ros.soak_observer import CYCLE, NODE_NAME, TOPIC_ALLOWANCE
from inspection_robot_testing.soak_backend import Backend, silent_client

KILLABLE = ("/cloud_terrace", "/camera_node", "/infrared_imager", "/status_control", "/move_base",
            "/obstacle_detector", "/robot_voice", "/preset_scale", "/find_scale", "/read_scale", "/robot_arm")
HEARTBEAT_TIMEOUT = 3.0  # s, status_control's (config/status_control.yaml)
RECONNECT = "backend reconnecting, the new one acquiring at once"
SPOOF = "spoofed obstacle clear and joystick acquire while a box stops the robot"
RETRY_PAUSE = 0.02   # s a calling backend waits after a failed call before the next (kill_called_node)
SPOOF_BOX_M = 1.0   # m ahead and behind the robot: whichever way the backend drives, the box is in the way
CAMERA_FAULT_REASONS = {"401": ["refused the credentials (HTTP 401"], "timeout": ["unreachable", "timed out"]}


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


class SoakFaults(object):
    """The soak's faults, mixed into Soak, whose state and helpers they use (see the module)."""

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
