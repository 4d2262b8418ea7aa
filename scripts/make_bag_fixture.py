#!/usr/bin/env python3
"""Writes test/fixtures/replay_run.bag: a small made-up 40 s run of a robot, as bag_recorder records it.

    scripts/rosenv python3 scripts/make_bag_fixture.py [OUT.bag]

The inputs of status_control (control_status 10 Hz, nav_status 10 Hz, robot_odom 20 Hz,
server_status 5 Hz) and the robot_status that status_control's logic (status.merge, default
timeouts) makes of them at 10 Hz, the latched map, virtual_obstacle_map and virtual_obstacles,
obstacle_status, one move_action goal and result, a patrol's task_status (1 Hz, latched) with its
read_scale_acks, a backend's read_scale_ack, a backend's virtual obstacle query and its ack, and one
failed control_ack, with a script a reader can follow (FIXTURE_* below, which the tests import):
- 0-10 s task mode at rest; 5-15 s drive along x from (0, 0) to (8, 0) at 0.8 m/s (a goal);
- 10-20 s backend (server) mode; 22-25 s soft e-stop engaged; 25-32 s drive along y to (8, 5.6);
- server_status stops after 27.8 s and resumes at 34 s: offline_warn rises at 30.8 s (3 s timeout);
- a 3-D obstacle from 26 to 27 s; a backend's reading 0.42 at 17 s; a failed control_ack at 21 s;
- task fixture_patrol (one stop, three presets) runs from 0.5 s, is paused by server mode 10-20 s,
  records oil_temp 118.2 C (alarm) at 20.5 s, the cabinet (ammeter 231.5 A normal, lamp 2 without
  a band) at 21.5 s, a failed switch preset at 21.9 s, and is done; task_status every second;
- a backend's virtual obstacle query (trans_id 99) at 3 s and move_base's answer.
Deterministic: the same file every time (fixed start time, no randomness). About 250 kB (lz4).
"""
import json
import math
import os
import sys

import rosbag
import rospy
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import OccupancyGrid, Odometry

from inspection_robot.interface import LIGHT_SOFT_ESTOP, MODE_SERVER, MODE_TASK
from inspection_robot.msg import (ControlStatus, GeneralAck, GeneralActionGoal, GeneralActionResult, GeneralCmd,
                                  GeneralTopic,
                                  NavStatus, ObstacleStatus, ReadScaleAck, RobotStatus)
from inspection_robot.status.merge import CONTROL_FIELDS, Heartbeat, StatusMerger

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEFAULT_OUT = os.path.join(ROOT, "test", "fixtures", "replay_run.bag")
FIXTURE_START = 1700000000.0       # bag time of the first message
FIXTURE_DURATION = 40.0
FIXTURE_HEARTBEAT_GAP = (28.0, 34.0)
FIXTURE_OFFLINE_AT = 30.8          # last beat (27.8 s, 5 Hz) + status_control's 3 s heartbeat_timeout
FIXTURE_SERVER_MODE = (10.0, 20.0)
FIXTURE_ESTOP = (22.0, 25.0)
FIXTURE_GOAL = (8.0, 0.0)
FIXTURE_TASK = "fixture_patrol"
FIXTURE_VIRTUAL_OBSTACLES = [{"id": "fixture_wall", "points": [[10.0, -1.0], [11.0, -1.0], [11.0, 3.0], [10.0, 3.0]],
                              "closed": True}]
FIXTURE_QUERY_TRANS_ID = 99
OIL = {"target": "transformer_1/oil_temp", "value": 118.2, "unit": "C", "alarm": "alarm", "status": "read"}
AMMETER = {"target": "cabinet_1/ammeter", "value": 231.5, "unit": "A", "alarm": "normal", "status": "read"}
LAMP = {"target": "cabinet_1/lamp_run", "value": 2.0, "unit": "", "alarm": "none", "status": "read"}
SWITCH = {"target": "bay_1/switch_2", "value": None, "unit": "", "alarm": "failed", "status": "failed"}
# (bag time, last_result) of the patrol's readings (task_status.last_result, docs/interface.md "Patrol")
FIXTURE_RESULTS = (
    (20.5, {"stop": 1, "preset": "/presets/transformer_1/20261123_075412", "readings": [OIL], "alarms": 1,
            "failed": 0, "reason": ""}),
    (21.5, {"stop": 1, "preset": "/presets/cabinet_1/20261123_075501", "readings": [AMMETER, LAMP], "alarms": 0,
            "failed": 0, "reason": ""}),
    (21.9, {"stop": 1, "preset": "/presets/switch_2/20261123_075530", "readings": [SWITCH], "alarms": 0,
            "failed": 1, "reason": "find_scale ended with 1: meter not found"}),
)


def pose_at(t):
    """(x, y, yaw, speed) of the made-up run at ``t`` seconds."""
    if t < 5.0:
        return 0.0, 0.0, 0.0, 0.0
    if t < 15.0:
        return 0.8 * (t - 5.0), 0.0, 0.0, 0.8
    if t < 25.0:
        return 8.0, 0.0, math.pi / 2 if t >= 24.0 else 0.0, 0.0
    if t < 32.0:
        return 8.0, 0.8 * (t - 25.0), math.pi / 2, 0.8
    return 8.0, 5.6, math.pi / 2, 0.0


def control_status(t):
    msg = ControlStatus(sender="robot_control")
    msg.mode = MODE_SERVER if FIXTURE_SERVER_MODE[0] <= t < FIXTURE_SERVER_MODE[1] else MODE_TASK
    msg.wheel_status = 1
    msg.light_status = LIGHT_SOFT_ESTOP if FIXTURE_ESTOP[0] <= t < FIXTURE_ESTOP[1] else 0
    msg.other_status = [0]
    msg.battery_voltage, msg.battery_current = 254, -12
    msg.battery_quantity = 80 - int(t // 20)
    msg.battery_status = 1 << 5
    msg.motor_status, msg.motor_info = [0] * 8, [0] * 8
    msg.temperature = [250] + [-1000] * 12
    return msg


def grid(width, height, resolution, origin, cells):
    msg = OccupancyGrid()
    msg.header.frame_id = "map"
    msg.info.resolution, msg.info.width, msg.info.height = resolution, width, height
    msg.info.origin.position.x, msg.info.origin.position.y = origin
    msg.info.origin.orientation.w = 1.0
    msg.data = cells
    return msg


def yard_grid(occupied):
    """A 20 m x 16 m grid at 0.1 m from (-4, -5): 100 where ``occupied(row, col, x, y)``, else 0."""
    width, height = 200, 160
    cells = [0] * (width * height)
    for row in range(height):
        for col in range(width):
            x, y = -4 + col * 0.1, -5 + row * 0.1
            cells[row * width + col] = 100 if occupied(row, col, x, y) else 0
    return grid(width, height, 0.1, (-4.0, -5.0), cells)


def yard_map():
    """The map: a fence ring and one equipment block."""
    return yard_grid(lambda row, col, x, y: row in (0, 159) or col in (0, 199) or (2.0 <= x <= 5.0 and 2.0 <= y <= 4.0))


def virtual_map():
    """move_base's virtual layer: one 1 m x 4 m obstacle."""
    return yard_grid(lambda _row, _col, x, y: 10.0 <= x <= 11.0 and -1.0 <= y <= 3.0)


def latched(topic, msg):
    return {"topic": topic, "type": msg._type, "md5sum": msg._md5sum, "message_definition": msg._full_text,
            "latching": "1", "callerid": "/move_base"}


def task_status(t):
    """The patrol's task_status dict at ``t`` (running, paused by server mode, done after its last reading)."""
    done = [result for at, result in FIXTURE_RESULTS if at <= t]
    status = {"task_id": FIXTURE_TASK, "priority": "routine", "state": "running", "holds": [], "stop": 1,
              "stops": 1, "stop_name": "bay_1", "preset": len(done) + 1, "presets": 3, "done": len(done), "total": 3,
              "last_result": done[-1] if done else None, "eta_s": 10.0 * (3 - len(done)), "suspended": "",
              "reason": "", "last_ended": None, "overhead_s": 0.01, "store": "/tmp/fixture/results.sqlite"}
    if len(done) == len(FIXTURE_RESULTS):
        status.update(state="done", stop=0, stops=0, stop_name="", preset=0, presets=0, done=0, total=0, eta_s=0.0,
                      last_ended={"task_id": FIXTURE_TASK, "state": "done", "reason": ""})
    elif FIXTURE_SERVER_MODE[0] <= t < FIXTURE_SERVER_MODE[1]:
        status.update(state="paused", holds=["mode"])
    return status


def write_fixture(path):
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    t0 = FIXTURE_START
    stamp = lambda t: rospy.Time.from_sec(t0 + t)
    merger = StatusMerger(Heartbeat(3.0), {"control": 1.0, "nav": 2.0, "odom": 1.0})
    with rosbag.Bag(path, "w", compression="lz4") as bag:
        for topic, msg in (("/map", yard_map()), ("/virtual_obstacle_map", virtual_map())):
            msg.header.stamp = stamp(0.0)
            bag.write(topic, msg, stamp(0.0), connection_header=latched(topic, msg))
        listing = GeneralTopic(sender="move_base", data=json.dumps(FIXTURE_VIRTUAL_OBSTACLES))
        listing.header.stamp = stamp(0.0)
        bag.write("/virtual_obstacles", listing, stamp(0.0), connection_header=latched("/virtual_obstacles", listing))
        obstacle = ObstacleStatus(sender="obstacle_detector", obstacle=False)
        bag.write("/obstacle_status", obstacle, stamp(0.0), connection_header=latched("/obstacle_status", obstacle))
        for i in range(int(FIXTURE_DURATION * 20)):
            t = i * 0.05
            x, y, yaw, speed = pose_at(t)
            odom = Odometry()
            odom.header.stamp, odom.header.frame_id, odom.child_frame_id = stamp(t), "odom", "base_link"
            odom.twist.twist.linear.x = speed
            bag.write("/robot_odom", odom, stamp(t + 0.002))
            merger.update_odometry(t0 + t + 0.002, speed, 0.0)
            if i % 2 == 0:
                cs = control_status(t)
                cs.header.stamp = stamp(t)
                bag.write("/control_status", cs, stamp(t + 0.003))
                merger.update_control(t0 + t + 0.003, {n: getattr(cs, n) for n in ("mode",) + CONTROL_FIELDS})
                ns = NavStatus(sender="move_base", nav_status=7, nav_warn=0, position=[x, y], orientation=yaw)
                ns.header.stamp = stamp(t)
                bag.write("/nav_status", ns, stamp(t + 0.004))
                merger.update_nav(t0 + t + 0.004, 0, [x, y], yaw)
            if i % 4 == 0 and not FIXTURE_HEARTBEAT_GAP[0] <= t < FIXTURE_HEARTBEAT_GAP[1]:
                beat = GeneralTopic(sender="server", data="")
                beat.header.stamp = stamp(t)
                bag.write("/server_status", beat, stamp(t + 0.001))
                merger.heartbeat.beat(t0 + t + 0.001)
            if i % 2 == 1:
                status = RobotStatus(sender="status_control", **merger.robot_status(t0 + t + 0.005))
                status.header.stamp = stamp(t + 0.005)
                bag.write("/robot_status", status, stamp(t + 0.006))
        goal = GeneralActionGoal()
        goal.header.stamp = goal.goal_id.stamp = stamp(5.0)
        goal.goal_id.id = "fixture-goal-1"
        goal.goal.type = "move"
        goal.goal.data = json.dumps({"goal_pose": {"position": {"x": FIXTURE_GOAL[0], "y": FIXTURE_GOAL[1], "z": 0},
                                                   "orientation": {"x": 0, "y": 0, "z": 0, "w": 1}}})
        bag.write("/move_action/goal", goal, stamp(5.0))
        result = GeneralActionResult()
        result.header.stamp = stamp(15.0)
        result.status.goal_id = goal.goal_id
        result.status.status = 3
        result.result.ret_code, result.result.data = "0", json.dumps({"position_error": 0.03})
        bag.write("/move_action/result", result, stamp(15.0))
        reading = ReadScaleAck(sender="read_scale", result="success", scale=[0.42], possibility=[97.0])
        reading.header.stamp = stamp(17.0)
        bag.write("/read_scale_ack", reading, stamp(17.0))
        ack = GeneralAck(sender="robot_control", receiver="server", trans_id=7, ack="failed",
                         data="unknown command 'foo'")
        ack.header.stamp = stamp(21.0)
        bag.write("/control_ack", ack, stamp(21.0))
        for t, flag in ((26.0, True), (27.0, False)):
            msg = ObstacleStatus(sender="obstacle_detector", obstacle=flag)
            msg.header.stamp = stamp(t)
            bag.write("/obstacle_status", msg, stamp(t), connection_header=latched("/obstacle_status", msg))
        for t in sorted(set([0.5 + k for k in range(int(FIXTURE_DURATION))] + [at for at, _r in FIXTURE_RESULTS])):
            msg = GeneralTopic(sender="task_manager", data=json.dumps(task_status(t)))
            msg.header.stamp = stamp(t)
            bag.write("/task_status", msg, stamp(t), connection_header=latched("/task_status", msg))
        for t, result in FIXTURE_RESULTS[:2]:   # read_scale's answers to task_manager, just before the results
            ack = ReadScaleAck(sender="read_scale", receiver="task_manager", result="success",
                               scale=[r["value"] for r in result["readings"]])
            ack.header.stamp = stamp(t - 0.1)
            bag.write("/read_scale_ack", ack, stamp(t - 0.1))
        query = GeneralCmd(sender="server", trans_id=FIXTURE_QUERY_TRANS_ID, cmd="query", data="")
        query.header.stamp = stamp(3.0)
        bag.write("/virtual_obstacle_cmd", query, stamp(3.0))
        answer = GeneralAck(sender="move_base", receiver="server", trans_id=FIXTURE_QUERY_TRANS_ID, ack="success",
                            data=json.dumps(FIXTURE_VIRTUAL_OBSTACLES))
        answer.header.stamp = stamp(3.01)
        bag.write("/virtual_obstacle_ack", answer, stamp(3.01))
        bag.write("/diagnostics", DiagnosticArray(), stamp(1.0))
    return path


if __name__ == "__main__":
    out = write_fixture(sys.argv[1] if len(sys.argv) > 1 else DEFAULT_OUT)
    print("%s: %d bytes" % (out, os.path.getsize(out)))
