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
the message classes): the patrol loop (Soak) and run(). Its parts: the faults in ros/soak_faults.py
(SoakFaults, which Soak mixes in), the observer in ros/soak_observer.py, the backend's websocket
session in inspection_robot_testing/soak_backend.py.
"""
import json
import os
import random
import sys
import threading
import time
from collections import OrderedDict

import rosnode
import rospy

from inspection_robot.interface import ACK_SUCCESS, MODE_CMD_ACQUIRE, MODE_NAMES, MODE_SERVER, SENDER_SERVER
from inspection_robot.msg import ControlStatus, ObstacleStatus
from inspection_robot.srv import ControlService
from inspection_robot_testing.fake_isapi import FakeIsapiCamera
from inspection_robot_testing.ros.soak_faults import KILLABLE, RECONNECT, SPOOF, SoakFaults
from inspection_robot_testing.ros.soak_observer import NODE_NAME, Observer
from inspection_robot_testing.soak_backend import Backend
from inspection_robot_testing.soak_invariants import (Availability, CallsAcrossRestart, ControlKept, FaultReasons,
                                                      Ledger, MemoryGrowth, MotionAuthority, NodeLiveness,
                                                      SpoofsRefused, held, table)

VO = "virtual obstacle"
ISAPI_USER, ISAPI_PASSWORD = "admin", "soak"   # launch/include/camera.launch, camera_isapi_url


class Soak(SoakFaults):
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

    def time_until(self, condition, timeout=30.0, period=0.1):
        t0 = time.monotonic()
        deadline = t0 + timeout
        while time.monotonic() < deadline:
            if condition():
                return time.monotonic() - t0
            time.sleep(period)
        return None


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
