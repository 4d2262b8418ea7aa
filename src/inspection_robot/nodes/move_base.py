"""move_base: map, virtual obstacles, global planning, path following and move_action.

Subscribes:  <~pose_topic> (geometry_msgs/PoseWithCovarianceStamped) robot pose, frame map (docs/interface.md
             "Localization contract")
             obstacle_status (ObstacleStatus) from obstacle_detector (its caller id: motion.owners, ~owners)
             control_status (ControlStatus) from robot_control: a goal pauses while mode != 0 (task)
             control_cmd (GeneralCmd): enable_/disable_/switch_obstacle toggle the 3-D obstacle enable bit
             location_cmd (GeneralCmd): set_location init_pose | last_pose | x,y,yaw
             virtual_obstacle_cmd (GeneralCmd): add | modify | delete | query | clear (JSON data)
Publishes:   map (nav_msgs/OccupancyGrid, latched) the static map, never holding virtual obstacles
             virtual_obstacle_map (nav_msgs/OccupancyGrid, latched) the virtual layer, for RViz
             virtual_obstacles (GeneralTopic, latched) the obstacle list as query answers it (JSON), on
             start and every change: recorded in bags, answers queries during a replay
             plan (nav_msgs/Path, latched) the current global plan
             move_cmd (MoveCmd, sender "move_base") at ~control_rate while a goal runs
             nav_status (NavStatus) at ~status_rate; virtual_obstacle_ack (GeneralAck)
             initialpose (geometry_msgs/PoseWithCovarianceStamped) on set_location, for the localizer
Actions:     move_action (GeneralAction) goal type "move"
Parameters:  config/move_base.yaml: every setting, its default and meaning (read through ros.node.NodeSettings);
             site settings, no default (the site file; sim.launch: config/sim_site.yaml): ~map_file (map_server
             YAML), ~pose_topic (the localizer's), ~init_pose ([x, y, yaw] m, rad); data_root (namespace); ~owners
             (test rigs only: motion/ros_owner_gate.py)
"""
import json
import math
import threading
import time
import traceback

import actionlib
import rospy
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped
from nav_msgs.msg import OccupancyGrid, Path

from inspection_robot.angles import quaternion_from_yaw, wrap_angle, yaw_from_quaternion
from inspection_robot.command import CommandError
from inspection_robot.interface import (MODE_TASK,
                                        MOVE_FEEDBACK_ALARM, MOVE_FEEDBACK_MOVING, MOVE_FEEDBACK_PLANNED,
                                        MOVE_FEEDBACK_PLANNING, MOVE_RESULT_CANCELLED,
                                        MOVE_RESULT_LOCALIZATION_LOST, MOVE_RESULT_PLAN_FAILED,
                                        MOVE_RESULT_SUCCESS, MOVE_VELOCITY_X_UNIT_M_S, MOVE_VELOCITY_YAW_UNIT_RAD_S,
                                        NAV_LOCALIZATION_LOST, NAV_OBSTACLE_3D, NAV_OFF_TRACK, SENDER_MOVE_BASE,
                                        WHEEL_OBSTACLE_OFF, WHEEL_STRAIGHT)
from inspection_robot.msg import (ControlStatus, GeneralAction, GeneralCmd, GeneralFeedback, GeneralResult,
                                  GeneralTopic, MoveCmd, NavStatus, ObstacleStatus)
from inspection_robot.motion.owners import OBSTACLE_STATUS
from inspection_robot.nav.costmap import Costmap
from inspection_robot.nav.curves import curved_path
from inspection_robot.nav.follower import DONE, Approach, FollowerParams, PathFollower
from inspection_robot.nav.goal import parse_move_goal
from inspection_robot.nav.gridmap import load_map
from inspection_robot.nav.localization import LocalizationMonitor, location_target
from inspection_robot.files import FileError, read_json, rename_durable, write_json_atomic
from inspection_robot.nav.planner import Planner, PlanningError
from inspection_robot.nav.supervisor import FOLLOW, REPLAN, STOP, GoalAborted, GoalSupervisor
from inspection_robot.nav.virtual_obstacles import VirtualObstacles
from inspection_robot.ros.node import NodeSettings, init_node, site_param
from inspection_robot.motion.ros_owner_gate import OwnerGate
from inspection_robot.ros.twin import CommandTwin
from inspection_robot.ros.data_root import data_root

OBSTACLE_CONTROL = {"enable_obstacle": True, "disable_obstacle": False, "switch_obstacle": None}


def grid_message(grid, occupancy, stamp):
    msg = OccupancyGrid()
    msg.header.frame_id = "map"
    msg.header.stamp = stamp
    msg.info.map_load_time = stamp
    msg.info.resolution = grid.resolution
    msg.info.width, msg.info.height = grid.width, grid.height
    msg.info.origin.position.x, msg.info.origin.position.y = grid.origin[0], grid.origin[1]
    msg.info.origin.orientation.w = 1.0
    msg.data = occupancy.ravel().tolist()
    return msg


def pose_json(pose):
    if pose is None:
        return None
    return {"x": round(pose[0], 4), "y": round(pose[1], 4), "yaw": round(pose[2], 4)}


STARTUP_WAIT = 60.0   # s a goal waits for the costmap of a node still starting


class MoveBase(object):
    def __init__(self, grid, obstacles, localization, follower_params, cfg, owners):
        self.grid = grid
        # built after the ROS interface is up (attach): a respawned move_base is back on the graph
        # before cv2, scipy and the inflation of the map; goals that come meanwhile wait for them
        self.costmap = None
        self.planner = None
        self._attached = threading.Event()
        self.obstacles = obstacles
        self.loc = localization
        self.follower_params = follower_params
        self.cfg = cfg
        self.enable_bits = int(cfg["enable_bits"])
        self.obstacle = False
        self.off_track = False
        self.control_mode = MODE_TASK  # robot_control's mode; task until heard otherwise
        self.control_stops_for_obstacles = False  # robot_control's obstacle switch on (wheel_status b5 clear)
        self._costmap_lock = threading.Lock()
        self._supervisor = None  # of the running goal
        self._last_saved_pose = None

        stamp = rospy.Time.now()
        self._map_pub = rospy.Publisher("map", OccupancyGrid, queue_size=1, latch=True)
        self._map_pub.publish(grid_message(grid, grid.occupancy, stamp))
        self._virtual_pub = rospy.Publisher("virtual_obstacle_map", OccupancyGrid, queue_size=1, latch=True)
        self._listing_pub = rospy.Publisher("virtual_obstacles", GeneralTopic, queue_size=1, latch=True)
        self._plan_pub = rospy.Publisher("plan", Path, queue_size=1, latch=True)
        self._cmd_pub = rospy.Publisher("move_cmd", MoveCmd, queue_size=10)
        self._status_pub = rospy.Publisher("nav_status", NavStatus, queue_size=10)
        # not latched: a localizer that (re)starts later must not be reset to an old set_location
        self._initial_pub = rospy.Publisher("initialpose", PoseWithCovarianceStamped, queue_size=1)

        rospy.Subscriber(cfg["pose_topic"], PoseWithCovarianceStamped, self._on_pose, queue_size=10)
        self._owners = owners   # obstacle_status counts only from obstacle_detector
        rospy.Subscriber("obstacle_status", ObstacleStatus, self._on_obstacle, queue_size=10)
        rospy.Subscriber("control_status", ControlStatus, self._on_control_status, queue_size=10)
        rospy.Subscriber("control_cmd", GeneralCmd, self._on_control, queue_size=10)
        rospy.Subscriber("location_cmd", GeneralCmd, self._on_location, queue_size=10)
        self._virtual_twin = CommandTwin(self.obstacles.table, None, "virtual_obstacle_cmd", "virtual_obstacle_ack",
                                         SENDER_MOVE_BASE, busy_when_joystick=False, data_root=cfg["data_root"])

        self._server = actionlib.SimpleActionServer("move_action", GeneralAction, self._execute, auto_start=False)
        self._server.start()
        rospy.Timer(rospy.Duration(1.0 / cfg["status_rate"]), self._publish_status)
        rospy.Timer(rospy.Duration(cfg["last_pose_period"]), self._save_last_pose)
        rospy.on_shutdown(self.stop)

    # --- inputs --------------------------------------------------------------------------------
    def _on_pose(self, msg):
        p = msg.pose.pose
        yaw = yaw_from_quaternion(p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w)
        self.loc.update(time.monotonic(), p.position.x, p.position.y, yaw, list(msg.pose.covariance),
                        msg.header.frame_id)

    def _on_obstacle(self, msg):
        if not self._owners.refusal(OBSTACLE_STATUS, OBSTACLE_STATUS, msg):
            self.obstacle = bool(msg.obstacle)

    def _on_control_status(self, msg):
        self.control_mode = int(msg.mode)
        self.control_stops_for_obstacles = not msg.wheel_status & WHEEL_OBSTACLE_OFF

    def _on_control(self, msg):
        if msg.cmd not in OBSTACLE_CONTROL:
            return  # the other control_cmd commands belong to robot_control
        enable = OBSTACLE_CONTROL[msg.cmd]
        if enable is None:
            enable = not self.enable_bits & NAV_OBSTACLE_3D
        self.enable_bits = (self.enable_bits | NAV_OBSTACLE_3D) if enable else (self.enable_bits & ~NAV_OBSTACLE_3D)
        rospy.loginfo("move_base: 3-D obstacle handling %s (%s from %s)", "enabled" if enable else "disabled",
                      msg.cmd, msg.sender)

    def _on_location(self, msg):
        try:
            x, y, yaw = location_target(msg.cmd, msg.data, self.cfg["init_pose"],
                                        lambda: read_json(self.cfg["last_pose_file"]))
        except CommandError as err:
            rospy.logwarn("move_base: location_cmd %s(%r) from %s refused: %s", msg.cmd, msg.data, msg.sender, err)
            return
        out = PoseWithCovarianceStamped()
        out.header.frame_id = "map"
        out.header.stamp = rospy.Time.now()
        out.pose.pose.position.x, out.pose.pose.position.y = x, y
        _, _, out.pose.pose.orientation.z, out.pose.pose.orientation.w = quaternion_from_yaw(yaw)
        out.pose.covariance[0] = out.pose.covariance[7] = 0.25 ** 2
        out.pose.covariance[35] = 0.1 ** 2
        self._initial_pub.publish(out)
        rospy.loginfo("move_base: set_location %s -> initialpose (%.3f, %.3f, %.3f)", msg.data, x, y, yaw)

    def attach(self, costmap, planner):
        """The costmap and planner, built once the interface is up; virtual obstacles stored meanwhile
        are drawn in now."""
        with self._costmap_lock:
            costmap.set_virtual(self.obstacles.polylines())
            planner.refresh()
            self.costmap, self.planner = costmap, planner
        self._attached.set()
        self._publish_virtual()

    def on_virtual_change(self, _listing):
        """Called by the store after a change was saved: re-inflate, republish, replan."""
        with self._costmap_lock:
            if self.costmap is None:
                return   # attach() draws them
            self.costmap.set_virtual(self.obstacles.polylines())
            self.planner.refresh()
        self._publish_virtual()
        supervisor = self._supervisor
        if supervisor is not None:
            supervisor.request_replan()

    # --- outputs -------------------------------------------------------------------------------
    def _publish_virtual(self):
        stamp = rospy.Time.now()
        occupancy = (self.costmap.virtual * 100).astype("int8")
        self._virtual_pub.publish(grid_message(self.grid, occupancy, stamp))
        listing = GeneralTopic(sender=SENDER_MOVE_BASE, data=json.dumps(self.obstacles.listing()))
        listing.header.stamp = stamp
        self._listing_pub.publish(listing)

    def _publish_plan(self, points):
        path = Path()
        path.header.frame_id = "map"
        path.header.stamp = rospy.Time.now()
        for x, y in points:
            pose = PoseStamped()
            pose.header = path.header
            pose.pose.position.x, pose.pose.position.y = float(x), float(y)
            pose.pose.orientation.w = 1.0
            path.poses.append(pose)
        self._plan_pub.publish(path)

    def nav_warn(self):
        warn = NAV_OBSTACLE_3D if self.obstacle else 0
        if self.loc.lost(time.monotonic()):
            warn |= NAV_LOCALIZATION_LOST
        if self.off_track:
            warn |= NAV_OFF_TRACK
        return warn

    def _publish_status(self, _event=None):
        problem = self.loc.problem(time.monotonic())
        if problem:
            rospy.logwarn_throttle(30.0, "move_base: localization lost (no goal can run): %s" % problem)
        msg = NavStatus(sender=SENDER_MOVE_BASE, nav_status=self.enable_bits, nav_warn=self.nav_warn())
        msg.header.stamp = rospy.Time.now()
        if self.loc.pose is not None:
            msg.position = [self.loc.pose[0], self.loc.pose[1]]
            msg.orientation = self.loc.pose[2]
        self._status_pub.publish(msg)

    def _save_last_pose(self, _event=None):
        pose = self.loc.pose
        if pose is None or pose == self._last_saved_pose or self.loc.lost(time.monotonic()):
            return
        try:
            write_json_atomic(self.cfg["last_pose_file"], pose_json(pose))
            self._last_saved_pose = pose
        except FileError as err:
            rospy.logwarn_throttle(30.0, "move_base: cannot save last pose to %s: %s"
                                   % (self.cfg["last_pose_file"], err))

    def send(self, velocity_x, velocity_yaw, wheel_control):
        msg = MoveCmd(sender=SENDER_MOVE_BASE, velocity_x=velocity_x / MOVE_VELOCITY_X_UNIT_M_S,
                      velocity_yaw=velocity_yaw / MOVE_VELOCITY_YAW_UNIT_RAD_S, wheel_control=wheel_control)
        msg.header.stamp = rospy.Time.now()
        self._cmd_pub.publish(msg)

    def stop(self):
        self.send(0.0, 0.0, WHEEL_STRAIGHT)

    # --- move_action ---------------------------------------------------------------------------
    def _feedback(self, code, **data):
        data["pose"] = pose_json(self.loc.pose)
        self._server.publish_feedback(GeneralFeedback(event_code=code, data=json.dumps(data)))

    def _execute(self, goal_msg):
        aborted = False
        try:
            ret_code, data = self._run(goal_msg)
        except GoalAborted as end:
            ret_code, data, aborted = end.ret_code, {"reason": str(end)}, True
        except rospy.ROSInterruptException:
            ret_code, data = MOVE_RESULT_CANCELLED, {"reason": "shutting down"}
        except Exception as err:  # boundary: the goal fails, the node lives on
            rospy.logerr("move_base: goal raised: %s\n%s", err, traceback.format_exc())
            ret_code, data = MOVE_RESULT_PLAN_FAILED, {"reason": "internal error: %s" % (err,)}
        self.stop()
        self.off_track = False
        data["pose"] = pose_json(self.loc.pose)
        result = GeneralResult(ret_code=ret_code, data=json.dumps(data))
        if ret_code == MOVE_RESULT_SUCCESS:
            self._server.set_succeeded(result)
        elif ret_code == MOVE_RESULT_CANCELLED and not aborted:
            self._server.set_preempted(result)
        else:
            self._server.set_aborted(result, data.get("reason", ""))
        rospy.loginfo("move_base: goal finished with ret_code %s %s", ret_code, data)

    def _check_localization(self, supervisor):
        supervisor.check_localization(self.loc.problem(time.monotonic()), self.enable_bits)
        return self.loc.pose

    def _plan(self, goal, supervisor):
        self._feedback(MOVE_FEEDBACK_PLANNING)
        if not self._attached.wait(STARTUP_WAIT):
            raise GoalAborted(MOVE_RESULT_PLAN_FAILED, "costmap not built %.0f s after start-up" % STARTUP_WAIT)
        pose = self._check_localization(supervisor)
        if pose is None:
            raise GoalAborted(MOVE_RESULT_LOCALIZATION_LOST, "localization lost: no pose")
        started = time.monotonic()
        supervisor.replanned(started)
        try:
            with self._costmap_lock:
                plan = self.planner.plan(pose[:2], (goal.x, goal.y))
        except PlanningError as err:
            raise GoalAborted(MOVE_RESULT_PLAN_FAILED, "planning failed: %s" % err)
        self._publish_plan(plan.points)
        self._feedback(MOVE_FEEDBACK_PLANNED, path_length=round(plan.length, 3),
                       planning_time=round(time.monotonic() - started, 3))
        curved = None
        if not supervisor.obstacle_met:
            curved = curved_path(plan.points, pose, goal, self.follower_params, self.costmap.clearance)
        return Approach(PathFollower(plan.points if curved is None else curved, goal, self.follower_params,
                                     self.costmap.clearance), curved=curved is not None)

    def _run(self, goal_msg):
        cfg = self.cfg
        try:
            goal = parse_move_goal(goal_msg.type, goal_msg.data, cfg["default_velocity_x"],
                                   cfg["default_velocity_yaw"], cfg["max_velocity_x"], cfg["max_velocity_yaw"])
        except CommandError as err:
            raise GoalAborted(MOVE_RESULT_PLAN_FAILED, "bad goal: %s" % err)
        supervisor = GoalSupervisor(cfg["mode_wait"], cfg["obstacle_wait"], cfg["replan_min_interval"],
                                    cfg["off_track_m"])
        self._supervisor = supervisor
        try:
            return self._supervise(goal, supervisor)
        finally:
            self._supervisor = None

    def _plain(self, goal, supervisor, approach):
        """``approach``, or a plan without its departure curve (a curve drives forward first, towards what
        stopped the robot); a plan that fails keeps ``approach`` (the goal waits for the obstacle) and is
        tried again after supervisor.replan_min_interval."""
        if not approach.curved or not supervisor.may_plan_plain(time.monotonic()):
            return approach
        try:
            return self._plan(goal, supervisor)
        except GoalAborted as err:
            if err.ret_code != MOVE_RESULT_PLAN_FAILED:
                raise
            supervisor.plain_plan_failed(time.monotonic())
            return approach

    def _supervise(self, goal, supervisor):
        approach = self._plan(goal, supervisor)
        rate = rospy.Rate(self.cfg["control_rate"])
        last_feedback = 0.0
        while not rospy.is_shutdown():
            if self._server.is_preempt_requested():
                return MOVE_RESULT_CANCELLED, {"reason": "cancelled"}
            pose = self._check_localization(supervisor)
            action, alarm = supervisor.check(time.monotonic(), self.control_mode, self.obstacle, self.enable_bits)
            if alarm:
                self._feedback(MOVE_FEEDBACK_ALARM, nav_warn=self.nav_warn(), reason=alarm)
            if action == STOP and supervisor.may_turn_away(self.control_stops_for_obstacles):
                # the follower's spin when it wants one: obstacle_detector then checks its disc
                approach = self._plain(goal, supervisor, approach)
                cmd = approach.blocked_command(pose)
                self.send(cmd.velocity_x, cmd.velocity_yaw, cmd.wheel_control)
            elif action == STOP:
                self.stop()
            if action == REPLAN:
                approach = self._plan(goal, supervisor)
                pose = self.loc.pose
            if action in (REPLAN, FOLLOW):
                progress = approach.step(time.monotonic(), self.loc.stamp, pose)
                supervisor.followed(progress)
                self.off_track = supervisor.off_track
                if progress.phase == DONE:
                    rest = approach.rest
                    if approach.corrections:
                        rospy.loginfo("move_base: goal judged at rest after %d correction(s)", approach.corrections)
                    error = math.hypot(goal.x - rest[0], goal.y - rest[1])
                    return MOVE_RESULT_SUCCESS, {"position_error": round(error, 4),
                                                 "yaw_error": round(abs(wrap_angle(goal.yaw - rest[2])), 4)}
                cmd = progress.command
                self.send(cmd.velocity_x, cmd.velocity_yaw, cmd.wheel_control)
                now = time.monotonic()
                if now - last_feedback >= self.cfg["feedback_period"]:
                    last_feedback = now
                    self._feedback(MOVE_FEEDBACK_MOVING, remaining=round(progress.remaining, 3), phase=progress.phase)
            rate.sleep()
        return MOVE_RESULT_CANCELLED, {"reason": "shutting down"}


def _params(settings):
    root = data_root()
    cfg = {
        "data_root": root,
        "map_file": site_param("~map_file"),
        "pose_topic": site_param("~pose_topic"),
        "virtual_obstacles_file": settings.path("~virtual_obstacles_file", root),
        "last_pose_file": settings.path("~last_pose_file", root),
        "init_pose": [float(v) for v in site_param("~init_pose")],
        "enable_bits": int(settings.get("~enable_bits")),
    }
    for name in ("last_pose_period", "robot_radius", "safety_margin", "margin_cost", "control_rate", "status_rate",
                 "feedback_period", "default_velocity_x", "max_velocity_x", "default_velocity_yaw", "max_velocity_yaw",
                 "off_track_m", "replan_min_interval", "obstacle_wait", "mode_wait", "max_xy_std", "max_yaw_std",
                 "pose_timeout", "coarse_factor"):
        cfg[name] = float(settings.get("~" + name))
    for name in ("control_rate", "status_rate", "last_pose_period", "feedback_period", "max_velocity_x",
                 "max_velocity_yaw", "default_velocity_x", "default_velocity_yaw", "pose_timeout", "max_xy_std",
                 "max_yaw_std"):
        if cfg[name] <= 0:
            raise ValueError("~%s must be positive" % name)
    if len(cfg["init_pose"]) != 3:
        raise ValueError("~init_pose must be [x, y, yaw]")
    return cfg


def main():
    init_node("move_base")
    settings = NodeSettings("move_base")
    cfg = _params(settings)
    follower_params = FollowerParams(**{k: float(v) for k, v in settings.get("~follower").items()})
    grid = load_map(cfg["map_file"])
    obstacles = VirtualObstacles(cfg["virtual_obstacles_file"])
    try:
        obstacles.load()
    except (FileError, ValueError) as err:
        aside = cfg["virtual_obstacles_file"] + ".corrupt"
        rename_durable(cfg["virtual_obstacles_file"], aside)
        rospy.logerr("move_base: virtual obstacles not loaded (file moved to %s), starting without them: %s",
                     aside, err)
    localization = LocalizationMonitor(cfg["max_xy_std"], cfg["max_yaw_std"], cfg["pose_timeout"],
                                       "%s (setting move_base/pose_topic)" % rospy.resolve_name(cfg["pose_topic"]))
    node = MoveBase(grid, obstacles, localization, follower_params, cfg, OwnerGate.from_param(SENDER_MOVE_BASE))
    obstacles.on_change = node.on_virtual_change
    costmap = Costmap(grid, cfg["robot_radius"], cfg["safety_margin"], cfg["margin_cost"])
    node.attach(costmap, Planner(costmap, coarse_factor=int(cfg["coarse_factor"])))
    rospy.loginfo("move_base: map %s (%dx%d at %.3f m), %d virtual obstacles, pose from %s", cfg["map_file"],
                  grid.width, grid.height, grid.resolution, len(obstacles.listing()), cfg["pose_topic"])
    rospy.spin()
