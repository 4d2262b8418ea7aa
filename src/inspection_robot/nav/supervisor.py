"""Goal supervision for move_action, without ROS: what the running goal does on each control tick.

One GoalSupervisor per goal. The node calls ``check(now, ...)`` every tick with the inputs of
that moment and acts on the answer:

- ``PAUSE``: robot_control is in another mode (joystick, server) and ignores move_cmd: send
  nothing; after ``mode_wait`` s the goal ends with ret_code "4";
- ``STOP``: a 3-D obstacle is in the travel corridor (and its enable bit is set): send a stop, or
  the follower's spin in place when it wants one and ``may_turn_away`` (follower.Approach.
  blocked_command says why); after ``obstacle_wait`` s the goal ends with "3";
- ``REPLAN``: plan again (after a pause or an obstacle wait the world may have changed, a
  virtual obstacle changed, or the robot is off track, at most every ``replan_min_interval`` s);
  the node then calls ``replanned(now)``; once an obstacle stopped the goal (``obstacle_met``) the
  plans have no departure curve (a curve drives forward first, towards what stopped the robot);
- ``FOLLOW``: step the path follower and report its progress with ``followed(progress)``.

``check`` returns (action, alarm): ``alarm`` is a reason to report once as feedback "3", else
None. An end of the goal is raised as GoalAborted(ret_code, reason); localization lost (with its
enable bit set) ends the goal with "2".
"""
from inspection_robot.interface import (MODE_NAMES, MODE_TASK, MOVE_RESULT_BLOCKED, MOVE_RESULT_CANCELLED,
                                        MOVE_RESULT_LOCALIZATION_LOST, NAV_LOCALIZATION_LOST, NAV_OBSTACLE_3D,
                                        NAV_OFF_TRACK)

PAUSE, STOP, REPLAN, FOLLOW = "pause", "stop", "replan", "follow"
OBSTACLE_REASON = "obstacle in the travel corridor"
BLOCKED_TURNS = 3   # obstacle stops per goal in which move_base may turn away (may_turn_away)
OFF_TRACK_REASON = "off track, replanning"


class GoalAborted(Exception):
    """Ends the running goal with ``ret_code`` and ``reason`` (actionlib state ABORTED)."""

    def __init__(self, ret_code, reason):
        Exception.__init__(self, reason)
        self.ret_code = ret_code


class GoalSupervisor(object):
    def __init__(self, mode_wait, obstacle_wait, replan_min_interval, off_track_m):
        self.mode_wait = float(mode_wait)
        self.obstacle_wait = float(obstacle_wait)
        self.replan_min_interval = float(replan_min_interval)
        self.off_track_m = float(off_track_m)
        self.off_track = False
        self._paused_since = None
        self._blocked_since = None
        self._last_replan = None
        self._replan_requested = False
        self.obstacle_stops = 0   # times a 3-D obstacle stopped this goal
        self._plain_failed = None  # when a plan without departure curve last failed (move_base's _plain)

    @property
    def obstacle_met(self):
        """A 3-D obstacle stopped this goal: plan without departure curves from now on."""
        return self.obstacle_stops > 0

    def may_turn_away(self, robot_control_stops):
        """While STOP: whether move_base may send the follower's spin instead of zeros.

        Only while robot_control refuses motion for the obstacle itself (``robot_control_stops``: its
        obstacle switch on), so the spin moves nothing until obstacle_detector finds its disc clear;
        and in at most ``BLOCKED_TURNS`` stops of one goal, so turning away and meeting the obstacle
        again cannot go on forever (the goal then waits ``obstacle_wait`` and ends "3" as before).
        """
        return bool(robot_control_stops) and 0 < self.obstacle_stops <= BLOCKED_TURNS

    def may_plan_plain(self, now):
        """While blocked: whether to plan without the departure curve now. After such a plan failed
        (the obstacle walls the goal in), not again before ``replan_min_interval``: not every tick."""
        return self._plain_failed is None or now - self._plain_failed >= self.replan_min_interval

    def plain_plan_failed(self, now):
        self._plain_failed = now

    def request_replan(self):
        """The costmap changed (any thread): plan again on the next tick."""
        self._replan_requested = True

    def replanned(self, now):
        self._replan_requested = False
        self._last_replan = now

    def followed(self, progress):
        self.off_track = progress.lateral_error > self.off_track_m

    def check_localization(self, problem, enable_bits):
        """``problem``: LocalizationMonitor.problem() (None when fine)."""
        if problem and enable_bits & NAV_LOCALIZATION_LOST:
            raise GoalAborted(MOVE_RESULT_LOCALIZATION_LOST, "localization lost: %s" % problem)

    def check(self, now, mode, obstacle, enable_bits):
        """Action for this tick (see the module docstring); raises GoalAborted to end the goal."""
        if mode != MODE_TASK:
            name = MODE_NAMES.get(mode, "unknown")
            if self._paused_since is None:
                self._paused_since = now
                return PAUSE, "robot_control in %s mode (%d): goal paused" % (name, mode)
            if now - self._paused_since > self.mode_wait:
                raise GoalAborted(MOVE_RESULT_CANCELLED, "robot_control in %s mode (%d) for %.1f s: goal given up"
                                  % (name, mode, self.mode_wait))
            return PAUSE, None
        if self._paused_since is not None:
            self._paused_since = None
            self._replan_requested = True  # the robot was driven elsewhere meanwhile
        if obstacle and enable_bits & NAV_OBSTACLE_3D:
            if self._blocked_since is None:
                self._blocked_since = now
                self.obstacle_stops += 1
                return STOP, OBSTACLE_REASON
            if now - self._blocked_since > self.obstacle_wait:
                raise GoalAborted(MOVE_RESULT_BLOCKED, "blocked by an obstacle for %.1f s" % self.obstacle_wait)
            return STOP, None
        if self._blocked_since is not None:
            self._blocked_since = None
            self._replan_requested = True  # the world may have changed while we waited
        if self._replan_requested:
            return REPLAN, OFF_TRACK_REASON if self.off_track else None
        if self.off_track and enable_bits & NAV_OFF_TRACK and (
                self._last_replan is None or now - self._last_replan > self.replan_min_interval):
            return REPLAN, OFF_TRACK_REASON
        return FOLLOW, None
