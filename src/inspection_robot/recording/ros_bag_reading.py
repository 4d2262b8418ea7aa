"""The ROS side of bag_report (tools/bag_report.py): open bags, check their topics' types, feed a run's messages
to recording.summary.RunAnalyzer.

Imports rosbag, genpy and the message classes, so it lives in the ROS wing; tools/bag_report.py is the
command line and the picture. Every bad input is a :class:`ReportError` naming the file, topic and type.
rosbag's connection list comes through compat_rosbag (its one private access).
"""
import os
import struct

import genmsg
import genmsg.msg_loader
import genpy
import genpy.dynamic
import rosbag

from inspection_robot.msg import (ControlStatus, GeneralAck, GeneralActionGoal, GeneralActionResult, GeneralTopic,
                                  NavStatus, ObstacleStatus, ReadScaleAck, RobotStatus)
from inspection_robot.recording.summary import RunAnalyzer
from inspection_robot.ros import compat_rosbag

STATUS_FIELDS = ("offline_warn", "mode", "velocity_x", "velocity_yaw", "position", "orientation", "nav_status",
                 "sensor_status", "wheel_status", "light_status", "stop_status", "circuit_status", "other_status",
                 "battery_voltage", "battery_current", "battery_quantity", "battery_status", "motor_status",
                 "motor_info", "temperature")
# topic (relative to the robot's namespace) -> message class it must carry.
TYPED_TOPICS = {
    "robot_status": RobotStatus,
    "obstacle_status": ObstacleStatus,
    "move_action/goal": GeneralActionGoal,
    "move_action/result": GeneralActionResult,
    "find_scale_action/result": GeneralActionResult,
    "read_scale_ack": ReadScaleAck,
    "task_status": GeneralTopic,
    "map": "nav_msgs/OccupancyGrid",
    "virtual_obstacle_map": "nav_msgs/OccupancyGrid",
}
# what status_control rebuilds robot_status from during a replay (replay.launch)
REPLAY_INPUTS = {"control_status": ControlStatus, "nav_status": NavStatus, "robot_odom": "nav_msgs/Odometry",
                 "server_status": GeneralTopic}
TASK_MANAGER = "task_manager"   # its read_scale_acks are the task readings of task_status
MAX_WARNINGS = 20
# what building a message class from a bag's own definition raises (an unknown or garbled type)
TYPE_ERRORS = (genmsg.MsgGenerationException, genmsg.InvalidMsgSpec, genmsg.msg_loader.MsgNotFound, ValueError,
               KeyError, SyntaxError)
BAG_ERRORS = (rosbag.ROSBagException, genpy.DeserializationError, struct.error, OSError, ValueError)


class ReportError(Exception):
    """Bad input: the message is printed as is."""


def status_fields(msg):
    return {name: getattr(msg, name) for name in STATUS_FIELDS}


def _open(path):
    if not os.path.exists(path):
        raise ReportError("%s: no such bag file" % path)
    try:
        return rosbag.Bag(path)
    except rosbag.ROSBagUnindexedException:
        raise ReportError("%s: bag is not indexed (recording interrupted or still running?); "
                          "repair a copy with 'rosbag reindex'" % path)
    except BAG_ERRORS as exc:
        raise ReportError("%s: not a readable bag (truncated or foreign file?): %s" % (path, exc))


def find_namespace(bags, namespace):
    """The robot namespace prefix ('/' or '/ns/') whose robot_status the bags hold."""
    topics = {}
    for path, bag in bags:
        for topic, info in bag.get_type_and_topic_info().topics.items():
            topics.setdefault(topic, info.msg_type)
    if namespace is not None:
        prefix = "/" + namespace.strip("/") + "/" if namespace.strip("/") else "/"
    else:
        candidates = sorted(t[:-len("robot_status")] for t in topics if t.endswith("/robot_status"))
        if not candidates:
            raise ReportError("%s: no robot_status topic (inspection_robot/RobotStatus) in the bag; topics: %s"
                              % (bags[0][0], ", ".join(sorted(topics)[:12]) or "none"))
        if len(candidates) > 1:
            raise ReportError("robot_status of several robots (%s): choose one with --ns" % ", ".join(candidates))
        prefix = candidates[0]
    if prefix + "robot_status" not in topics:
        raise ReportError("%s: no topic %srobot_status in the bag" % (bags[0][0], prefix))
    return prefix, topics


def _read(name, datatype):
    """Is topic ``name`` (relative to the namespace) one that bag_report reads?"""
    return (name in TYPED_TOPICS or (name.endswith("_ack") and datatype == GeneralAck._type)
            or (name.endswith("_action/result") and datatype == GeneralActionResult._type))


def _check_type(path, conn, expected):
    """ReportError unless connection ``conn`` carries ``expected`` (a message class: same definition too)."""
    name = expected if isinstance(expected, str) else expected._type
    if conn.datatype != name:
        raise ReportError("%s: topic %s has type %s, expected %s" % (path, conn.topic, conn.datatype, name))
    if not isinstance(expected, str) and conn.md5sum != expected._md5sum:
        raise ReportError("%s: topic %s: type %s in the bag differs from this build's definition "
                          "(md5 %s, expected %s)" % (path, conn.topic, name, conn.md5sum, expected._md5sum))


def check_types(bags, prefix, expected_types=None):
    """The topics to read (absolute names). Each must carry the expected type (TYPED_TOPICS, same
    definition) and its definition in the bag must build a message class; other topics are not read.
    ``expected_types`` (name -> type) are checked as well, and not read."""
    topics, built = set(), set()
    for path, bag in bags:
        for conn in compat_rosbag.connections(bag):
            name = conn.topic[len(prefix):] if conn.topic.startswith(prefix) else None
            if name in (expected_types or {}):
                _check_type(path, conn, expected_types[name])
            if name is None or not _read(name, conn.datatype):
                continue
            if name in TYPED_TOPICS:
                _check_type(path, conn, TYPED_TOPICS[name])
            if (conn.datatype, conn.md5sum) not in built:
                try:
                    genpy.dynamic.generate_dynamic(conn.datatype, conn.msg_def)
                except TYPE_ERRORS as exc:
                    raise ReportError("%s: topic %s: type %s cannot be read from the bag's definition of it: %s"
                                      % (path, conn.topic, conn.datatype, exc))
                built.add((conn.datatype, conn.md5sum))
            topics.add(conn.topic)
    return sorted(topics)


def check_replayable(paths, namespace=None):
    """A one-line description of bags that replay.launch can play; ReportError naming what is wrong."""
    bags = [(p, _open(p)) for p in paths]
    try:
        prefix, topics = find_namespace(bags, namespace)
        missing = [prefix + name for name in sorted(REPLAY_INPUTS) if prefix + name not in topics]
        if missing:
            raise ReportError("%s: no %s in the bag: status_control cannot rebuild robot_status from it"
                              % (paths[0], ", ".join(missing)))
        check_types(bags, prefix, REPLAY_INPUTS)
        duration = sum(bag.get_end_time() - bag.get_start_time() for _p, bag in bags if bag.get_message_count())
    finally:
        for _path, bag in bags:
            bag.close()
    return "%s: replayable: %.1f s of namespace %s (%s)" % (
        paths[0], duration, prefix, ", ".join(sorted(REPLAY_INPUTS)))


def read_run(paths, namespace=None):
    """Returns (RunSummary, map OccupancyGrid or None, virtual obstacle grid or None, warnings)."""
    bags = [(p, _open(p)) for p in paths]
    try:
        prefix, _topics = find_namespace(bags, namespace)
        topics = check_types(bags, prefix)
        analyzer = RunAnalyzer()
        grids = {"map": None, "virtual_obstacle_map": None}
        warnings = []
        for path, bag in sorted(bags, key=lambda pb: pb[1].get_start_time() if pb[1].get_message_count() else 0):
            try:
                for topic, msg, stamp in bag.read_messages(topics=topics):
                    if topic.startswith(prefix):
                        _feed(analyzer, grids, warnings, topic[len(prefix):], msg, stamp.to_sec())
            except BAG_ERRORS as exc:
                raise ReportError("%s: bag is truncated or corrupt after %.1f s of data: %s"
                                  % (path, analyzer.finish().duration, exc))
        summary = analyzer.finish()
    finally:
        for _path, bag in bags:
            bag.close()
    if not summary.status_count:
        raise ReportError("%s: topic %srobot_status holds no message" % (paths[0], prefix))
    return summary, grids["map"], grids["virtual_obstacle_map"], warnings


def _feed(analyzer, grids, warnings, name, msg, t):
    problem = None
    if name == "robot_status":
        analyzer.add_status(t, status_fields(msg))
    elif name in grids:
        grids[name] = msg
    elif name == "obstacle_status":
        analyzer.add_obstacle(t, msg.obstacle)
    elif name == "move_action/goal":
        problem = analyzer.add_goal(t, msg.goal.data)
    elif name == "task_status":
        problem = analyzer.add_task_status(t, msg.data)
    elif name.endswith("_action/result"):
        analyzer.add_action_result(t, name[:-len("/result")], msg.result.ret_code, msg.result.data)
    elif name == "read_scale_ack":
        if msg.receiver != TASK_MANAGER:
            analyzer.add_reading(t, "read_scale", list(msg.scale) + list(msg.foreign_scale))
    elif name.endswith("_ack") and getattr(msg, "_type", "") == GeneralAck._type:
        analyzer.add_ack(t, name, msg.ack, msg.data)
    if problem and len(warnings) < MAX_WARNINGS:
        warnings.append("%.1f s: %s" % (t, problem))
