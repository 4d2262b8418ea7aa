"""task_manager: unattended patrols (docs/interface.md, "Patrol (task_manager)"). ROS wiring only: the
commands, the patrol loop, schedules, results and task_status are task.service.TaskService's.

Services:    task_control (ControlService): submit, pause, resume, cancel, return_home, query_status,
             query_tasks, query_results, report, review_queue, review, export_results, plan, routine_save,
             routine_list, routine_delete, schedule_set, schedule_list, schedule_delete (same table as
             task_cmd); answers name files relative to data_root (task.client_view)
Subscribes:  task_cmd (GeneralCmd), robot_status (RobotStatus: mode, pose; the pose, thinned (task.track), is
             the active task's driven path in the store: the report's map and distance driven)
             read_scale_ack (ReadScaleAck)
             virtual_obstacle_map (nav_msgs/OccupancyGrid, latched by move_base): reachability at submission
Publishes:   task_ack (GeneralAck), task_status (GeneralTopic, latched, JSON), read_scale_cmd (ReadScaleCmd)
Actions:     task_action (GeneralAction), server: goal type "patrol" = submit, feedback = progress
             move_action, find_scale_action (GeneralAction), client
Parameters:  config/task_manager.yaml: every setting, its default and meaning (read through
             ros.node.NodeSettings); data_root (namespace: the robot's state directory; its tasks/ and
             corrections/: task/service.py); map_file, robot_radius: move_base's own (move_base/map_file,
             move_base/robot_radius) so reachability uses the map and inflation move_base plans with
             (~map_file and ~robot_radius override them where task_manager runs without move_base);
             ~home_pose ([x, y, yaw] m, rad; a site setting, no default)
"""
import os
import time

import actionlib
import rospy
from nav_msgs.msg import OccupancyGrid

from inspection_robot.msg import GeneralAction, GeneralTopic, RobotStatus
from inspection_robot.ros.data_root import data_root
from inspection_robot.ros.language import site_translator
from inspection_robot.ros.node import NodeSettings, init_node, site_param
from inspection_robot.task.ros_goal import ActionGoal
from inspection_robot.task.ros_steps import StepRunner
from inspection_robot.ros.twin import CommandTwin
from inspection_robot.ros.worker import RequestWorker
from inspection_robot.task.checks import Reachability
from inspection_robot.task.patrol import PatrolConfig
from inspection_robot.task.schedule import Scheduler
from inspection_robot.task.service import ServiceConfig, TaskService
from inspection_robot.task.store import ResultStore
from inspection_robot.task.trend import TrendConfig
from inspection_robot.thermal.diagnosis import DiagnosisError, check_rules

NODE_NAME = "task_manager"
LOGGERS = {"info": rospy.loginfo, "warn": rospy.logwarn, "error": rospy.logerr}


def serve(service, root, status_period, schedule_check_s):
    """Wire ``service`` to ROS (its command twin, inputs, task_action server, timers), then run its patrol loop."""
    twin = CommandTwin(service.table, "task_control", "task_cmd", "task_ack", NODE_NAME, root,
                       busy_when_joystick=False)

    def on_robot_status(msg):
        pose = (float(msg.position[0]), float(msg.position[1]), float(msg.orientation)) \
            if len(msg.position) >= 2 else None
        service.on_robot_status(pose, msg.mode)
    subs = [rospy.Subscriber("robot_status", RobotStatus, on_robot_status, queue_size=1),
            rospy.Subscriber("virtual_obstacle_map", OccupancyGrid, lambda msg: service.on_virtual_map(
                msg.info.width, msg.info.height, msg.info.resolution, msg.data), queue_size=1)]
    # actionlib calls back under its own lock, and the service publishes feedback under its lock:
    # the callbacks only queue the request, one worker runs it (one lock order, no deadlock)
    worker = RequestWorker("task_action", service.action_request, service.action_refused, 20)
    action = actionlib.ActionServer("task_action", GeneralAction,
                                    lambda handle: worker.submit(("goal", ActionGoal(handle))),
                                    lambda handle: worker.submit(("cancel", ActionGoal(handle))), auto_start=False)
    action.start()
    service.publish_status(force=True)
    # also while a step runs (a drive may take minutes): the patrol loop is blocked in it then
    timers = [rospy.Timer(rospy.Duration(status_period / 2.0), lambda _event: service.status_tick()),
              rospy.Timer(rospy.Duration(schedule_check_s), lambda _event: service.schedule_timer())]
    rospy.loginfo("%s: results in %s" % (NODE_NAME, service.store.path))
    service.spin(lambda: not rospy.is_shutdown(), rospy.sleep)
    return twin, subs, action, timers   # referenced until the loop ends


def move_base_param(name):
    """move_base's own ``name`` (the planner's map and inflation), unless task_manager has ``~name``."""
    private = "~" + name
    if rospy.has_param(private):
        return rospy.get_param(private)
    if not rospy.has_param("move_base/" + name):
        raise ValueError("neither ~%s nor move_base/%s is set: task_manager checks reachability on move_base's map"
                         % (name, name))
    return rospy.get_param("move_base/" + name)


def _thermal_rules(overrides):
    try:
        return check_rules(overrides)
    except DiagnosisError as err:
        raise ValueError("~thermal_grades: %s" % err)


def main():
    init_node(NODE_NAME)
    settings = NodeSettings(NODE_NAME)
    root = data_root()
    tasks_dir = os.path.join(root, "tasks")
    os.makedirs(tasks_dir, exist_ok=True)
    preset_root = settings.path("~preset_root", root)
    home_pose = [float(v) for v in site_param("~home_pose")]
    if len(home_pose) != 3:
        raise ValueError("~home_pose must be [x, y, yaw], got %r" % (home_pose,))
    uncertain_retries = settings.get("~uncertain_retries")
    if isinstance(uncertain_retries, bool) or not isinstance(uncertain_retries, int) \
            or not 0 <= uncertain_retries <= 10:
        raise ValueError("~uncertain_retries must be an integer in [0, 10], got %r" % (uncertain_retries,))
    trend = TrendConfig(int(settings.get("~trend_window")), int(settings.get("~trend_min_points")),
                        float(settings.get("~trend_horizon_days")), 600.0)
    if not 2 <= trend.min_points <= trend.window or not trend.horizon_days > 0:
        raise ValueError("~trend_min_points must be in [2, ~trend_window] and ~trend_horizon_days positive")
    config = PatrolConfig(retry_delay_s=float(settings.get("~retry_delay_s")), home_pose=tuple(home_pose),
                          move_estimate_s=float(settings.get("~move_estimate_s")),
                          preset_estimate_s=float(settings.get("~preset_estimate_s")),
                          uncertain_retries=uncertain_retries, trend=trend,
                          thermal_rules=_thermal_rules(settings.get("~thermal_grades")))
    retries = int(settings.get("~retries"))
    reachable = Reachability(os.path.expanduser(move_base_param("map_file")),
                             float(move_base_param("robot_radius")), home_pose[:2],
                             float(settings.get("~virtual_wait_s")))
    timeouts = {"move": float(settings.get("~move_timeout_s")),
                "find": float(settings.get("~find_timeout_s")),
                "read": float(settings.get("~read_timeout_s")),
                "server": float(settings.get("~server_timeout_s"))}
    velocity = (float(settings.get("~velocity_x")), float(settings.get("~velocity_yaw")))
    turn_at_stops = settings.get("~turn_at_stops")
    if not isinstance(turn_at_stops, bool):
        raise ValueError("~turn_at_stops must be true or false, got %r" % (turn_at_stops,))
    store = ResultStore(os.path.join(tasks_dir, "results.sqlite"))
    schedule_check_s = float(settings.get("~schedule_check_s"))
    schedule_grace_s = float(settings.get("~schedule_grace_s"))
    if not 0 < schedule_check_s <= 60 or not schedule_grace_s >= schedule_check_s:
        raise ValueError("~schedule_check_s must be in (0, 60] s and ~schedule_grace_s at least as long, got %r, %r"
                         % (schedule_check_s, schedule_grace_s))
    status_period = float(settings.get("~status_period"))
    if status_period <= 0:
        raise ValueError("~status_period must be positive, got %r" % status_period)
    status_pub = rospy.Publisher("task_status", GeneralTopic, queue_size=5, latch=True)

    def publish_status(text):
        msg = GeneralTopic(sender=NODE_NAME, data=text)
        msg.header.stamp = rospy.Time.now()
        status_pub.publish(msg)
    service = TaskService(ServiceConfig(config, root, preset_root, retries, status_period, site_translator()), store,
                          Scheduler(store, schedule_grace_s, time.time()), reachable,
                          lambda pose: StepRunner(NODE_NAME, velocity[0], velocity[1], timeouts, pose, turn_at_stops),
                          publish_status, lambda level, text: LOGGERS[level]("%s: %s" % (NODE_NAME, text)))
    serve(service, root, status_period, schedule_check_s)
