#!/usr/bin/env python3
"""A backend's first session with the robot over its websocket, with roslibpy 1.x or 2.x.

Copy it and build on it. It does what every backend does (docs/interface.md):
  1. connects, draws a session number and sends the heartbeat under it (server_status, trans_id =
     the session, every 0.5 s) until it ends;
  2. waits for robot_status to answer *its own* heartbeat (offline_warn 0 and trans_id = its
     session): a backend that reconnects would otherwise see the previous one's heartbeat;
  3. takes the robot (mode_cmd acquire server with trans_id = its session, answered on mode_ack:
     the robot grants it on this session's heartbeat only) and drives it a little with
     move_cmd (0.3 m/s for 1.5 s, sent at 10 Hz: the robot stops 0.5 s after the last one);
  4. gives it back to task mode (mode_cmd release): move_base drives only in task mode;
  5. drives to a goal as an action goal (move_action), printing its feedback and result;
  6. reads task_status (the patrol's state) and exports the results store as a snapshot
     (task_control export_results), then checks the snapshot over file_control (stat: size, sha256).
It prints one line per step and exits 0 when every step succeeded, 1 otherwise.

    pip install roslibpy          # 2.x today; 1.x works the same
    python3 roslibpy_backend.py --host 127.0.0.1 --port 9090 --goal 7.0,5.0,0.0

roslibpy 2.x moved the ROS 1 action client to ``roslibpy.ros1.actionlib``; its top-level
``roslibpy.ActionClient`` is the ROS 2 one (the robot answers it ``Unknown operation:
send_action_goal``). roslibpy 1.x has it as ``roslibpy.actionlib``. The import below works on both.
"""
import argparse
import json
import math
import random
import sys
import threading
import time

import roslibpy

try:
    from roslibpy.ros1 import actionlib   # roslibpy 2.x
except ImportError:
    from roslibpy import actionlib        # roslibpy 1.x


class Backend(object):
    def __init__(self, ros, sender="server"):
        self.ros = ros
        self.sender = sender
        self.trans_id = 0
        self.session = random.SystemRandom().randint(1, 2 ** 32 - 1)   # names this connection's heartbeat
        self.robot_status = None
        self.task_status = None
        self.acks = {}                      # (topic, trans_id) -> ack message
        self.changed = threading.Condition()
        self.stopping = threading.Event()
        roslibpy.Topic(ros, "robot_status", "inspection_robot/RobotStatus", throttle_rate=200).subscribe(
            lambda m: self._set("robot_status", m))
        roslibpy.Topic(ros, "task_status", "inspection_robot/GeneralTopic").subscribe(
            lambda m: self._set("task_status", json.loads(m["data"])))
        roslibpy.Topic(ros, "mode_ack", "inspection_robot/GeneralAck").subscribe(lambda m: self._ack("mode", m))
        self.mode_cmd = roslibpy.Topic(ros, "mode_cmd", "inspection_robot/GeneralCmd")
        self.move_cmd = roslibpy.Topic(ros, "move_cmd", "inspection_robot/MoveCmd")
        self.heartbeat = roslibpy.Topic(ros, "server_status", "inspection_robot/GeneralTopic")
        threading.Thread(target=self._beat, daemon=True).start()

    def _set(self, name, value):
        with self.changed:
            setattr(self, name, value)
            self.changed.notify_all()

    def _ack(self, topic, msg):
        with self.changed:
            self.acks[(topic, msg["trans_id"])] = msg
            self.changed.notify_all()

    def _beat(self):
        while not self.stopping.wait(0.5):   # the robot goes offline after 3 s without one
            self.heartbeat.publish(roslibpy.Message({"sender": self.sender, "trans_id": self.session, "data": ""}))

    def online(self):
        """robot_status answers this backend's own heartbeat: online, and its trans_id is our session."""
        status = self.robot_status
        return status is not None and status["offline_warn"] == 0 and status["trans_id"] == self.session

    def wait(self, predicate, timeout, what):
        """predicate()'s first true value, or RuntimeError naming ``what`` after ``timeout`` s."""
        deadline = time.monotonic() + timeout
        with self.changed:
            while True:
                value = predicate()
                if value:
                    return value
                left = deadline - time.monotonic()
                if left <= 0:
                    raise RuntimeError("timed out after %.0f s waiting for %s" % (timeout, what))
                self.changed.wait(min(left, 0.5))

    def next_id(self):
        self.trans_id += 1
        return self.trans_id

    def mode(self, cmd, data, timeout=10.0, trans_id=None):
        """A mode_cmd and its mode_ack: (ack, data). An acquire server goes with ``trans_id`` = the session."""
        trans_id = self.next_id() if trans_id is None else trans_id
        self.mode_cmd.publish(roslibpy.Message({"sender": self.sender, "trans_id": trans_id, "cmd": cmd, "data": data}))
        ack = self.wait(lambda: self.acks.get(("mode", trans_id)), timeout, "mode_ack of %s" % cmd)
        return ack["ack"], ack["data"]

    def drive(self, speed_mm_s, seconds):
        """move_cmd at 10 Hz for ``seconds`` (velocity_x in 0.001 m/s), then one explicit stop."""
        for speed in [speed_mm_s] * int(seconds * 10) + [0.0]:
            self.move_cmd.publish(roslibpy.Message({"sender": self.sender, "trans_id": 0, "velocity_x": float(speed),
                                                    "velocity_yaw": 0.0, "wheel_control": 0}))
            time.sleep(0.1)

    def pose(self):
        return tuple(round(v, 2) for v in self.robot_status["position"][:2])

    def control(self, service, cmd, data="", timeout=30.0):
        """A command on a ControlService (task_control, file_control, ...): (ack, data)."""
        trans_id = self.next_id()
        reply = roslibpy.Service(self.ros, service, "inspection_robot/ControlService").call(
            roslibpy.ServiceRequest({"sender": self.sender, "trans_id": trans_id, "cmd": cmd, "data": data}),
            timeout=timeout)
        return reply["ack"], reply["data"]


def move(ros, x, y, yaw, timeout):
    """move_action goal (type "move"); returns (ret_code, result data, feedback count)."""
    client = actionlib.ActionClient(ros, "move_action", "inspection_robot/GeneralAction")
    goal_pose = {"position": {"x": x, "y": y, "z": 0.0},
                 "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2.0), "w": math.cos(yaw / 2.0)}}
    goal = actionlib.Goal(client, roslibpy.Message({"sender": "server", "trans_id": 1, "type": "move", "data": json.dumps(
        {"goal_pose": goal_pose, "with_direction": 1, "precision": 0})}))
    feedback = []
    goal.on("feedback", lambda f: feedback.append(f))
    goal.send()
    result = goal.wait(timeout)   # raises when no result came in time
    client.dispose()
    return result["ret_code"], json.loads(result["data"] or "{}"), len(feedback)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--host", default="127.0.0.1")
    parser.add_argument("--port", type=int, default=9090)
    parser.add_argument("--goal", default="7.0,5.0,0.0", help="x,y,yaw (m, m, rad, map) of the short move")
    parser.add_argument("--timeout", type=float, default=120.0, help="s for the move")
    args = parser.parse_args()
    x, y, yaw = (float(v) for v in args.goal.split(","))

    ros = roslibpy.Ros(args.host, args.port)
    ros.run(timeout=20)
    print("roslibpy %s: connected to %s:%d" % (getattr(roslibpy, "__version__", "?"), args.host, args.port))
    backend = Backend(ros)
    try:
        backend.wait(backend.online, 20.0, "robot_status online on our heartbeat (offline_warn 0, trans_id %d)"
                     % backend.session)
        print("online: robot_status offline_warn 0, mode %d, our heartbeat (session %d)"
              % (backend.robot_status["mode"], backend.session))
        ack, data = backend.mode("acquire", "server", trans_id=backend.session)
        print("acquire server: %s %s" % (ack, data))
        if ack != "success":
            return 1
        before = backend.pose()
        backend.drive(300.0, 1.5)
        time.sleep(1.0)   # braking, and robot_status catching up
        print("move_cmd: drove from %s to %s" % (before, backend.pose()))
        ack, data = backend.mode("release", "")
        print("release: %s %s" % (ack, data))
        ret_code, result, feedbacks = move(ros, x, y, yaw, args.timeout)
        print("move_action: ret_code %s, %d feedback(s), pose %s" % (ret_code, feedbacks, json.dumps(result.get("pose"))))
        status = backend.wait(lambda: backend.task_status, 20.0, "task_status")
        print("task_status: state %s, task %r, %s/%s presets done" % (status["state"], status["task_id"],
                                                                      status["done"], status["total"]))
        ack, data = backend.control("task_control", "export_results")
        if ack != "success":
            print("export_results: %s %s" % (ack, data))
            return 1
        path = json.loads(data)["path"]
        ack, data = backend.control("file_control", "stat", json.dumps({"path": path}))
        stat = json.loads(data) if ack == "success" else {}
        print("export_results: %s, %s bytes, sha256 %s" % (path, stat.get("size"), stat.get("sha256", data)[:12]))
        return 0 if ret_code == "0" and ack == "success" else 1
    finally:
        backend.stopping.set()
        ros.close()


if __name__ == "__main__":
    sys.exit(main())
