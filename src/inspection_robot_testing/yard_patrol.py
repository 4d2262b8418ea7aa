"""A backend-like client that patrols the simulated yard over the websocket (`make patrol`, the
patrol rostest and bench/bench_patrol.py).

The yard plan (``YARD_STOPS``) covers every meter of config/sim_world.yaml's faces: six stops,
eight presets (one infrared, lamps and switches). ``PatrolClient`` talks only rosbridge through a
roslibpy ``Ros`` passed in (roslibpy is a test/demo dependency, never imported here): it records
the presets like an operator (robot put at the stop with robot_control's sim/inject_fault
set_pose, head aimed, preset_scale_cmd), calibrates them from the world's ground truth
(``calibrate_preset --from-world``, as the inspection rostest does), submits the
task on task_cmd and follows task_status. ``alarm_bands`` derives each target's normal band from
the world (a gauge's green zone, else its range without the red zones at its ends; a lamp or switch
its current state; a hot spot up to ``HOT_SPOT_LIMIT_C``).
"""
import concurrent.futures
import json
import math
import os
import shutil
import subprocess
import sys
import threading
import time

from inspection_robot.interface import ACK_SUCCESS, SENDER_SERVER
from inspection_robot.inspection.lamp import LAMP_CODES
from inspection_robot.inspection.preset import load_preset

HALF_PI = math.pi / 2.0
HOT_SPOT_LIMIT_C = 60.0
# stop name, pose (x, y, yaw), presets: (preset id, height aimed at m, distance to the side m, zoom, infrared)
YARD_STOPS = [
    ("transformer_1_left", (15.5, 10.0, 0.0), [("transformer_1_left", 1.5, 3.0, 2.0, False)]),
    ("transformer_1_front", (20.0, 15.0, -HALF_PI),
     [("transformer_1", 1.6, 3.0, 1.5, False), ("transformer_1_thermal", 2.95, 3.0, 2.0, True)]),
    ("cabinet_1", (20.0, 21.4, HALF_PI), [("cabinet_1", 1.55, 3.0, 2.0, False)]),
    ("cabinet_2", (26.0, 21.4, HALF_PI),
     [("cabinet_2", 1.45, 3.0, 2.0, False), ("cabinet_2_zoom", 1.4, 3.0, 3.0, False)]),
    ("breaker_1", (30.0, 14.5, -HALF_PI),
     [("breaker_1", 1.45, 3.5, 2.0, False), ("breaker_1_thermal", 1.9, 3.5, 1.5, True)]),
    ("breaker_2", (36.0, 14.5, -HALF_PI), [("breaker_2", 1.45, 3.5, 2.0, False)]),
]


def preset_count(stops=None):
    return sum(len(p) for _n, _pose, p in (stops or YARD_STOPS))


def alarm_band(world, name):
    """The normal band [low, high] of a face or hot spot of the world, or None."""
    if name in world.hot_spots:
        return [-50.0, HOT_SPOT_LIMIT_C]
    face = world.faces.get(name)
    if face is None:
        return None
    if face.type == "display":
        return list(face.range)
    if face.type == "gauge":
        greens = [(a, b) for a, b, c in face.zones if c == "green"]
        if greens:
            return [greens[0][0], greens[0][1]]
        low, high = face.range
        for a, b, c in face.zones:
            if c == "red" and a <= face.range[0]:
                low = max(low, b)
            elif c == "red" and b >= face.range[1]:
                high = min(high, a)
        return [low, high]
    return [expected_value(world, name, face.value)] * 2


def expected_value(world, name, value):
    """What read_scale answers for ``name`` when the simulator holds ``value`` (text or number)."""
    if name in world.hot_spots:
        return float(value)
    face = world.faces[name]
    if face.type in ("gauge", "display"):
        return float(value)
    if face.type == "lamp":
        return float(LAMP_CODES[face.color]) if value == "on" else 0.0
    return 1.0 if value == "closed" else 0.0


def yaw_quaternion(yaw):
    return {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2.0), "w": math.cos(yaw / 2.0)}


def build_task(task_id, directories, target_names, world, priority="routine", stops=None, retries=1,
               order="given"):
    """The task JSON object for ``stops`` (default the whole yard) with the world's alarm bands."""
    out = []
    for name, (x, y, yaw), presets in (stops or YARD_STOPS):
        entries = []
        for preset_id, _h, _d, _z, _ir in presets:
            bands = dict((t, alarm_band(world, t)) for t in target_names[preset_id])
            entries.append({"preset": directories[preset_id],
                            "alarms": dict((t, b) for t, b in bands.items() if b is not None)})
        out.append({"name": name, "pose": {"x": x, "y": y, "yaw": yaw}, "precision": 0, "presets": entries})
    return {"id": task_id, "priority": priority, "retries": retries, "order": order, "stops": out}


class PatrolClient(object):
    """The backend's side of a patrol, over rosbridge only (``ros``: a connected roslibpy.Ros)."""

    def __init__(self, ros, roslibpy, log=print):
        self.ros = ros
        self.roslibpy = roslibpy
        self.log = log
        self._lock = threading.Condition()
        self.status = None
        self.statuses = []
        self.acks = {}
        self._trans_id = int(time.time()) % 100000 * 10
        self._task_cmd = roslibpy.Topic(ros, "task_cmd", "inspection_robot/GeneralCmd")
        roslibpy.Topic(ros, "task_status", "inspection_robot/GeneralTopic").subscribe(self._on_status)
        roslibpy.Topic(ros, "task_ack", "inspection_robot/GeneralAck").subscribe(self._on_ack)
        self._preset_cmd = roslibpy.Topic(ros, "preset_scale_cmd", "inspection_robot/PresetScaleCmd")
        roslibpy.Topic(ros, "preset_scale_ack", "inspection_robot/PresetScaleAck").subscribe(self._on_preset_ack)
        self._joints = None
        roslibpy.Topic(ros, "terrace_state", "sensor_msgs/JointState", throttle_rate=50).subscribe(self._on_joints)
        self.preset_acks = {}
        self._nav_pose = None
        roslibpy.Topic(ros, "nav_status", "inspection_robot/NavStatus", throttle_rate=50).subscribe(self._on_nav)

    # --- plumbing ------------------------------------------------------------------------------
    def _on_status(self, msg):
        with self._lock:
            self.status = json.loads(msg["data"])
            self.statuses.append(self.status)
            self._lock.notify_all()

    def _on_ack(self, msg):
        with self._lock:
            self.acks[msg["trans_id"]] = msg
            self._lock.notify_all()

    def _on_preset_ack(self, msg):
        with self._lock:
            self.preset_acks[msg["trans_id"]] = msg
            self._lock.notify_all()

    def _on_nav(self, msg):
        with self._lock:
            if len(msg["position"]) >= 2:
                self._nav_pose = (msg["position"][0], msg["position"][1], msg["orientation"])
                self._lock.notify_all()

    def _on_joints(self, msg):
        with self._lock:
            self._joints = dict(zip(msg["name"], msg["position"]))
            self._lock.notify_all()

    def wait(self, predicate, timeout, what):
        deadline = time.monotonic() + timeout
        with self._lock:
            while True:
                value = predicate()
                if value:
                    return value
                if time.monotonic() > deadline:
                    raise RuntimeError("timed out after %.0f s waiting for %s" % (timeout, what))
                self._lock.wait(0.1)

    def next_id(self):
        self._trans_id += 1
        return self._trans_id

    def call(self, service, cmd, data="", timeout=30):
        """A ControlService call: returns (ack, data)."""
        srv = self.roslibpy.Service(self.ros, service, "inspection_robot/ControlService")
        trans_id = self.next_id()
        reply = srv.call(self.roslibpy.ServiceRequest({"sender": SENDER_SERVER, "trans_id": trans_id, "cmd": cmd,
                                                       "data": data}), timeout=timeout)
        if reply["trans_id"] != trans_id:
            raise RuntimeError("%s %s: trans_id %d echoed as %d" % (service, cmd, trans_id, reply["trans_id"]))
        return reply["ack"], reply["data"]

    def wait_services(self, names, timeout=120.0):
        """Wait until rosapi lists every service in ``names`` (nodes start in any order)."""
        wanted = set("/" + n.lstrip("/") for n in names)
        deadline = time.monotonic() + timeout
        missing = wanted
        while True:
            try:
                missing = wanted - set(self.ros.get_services())
            except self.roslibpy.core.RosTimeoutError:   # rosapi slower than roslibpy's 3 s: ask again
                pass
            else:
                if not missing:
                    return
            if time.monotonic() > deadline:
                raise RuntimeError("services %s not available after %.0f s" % (", ".join(sorted(missing)), timeout))
            time.sleep(1.0)   # the bridge offers no way to wait for a service: ask rosapi again

    def must(self, service, cmd, data="", timeout=30):
        ack, out = self.call(service, cmd, data, timeout)
        if ack != ACK_SUCCESS:
            raise RuntimeError("%s %s(%s) failed: %s" % (service, cmd, data[:80], out))
        return out

    def task_cmd(self, cmd, data="", timeout=30.0):
        """task_cmd over the topic twin; returns the GeneralAck (trans_id matched)."""
        trans_id = self.next_id()
        self._task_cmd.publish(self.roslibpy.Message({"sender": SENDER_SERVER, "trans_id": trans_id, "cmd": cmd,
                                                      "data": data}))
        return self.wait(lambda: self.acks.get(trans_id), timeout, "task_ack of %s" % cmd)

    # --- presets ---------------------------------------------------------------------------------
    def teleport(self, pose, timeout=15.0):
        """Put the simulated robot at ``pose`` (robot_control refuses while the chassis still moves)."""
        deadline = time.monotonic() + timeout
        while True:
            ack, data = self.call("sim/inject_fault", "set_pose", "%.4f,%.4f,%.5f" % tuple(pose))
            if ack == ACK_SUCCESS:
                break
            if time.monotonic() > deadline:
                raise RuntimeError("set_pose %s refused: %s" % (pose, data))
            time.sleep(0.2)   # the chassis is still moving: ask again (no state to wait on over the link)
        # preset_scale records the pose of nav_status: wait until it shows the new one (within 5 sigma of
        # sim_localizer's noise, config/sim_localizer.yaml: 2 cm, 0.5 deg)
        self.wait(lambda: self._nav_pose is not None and math.hypot(self._nav_pose[0] - pose[0],
                                                                    self._nav_pose[1] - pose[1]) < 0.1
                  and abs(math.remainder(self._nav_pose[2] - pose[2], 2 * math.pi)) < 0.05, 15.0,
                  "nav_status at %s" % (pose,))

    def record_preset(self, preset_id, aim_height, dist, zoom, infrared, sensor_height=1.2):
        tilt = round(math.degrees(math.atan2(sensor_height - aim_height, dist)) * 100)
        self.must("terrace_control", "set_angle", "0,%d" % tilt)
        self.must("camera_control", "set_zoom_level", "%.2f" % zoom)
        self.wait(lambda: self._joints is not None and abs(math.degrees(self._joints.get("tilt", 99)) - tilt / 100.0)
                  < 0.02 and abs(math.degrees(self._joints.get("pan", 99))) < 0.02, 30.0, "head settled")
        trans_id = self.next_id()
        self._preset_cmd.publish(self.roslibpy.Message({"sender": SENDER_SERVER, "trans_id": trans_id,
                                                        "preset_id": preset_id, "infrared": infrared,
                                                        "type": "meter", "extra_data": ""}))
        ack = self.wait(lambda: self.preset_acks.get(trans_id), 60.0, "preset_scale_ack of %s" % preset_id)
        if ack["result"] != ACK_SUCCESS:
            raise RuntimeError("preset %s not recorded: %s" % (preset_id, ack["directory"]))
        return ack["directory"]

    def record_yard(self, world_file, stops=None, progress=None):
        """Record and calibrate every preset of the plan; returns ({preset id: dir}, {preset id: targets}).
        Each calibration runs in the background while the next preset is recorded."""
        directories, pending = {}, {}
        self.wait_services(("sim/inject_fault", "terrace_control", "camera_control", "infrared_control",
                            "task_control"))
        with concurrent.futures.ThreadPoolExecutor(max_workers=1) as pool:
            for _name, pose, presets in (stops or YARD_STOPS):
                self.teleport(pose)
                for preset_id, aim, dist, zoom, infrared in presets:
                    directories[preset_id] = self.record_preset(preset_id, aim, dist, zoom, infrared)
                    pending[preset_id] = pool.submit(calibrate, directories[preset_id], world_file, pose)
            targets = {}
            for preset_id, future in pending.items():
                targets[preset_id] = future.result()
                if progress:
                    progress(preset_id, targets[preset_id])
        return directories, targets

    # --- the task ----------------------------------------------------------------------------------
    def submit(self, task):
        ack = self.task_cmd("submit", json.dumps(task))
        if ack["ack"] != ACK_SUCCESS:
            raise RuntimeError("task %s refused: %s" % (task["id"], ack["data"]))
        return json.loads(ack["data"])

    def wait_task_end(self, task_id, timeout, progress=None):
        """Follow task_status until ``task_id`` ends; ``progress(status)`` on every status."""
        deadline = time.monotonic() + timeout
        seen = 0
        while True:
            with self._lock:
                fresh, seen = self.statuses[seen:], len(self.statuses)
            for status in fresh:
                if progress:
                    progress(status)
                ended = status.get("last_ended") or {}
                if ended.get("task_id") == task_id:
                    return dict(status, task_id=task_id, state=ended["state"], reason=ended["reason"])
            if time.monotonic() > deadline:
                raise RuntimeError("task %s did not end within %.0f s (last status %s)"
                                   % (task_id, timeout, self.status))
            with self._lock:
                if len(self.statuses) == seen:
                    self._lock.wait(0.5)

    def results(self, task_id):
        return json.loads(self.must("task_control", "query_results", json.dumps({"task_id": task_id,
                                                                                 "limit": 5000})))


def calibrate(preset_dir, world_file, pose):
    """``calibrate_preset PRESET_DIR --from-world WORLD --pose X,Y,YAW`` (a separate process: the
    renderer would hold the GIL and starve the websocket client's thread); ``pose``: where the robot
    was put (preset.ini has the localizer's noisy pose); returns the preset's target names."""
    tool = shutil.which("calibrate_preset")
    command = [sys.executable, tool] if tool else ["rosrun", "inspection_robot", "calibrate_preset"]
    proc = subprocess.run(command + [preset_dir, "--from-world", world_file, "--pose", "%.6f,%.6f,%.6f" % tuple(pose)],
                          stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, universal_newlines=True, timeout=300)
    if proc.returncode != 0:
        raise RuntimeError("calibrate_preset %s: %s" % (preset_dir, proc.stderr.strip()))
    return [t.name for t in load_preset(preset_dir).targets]


def progress_bar(status, width=30):
    """One line: [#####.....] 12/24 presets, stop 3/6 cabinet_1, running, ETA 95 s."""
    total = max(1, status.get("total") or 0)
    filled = int(width * (status.get("done") or 0) / total)
    return "[%s%s] %d/%d presets, stop %d/%d %s, %s%s, ETA %.0f s" % (
        "#" * filled, "." * (width - filled), status.get("done", 0), status.get("total", 0), status.get("stop", 0),
        status.get("stops", 0), status.get("stop_name", ""), status.get("state", ""),
        (" (held: %s)" % ",".join(status["holds"])) if status.get("holds") else "", status.get("eta_s", 0.0))


def config_file(name):
    """A file of the package's config/ folder: the harness always runs from the source tree (src/<this>)."""
    here = os.path.dirname(os.path.abspath(__file__))
    return os.path.normpath(os.path.join(here, "..", "..", "config", name))


def default_world_file():
    return config_file("sim_world.yaml")
