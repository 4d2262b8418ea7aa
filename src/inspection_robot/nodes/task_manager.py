"""task_manager: unattended patrols (docs/interface.md, "Patrol (task_manager)").

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
Parameters:  data_root (namespace: the robot's state directory): store and reports under
             <data_root>/tasks/ (snapshots in tasks/exports/), review corrections in
             <data_root>/corrections/; ~preset_root (str, presets: relative to data_root unless absolute);
             map_file, robot_radius: move_base's own (move_base/map_file, move_base/robot_radius) so
             reachability uses the map and inflation move_base plans with (~map_file and
             ~robot_radius override them where task_manager runs without move_base);
             ~home_pose ([x, y, yaw] m, rad; a site setting, no default); ~retries (int, 1);
             ~retry_delay_s (s, 3.0);
             ~uncertain_retries (int >= 0, 1): inspections again of a preset read uncertain;
             ~trend_window (10), ~trend_min_points (4), ~trend_horizon_days (7.0): the trend warning;
             ~velocity_x (m/s, 0.8), ~velocity_yaw (rad/s, 0.8); ~turn_at_stops (bool, false: the
             head's pan, not the robot, turns to a stop's heading); ~move_timeout_s (300),
             ~find_timeout_s (90), ~read_timeout_s (60), ~server_timeout_s (60: a step waits this long
             for an action server that is not up); ~move_estimate_s (20), ~preset_estimate_s (10):
             ETA before anything was measured; ~status_period (s, 1.0): task_status (and task_action
             feedback) republished at least this often while a task runs (at once on every change);
             ~virtual_wait_s (s, 5.0): a submission waits this long for move_base's virtual obstacles;
             ~schedule_check_s (s, 10.0): how often schedules are looked at; ~schedule_grace_s (s, 600.0):
             how long a due scheduled run waits for a running task before it is missed
"""
import json
import os
import threading
import time
import traceback

import actionlib
import numpy as np
import rospy
from nav_msgs.msg import OccupancyGrid

from inspection_robot.command import CommandError, CommandTable, no_data
from inspection_robot.files import hide_root, root_relative
from inspection_robot.msg import GeneralAction, GeneralFeedback, GeneralResult, GeneralTopic, RobotStatus
from inspection_robot.ros.node import init_node, site_param
from inspection_robot.version import version
from inspection_robot.ros.task_steps import StepRunner
from inspection_robot.ros.twin import CommandTwin
from inspection_robot.ros.worker import RequestWorker
from inspection_robot.task.action import END_CANCELED, END_SUCCEEDED, check_goal_type, goal_end, goal_feedback, \
    goal_refused
from inspection_robot.task.client_view import client_progress, client_row
from inspection_robot.task.checks import Reachability, resolve_preset
from inspection_robot.task.route import plan_route, route_points
from inspection_robot.task.patrol import OUTCOME_FAILED, BusyError, Patrol, PatrolConfig
from inspection_robot.task.report import summary, write_reports
from inspection_robot.task.review import parse_query, review
from inspection_robot.task.schedule import Scheduler, next_run, parse_routine, parse_schedule, routine_task
from inspection_robot.task.spec import check_task_id, parse_task
from inspection_robot.task.states import ENDED_STATES
from inspection_robot.task.store import ResultStore, StoreError, export_snapshot
from inspection_robot.task.track import PathThinner
from inspection_robot.task.trend import TrendConfig
from inspection_robot.ros.data_root import data_root, path_param

NODE_NAME = "task_manager"
QUERY_KEYS = ("task_id", "target", "from", "to", "after_id", "limit")
REVIEW_QUEUE_KEYS = ("task_id", "limit")
REPORT_TREND_POINTS = 20   # a meter's readings up to this task's drawn beside each of its readings in the report
PLAN_ID = "plan"           # the id a task is checked with when it has none (plan, routine_save)


class TaskManager(object):
    def __init__(self, store, reports_dir, patrol_config, preset_root, reachable, runner_factory, default_retries,
                 status_period, corrections_dir, data_root, scheduler, schedule_check_s):
        self._lock = threading.RLock()
        self._wake = threading.Condition(self._lock)
        self.store = store
        self._reports_dir = reports_dir
        self._exports_dir = os.path.join(os.path.dirname(reports_dir), "exports")
        self._corrections_dir = corrections_dir
        self._preset_root = preset_root
        self._data_root = data_root   # answers name files relative to it; taken out of refusals (files.hide_root)
        self._reachable = reachable
        self._default_retries = default_retries
        self._status_period = status_period
        self._pose = None
        self._tracks = {}   # task id -> PathThinner: poses of the path it drove, not yet stored
        self._overhead_s = 0.0
        self._status_pub = rospy.Publisher("task_status", GeneralTopic, queue_size=5, latch=True)
        self._last_status = None
        self._last_status_time = 0.0
        self._goals = {}   # task id -> task_action goal handle (only tasks submitted as an action)
        self.patrol = Patrol(store, patrol_config, time.time(), on_finished=self._on_finished)
        self._runner = runner_factory(lambda: self._pose)
        table = CommandTable({
            "submit": self._submit, "pause": self._changing(self.patrol.pause),
            "resume": self._changing(self.patrol.resume),
            "cancel": self._changing(lambda data: self.patrol.cancel(data, time.time())),
            "return_home": no_data(self._changing(lambda _data: self.patrol.return_home(time.time()))),
            "query_status": no_data(lambda d: self._status_json()),
            "query_tasks": no_data(self._query_tasks), "query_results": self._query_results, "report": self._report,
            "review_queue": self._review_queue, "review": self._review,
            "export_results": no_data(self._export_results),
            "plan": self._plan, "routine_save": self._routine_save, "routine_list": no_data(self._routine_list),
            "routine_delete": self._routine_delete, "schedule_set": self._schedule_set,
            "schedule_list": no_data(self._schedule_list), "schedule_delete": self._schedule_delete,
        })
        self._scheduler = scheduler
        self._schedule_status = {}
        self._refresh_schedule_status()
        self._twin = CommandTwin(table, "task_control", "task_cmd", "task_ack", NODE_NAME, busy_when_joystick=False)
        self._status_sub = rospy.Subscriber("robot_status", RobotStatus, self._on_robot_status, queue_size=1)
        self._virtual_sub = rospy.Subscriber("virtual_obstacle_map", OccupancyGrid, self._on_virtual_map,
                                             queue_size=1)
        # actionlib calls back under its own lock, and this node publishes feedback under self._lock:
        # the callbacks only queue the request, one worker runs it (one lock order, no deadlock)
        self._action_worker = RequestWorker("task_action", self._action_request, self._action_refused, 20)
        self._action = actionlib.ActionServer("task_action", GeneralAction,
                                              lambda goal: self._action_worker.submit(("goal", goal)),
                                              lambda goal: self._action_worker.submit(("cancel", goal)),
                                              auto_start=False)
        self._action.start()
        self._publish_status(force=True)
        # also while a step runs (a drive may take minutes): the patrol loop is blocked in it then
        self._status_timer = rospy.Timer(rospy.Duration(status_period / 2.0), self._on_status_timer)
        self._schedule_timer = rospy.Timer(rospy.Duration(schedule_check_s), self._on_schedule_timer)

    # --- inputs --------------------------------------------------------------------------------
    def _on_robot_status(self, msg):
        if len(msg.position) >= 2:
            self._pose = (float(msg.position[0]), float(msg.position[1]), float(msg.orientation))
        with self._lock:
            active = self.patrol.active
            if self._pose is not None and active is not None:
                task_id = active.task.task_id
                track = self._tracks.get(task_id)
                if track is None:
                    track = self._tracks[task_id] = PathThinner(task_id)
                track.add(time.time(), *self._pose)
            if msg.mode != self.patrol.mode:
                self.patrol.set_mode(msg.mode)
                self._changed()

    def _on_virtual_map(self, msg):
        cells = np.asarray(msg.data, dtype=np.int8)
        grid = self._reachable.costmap.grid
        if (msg.info.height, msg.info.width) != (grid.height, grid.width) or cells.size != grid.height * grid.width \
                or abs(msg.info.resolution - grid.resolution) > 1e-9:
            rospy.logerr_throttle(30.0, "%s: virtual_obstacle_map is %dx%d at %.3f m, the map %dx%d at %.3f m: "
                                  "ignored (task_manager and move_base must load the same map)"
                                  % (NODE_NAME, msg.info.width, msg.info.height, msg.info.resolution, grid.width,
                                     grid.height, grid.resolution))
            return
        self._reachable.set_virtual(cells.reshape(grid.height, grid.width) > 0)

    def _changed(self):
        self._publish_status()
        self._wake.notify_all()

    # --- commands (run under the lock; CommandError -> failed with the reason) ---------------------
    def _changing(self, change):
        """A command handler: ``change(data)`` on the patrol under the lock, then the new status
        is published and answered (CommandError from the patrol -> failed with its reason)."""
        def handler(data):
            with self._lock:
                change(data)
                self._changed()
                return self._status_json()
        return handler

    def _checked_task(self, data, known=(), default_id=None):
        """Every submission check of the task JSON ``data`` and its route (ordered when asked): a Task.
        Called outside the lock: checking presets and the map must not stall the patrol loop."""
        task = parse_task(data, lambda name: resolve_preset(self._preset_root, name, self._data_root), self._reachable,
                          self._default_retries, known, default_id)
        start, home = self._route_ends()
        plan_route(task, start, home, self._reachable.path_length)
        return task

    def _route_ends(self):
        """Where a route starts (the robot; the home pose while its pose is unknown) and ends (home)."""
        pose, home = self._pose, self.patrol.config.home_pose
        return (pose or home)[:2], home[:2]

    def _submit(self, data, goal=None):
        """Check and start a task; ``goal``: its task_action goal handle, accepted with it."""
        with self._lock:
            known = self.store.task_ids()
        task = self._checked_task(data, known)
        with self._lock:
            self.patrol.submit(task, time.time())
            if goal is not None:
                goal.set_accepted()
                self._goals[task.task_id] = goal
            self._changed()
            return self._status_json()

    # --- planning, routines and schedules (task/schedule.py) ----------------------------------------
    def _plan(self, data):
        """A task checked and ordered like submit, not submitted: its stops in driving order and the
        planner's path through them."""
        task = self._checked_task(data, default_id=PLAN_ID)
        start, home = self._route_ends()
        path = route_points(task, start, home, lambda a, b: self._reachable.path(a, b).points)
        stops = [{"name": s["name"], "pose": {"x": s["x"], "y": s["y"], "yaw": s["yaw"]},
                  "presets": [root_relative(p["directory"], self._data_root) for p in s["presets"]]}
                 for s in task.stops]
        return json.dumps({"order": task.order, "stops": stops, "path": path,
                           "planned_length_m": task.planned_length_m}, sort_keys=True)

    def _routine_save(self, data):
        name, task = parse_routine(data)
        self._checked_task(json.dumps(routine_task(task, PLAN_ID)))
        with self._lock:
            routine = self.store.save_routine(name, task, time.time())
        rospy.loginfo("%s: routine '%s' saved (%d stops)" % (NODE_NAME, name, len(task.get("stops", []))))
        return json.dumps(routine, sort_keys=True)

    def _routine_list(self, _data):
        return json.dumps(self.store.routines(), sort_keys=True)

    def _routine_delete(self, data):
        with self._lock:
            if self.store.routine(data) is None:
                raise CommandError("unknown routine '%s'" % data[:64])
            users = [s["name"] for s in self.store.schedules() if s["routine"] == data]
            if users:
                raise CommandError("routine '%s' is used by schedule(s) %s" % (data, ", ".join(users)))
            self.store.delete_routine(data)
        return json.dumps({"deleted": data})

    def _schedule_set(self, data):
        with self._lock:
            now = time.time()
            schedule = parse_schedule(data, set(r["name"] for r in self.store.routines()), now,
                                      self._scheduler.tz)
            self.store.set_schedule(schedule, now)
            self._scheduler.forget(schedule["name"])
            self._refresh_schedule_status()
            row = next(r for r in self._schedule_rows(now) if r["name"] == schedule["name"])
        rospy.loginfo("%s: schedule '%s' set: %s" % (NODE_NAME, schedule["name"], json.dumps(schedule)))
        return json.dumps(row, sort_keys=True)

    def _schedule_list(self, _data):
        with self._lock:
            return json.dumps(self._schedule_rows(time.time()), sort_keys=True)

    def _schedule_delete(self, data):
        with self._lock:
            if not self.store.delete_schedule(data):
                raise CommandError("unknown schedule '%s'" % data[:64])
            self._scheduler.forget(data)
            self._refresh_schedule_status()
        return json.dumps({"deleted": data})

    def _schedule_rows(self, now):
        """schedule_list's rows: each schedule with its next run, last run and missed runs."""
        rows = []
        for s in self.store.schedules():
            row = dict((k, s[k]) for k in ("name", "routine", "time", "weekdays", "date", "enabled") if k in s)
            row["next_run"] = next_run(s, max(now, s["set_at"]), self._scheduler.tz) if s["enabled"] else None
            task = self.store.task(s["last_task_id"]) if s["last_task_id"] else None
            row["last_run"] = None if s["last_at"] is None else {
                "at": s["last_at"], "task_id": s["last_task_id"], "state": task["state"] if task else ""}
            row["missed"] = [{"at": m["at"], "reason": m["reason"]} for m in self.store.missed_runs(s["name"])]
            rows.append(row)
        return rows

    def _refresh_schedule_status(self):
        """task_status's schedule keys (kept here: task_status is built often, the store asked rarely)."""
        now = time.time()
        upcoming = [(next_run(s, max(now, s["set_at"]), self._scheduler.tz), s["name"], s["routine"])
                    for s in self.store.schedules() if s["enabled"]]
        upcoming = sorted(u for u in upcoming if u[0] is not None)
        last = self.store.missed_runs(limit=1)
        self._schedule_status = {
            "missed_runs": self.store.get_meta("missed_runs", 0), "last_missed": last[0] if last else None,
            "next_scheduled": {"at": upcoming[0][0], "schedule": upcoming[0][1], "routine": upcoming[0][2]}
            if upcoming else None}

    def _on_schedule_timer(self, _event):
        try:
            self._schedule_tick(time.time())
        except Exception as err:  # boundary: a bug in one tick is logged, the next tick tries again
            rospy.logerr("%s: schedule tick: %s\n%s" % (NODE_NAME, err, traceback.format_exc()))

    def _schedule_tick(self, now):
        """Submit the scheduled runs that are due; a run that cannot start is missed, logged once."""
        with self._lock:
            busy = ""
            if self.patrol.returning_home:
                busy = "the robot was returning home"
            elif self.patrol.active is not None:
                busy = "task '%s' was running" % self.patrol.active.task.task_id
            start, missed = self._scheduler.tick(now, busy)
        for run in start:
            routine = self.store.routine(run.routine)
            try:
                if routine is None:
                    raise CommandError("unknown routine '%s'" % run.routine)
                with self._lock:   # its task and its schedule's last_run are seen together (schedule_list)
                    self._submit(json.dumps(routine_task(routine["task"], run.task_id)))
                    self._scheduler.started_run(run, time.time())
            except BusyError:   # a task started while this one was checked: it waits on
                with self._lock:
                    self._scheduler.busy_run(run)
            except CommandError as err:
                reason = str(hide_root(err, self._data_root))
                with self._lock:
                    self._scheduler.failed_run(run, reason, time.time())
                missed.append((run, reason))
            else:
                rospy.loginfo("%s: schedule '%s' started task %s" % (NODE_NAME, run.schedule, run.task_id))
        for run, reason in missed:
            rospy.logwarn("%s: schedule '%s' missed its run of %s (task %s): %s" % (
                NODE_NAME, run.schedule, time.strftime("%Y-%m-%d %H:%M", time.localtime(run.at)), run.task_id,
                reason))
        if start or missed:
            with self._lock:
                self._refresh_schedule_status()
                self._changed()

    # --- task_action -----------------------------------------------------------------------------

    def _action_request(self, request):
        kind, goal = request
        if kind == "goal":
            self._on_goal(goal)
        else:
            self._on_cancel(goal)

    def _action_refused(self, request):
        kind, goal = request
        if kind == "goal":
            reason = "busy: too many task_action requests waiting"
            ret_code, data = goal_refused(reason)
            goal.set_rejected(GeneralResult(ret_code=ret_code, data=data), reason)

    def _on_goal(self, goal):
        request = goal.get_goal()
        try:
            check_goal_type(request.type)
            self._submit(request.data, goal)
        except CommandError as err:
            reason = hide_root(err, self._data_root)
            ret_code, data = goal_refused(reason)
            goal.set_rejected(GeneralResult(ret_code=ret_code, data=data), reason)
            rospy.logwarn("%s: task_action goal from %s refused: %s" % (NODE_NAME, request.sender or "?", err))
        except Exception as err:  # boundary: a bug refuses this goal, the node lives on
            rospy.logerr("%s: task_action goal raised %s\n%s" % (NODE_NAME, err, traceback.format_exc()))
            ret_code, data = goal_refused(hide_root("internal error: %s" % (err,), self._data_root))
            goal.set_rejected(GeneralResult(ret_code=ret_code, data=data), "internal error")

    def _on_cancel(self, goal):
        with self._lock:
            task_id = next((t for t, g in self._goals.items() if g.get_goal_id().id == goal.get_goal_id().id), None)
            if task_id is None or task_id not in self.patrol.runs:
                return
            self.patrol.cancel(task_id, time.time(), "cancelled by the action client")
            self._changed()

    def _end_goal(self, task_id, report_path):
        goal = self._goals.pop(task_id, None)
        if goal is None:
            return
        row = self.store.task(task_id)
        end, ret_code, data = goal_end(summary(row, self.store.readings(task_id=task_id, limit=10 ** 9), ()),
                                       root_relative(report_path, self._data_root))
        result = GeneralResult(ret_code=ret_code, data=data)
        if end == END_SUCCEEDED:
            goal.set_succeeded(result, row["state"])
        elif end == END_CANCELED:
            goal.set_canceled(result, row["reason"])
        else:
            goal.set_aborted(result, row["reason"])

    def _query_tasks(self, _data):
        return json.dumps([{"task_id": t["task_id"], "priority": t["priority"], "state": t["state"],
                            "reason": t["reason"], "submitted": t["submitted"], "ended": t["ended"]}
                           for t in self.store.tasks()])

    def _query_results(self, data):
        query = parse_query(data, QUERY_KEYS, 1000)
        return json.dumps([client_row(r, self._data_root) for r in self.store.readings(
            query.get("task_id"), query.get("from"), query.get("to"), query["limit"], query.get("target"),
            query.get("after_id"))])

    def _review_queue(self, data):
        query = parse_query(data, REVIEW_QUEUE_KEYS, 100)
        return json.dumps([client_row(r, self._data_root)
                           for r in self.store.review_queue(query.get("task_id"), query["limit"])])

    def _review(self, data):
        with self._lock:   # one review at a time: two for one row must not race over its file
            try:
                row, path = review(self.store, self._corrections_dir, data, time.time())
            except StoreError as err:
                raise CommandError(str(err))
        rospy.loginfo("%s: reading %d reviewed by %s: %s (robot %s), %s" % (
            NODE_NAME, row["id"], row["review_by"], row["review_value"], row["value"], path))
        return json.dumps(dict(client_row(row, self._data_root), correction=root_relative(path, self._data_root)))

    def _export_results(self, _data):
        """A consistent snapshot of the results store for file_control (the live file's latest
        commits sit in its -wal)."""
        try:
            path = export_snapshot(self.store, self._exports_dir, time.time())
        except StoreError as err:
            raise CommandError(str(err))
        return json.dumps({"path": root_relative(path, self._data_root), "size": os.path.getsize(path)},
                          sort_keys=True)

    def _report(self, data):
        if self.store.task(data) is None:
            raise CommandError("unknown task '%s'" % data[:64])
        try:
            return json.dumps(dict((name, root_relative(path, self._data_root))
                                   for name, path in self._write_report(data).items()))
        except OSError as err:
            raise CommandError("cannot write the report: %s" % err)

    def _write_report(self, task_id):
        # the id names the folder: an id stored before ids were restricted ('..') must not escape reports/
        folder = os.path.join(self._reports_dir, check_task_id(task_id))
        with self._lock:
            self._store_paths(task_id)
        readings = self.store.readings(task_id=task_id, limit=10 ** 9)
        return write_reports(folder, self.store.task(task_id), readings, self.store.steps(task_id), self._data_root,
                             version(), self.store.meter_histories(readings, REPORT_TREND_POINTS),
                             self.store.driven_path(task_id), self._reachable.costmap.grid)

    def _on_finished(self, task_id):
        """A task ended: its report is written at once (a failure is logged, the patrol goes on),
        then its task_action goal, if any, ends."""
        report = ""
        try:
            report = self._write_report(task_id)["report.html"]
            rospy.loginfo("%s: task %s ended, report %s" % (NODE_NAME, task_id, report))
        except (CommandError, OSError, StoreError) as err:   # FileError is a CommandError
            rospy.logerr("%s: cannot write the report of %s: %s" % (NODE_NAME, task_id, err))
        self._end_goal(task_id, report)

    # --- status --------------------------------------------------------------------------------
    def _status_json(self):
        status = client_progress(self.patrol.status(), self._data_root)
        status["overhead_s"] = round(self._overhead_s, 3)
        status["store"] = root_relative(self.store.path, self._data_root)
        status.update(self._schedule_status)
        if status["task_id"] and status["state"] in ENDED_STATES:
            status["report"] = root_relative(os.path.join(self._reports_dir, status["task_id"], "report.html"),
                                             self._data_root)
        return json.dumps(status, sort_keys=True)

    def _on_status_timer(self, _event):
        with self._lock:
            self._publish_status()
            self._store_paths()

    def _store_paths(self, task_id=None):
        """Store the kept poses of every task's path (``task_id``: of that one); a store failure keeps
        them for the next try (bounded: PathThinner drops the oldest and counts them)."""
        for tid, track in list(self._tracks.items()):
            if task_id is not None and tid != task_id:
                continue
            ended = tid not in self.patrol.runs
            poses = track.take(final=ended)
            if poses:
                try:
                    self.store.add_poses(tid, poses)
                except StoreError as err:
                    track.give_back(poses)
                    rospy.logwarn_throttle(10.0, "%s: path of %s not stored yet: %s" % (NODE_NAME, tid, err))
            if track.dropped:
                rospy.logwarn("%s: %d pose(s) of the path of %s dropped (the store took none for too long)"
                              % (NODE_NAME, track.dropped, tid))
                track.dropped = 0
            if ended and not track.pending:
                del self._tracks[tid]   # ended and stored

    def _publish_status(self, force=False):
        text = self._status_json()
        now = time.monotonic()
        if force or text != self._last_status or now - self._last_status_time > self._status_period:
            msg = GeneralTopic(sender=NODE_NAME, data=text)
            msg.header.stamp = rospy.Time.now()
            self._status_pub.publish(msg)
            self._last_status, self._last_status_time = text, now
            for task_id, goal in self._goals.items():
                progress = self.patrol.task_progress(task_id)
                if progress is not None:
                    code, data = goal_feedback(client_progress(progress, self._data_root))
                    goal.publish_feedback(GeneralFeedback(event_code=code, data=data))

    # --- the patrol loop -----------------------------------------------------------------------
    def spin(self):
        while not rospy.is_shutdown():
            try:
                self._once()
            except StoreError as err:   # disk full, permissions: keep trying, loudly
                rospy.logerr_throttle(10.0, "%s: %s" % (NODE_NAME, err))
                rospy.sleep(1.0)
            except Exception as err:  # boundary: the patrol loop outlives any one step
                rospy.logerr("%s: patrol loop: %s\n%s" % (NODE_NAME, err, traceback.format_exc()))
                rospy.sleep(1.0)

    def _once(self):
        tick = time.monotonic()
        with self._lock:
            step = self.patrol.next_step(time.time())
            if step is None:
                self._publish_status()
                self._overhead_s += time.monotonic() - tick
                self._wake.wait(0.5)
                return
            self._publish_status()
        self._overhead_s += time.monotonic() - tick
        started = time.time()
        rospy.loginfo("%s: %s %s stop %d preset %d" % (NODE_NAME, step.task_id, step.kind, step.stop + 1,
                                                       step.preset_index + 1))
        try:
            outcome, detail, timings = self._runner.run(step, lambda: self._interrupt_wanted(step),
                                                        lambda fraction: self._drive_progress(step, fraction))
        except Exception as err:  # boundary: a bug in one step fails that step, the patrol goes on
            rospy.logerr("%s: %s step raised %s\n%s" % (NODE_NAME, step.kind, err, traceback.format_exc()))
            outcome, detail, timings = OUTCOME_FAILED, "internal error: %s" % (err,), {}
        tick = time.monotonic()
        ended = time.time()
        with self._lock:
            self.patrol.step_done(step, outcome, detail, started, ended)
            offset = started
            for kind in ("find", "read"):
                if kind in timings:
                    self.store.add_step(step.task_id, step.stop, step.preset_index, kind, outcome, offset,
                                        offset + timings[kind])
                    offset += timings[kind]
            if outcome != "ok":
                rospy.logwarn("%s: %s %s stop %d: %s: %s" % (NODE_NAME, step.task_id, step.kind, step.stop + 1,
                                                             outcome, detail))
            self._overhead_s += time.monotonic() - tick
            self._publish_status(force=True)

    def _drive_progress(self, step, fraction):
        with self._lock:   # eta_s falls with it; the status timer publishes the change
            self.patrol.drive_progress(step, fraction)

    def _interrupt_wanted(self, step):
        with self._lock:
            return self.patrol.interrupt_wanted(step)


def move_base_param(name):
    """move_base's own ``name`` (the planner's map and inflation), unless task_manager has ``~name``."""
    private = "~" + name
    if rospy.has_param(private):
        return rospy.get_param(private)
    if not rospy.has_param("move_base/" + name):
        raise ValueError("neither ~%s nor move_base/%s is set: task_manager checks reachability on move_base's map"
                         % (name, name))
    return rospy.get_param("move_base/" + name)


def main():
    init_node(NODE_NAME)
    root = data_root()
    tasks_dir = os.path.join(root, "tasks")
    os.makedirs(tasks_dir, exist_ok=True)
    preset_root = path_param("~preset_root", "presets", root)
    home_pose = [float(v) for v in site_param("~home_pose")]
    if len(home_pose) != 3:
        raise ValueError("~home_pose must be [x, y, yaw], got %r" % (home_pose,))
    uncertain_retries = rospy.get_param("~uncertain_retries", 1)
    if isinstance(uncertain_retries, bool) or not isinstance(uncertain_retries, int) \
            or not 0 <= uncertain_retries <= 10:
        raise ValueError("~uncertain_retries must be an integer in [0, 10], got %r" % (uncertain_retries,))
    trend = TrendConfig(int(rospy.get_param("~trend_window", 10)), int(rospy.get_param("~trend_min_points", 4)),
                        float(rospy.get_param("~trend_horizon_days", 7.0)), 600.0)
    if not 2 <= trend.min_points <= trend.window or not trend.horizon_days > 0:
        raise ValueError("~trend_min_points must be in [2, ~trend_window] and ~trend_horizon_days positive")
    config = PatrolConfig(retry_delay_s=float(rospy.get_param("~retry_delay_s", 3.0)), home_pose=tuple(home_pose),
                          move_estimate_s=float(rospy.get_param("~move_estimate_s", 20.0)),
                          preset_estimate_s=float(rospy.get_param("~preset_estimate_s", 10.0)),
                          uncertain_retries=uncertain_retries, trend=trend)
    retries = int(rospy.get_param("~retries", 1))
    reachable = Reachability(os.path.expanduser(move_base_param("map_file")),
                             float(move_base_param("robot_radius")), home_pose[:2],
                             float(rospy.get_param("~virtual_wait_s", 5.0)))
    timeouts = {"move": float(rospy.get_param("~move_timeout_s", 300.0)),
                "find": float(rospy.get_param("~find_timeout_s", 90.0)),
                "read": float(rospy.get_param("~read_timeout_s", 60.0)),
                "server": float(rospy.get_param("~server_timeout_s", 60.0))}
    velocity = (float(rospy.get_param("~velocity_x", 0.8)), float(rospy.get_param("~velocity_yaw", 0.8)))
    turn_at_stops = rospy.get_param("~turn_at_stops", False)
    if not isinstance(turn_at_stops, bool):
        raise ValueError("~turn_at_stops must be true or false, got %r" % (turn_at_stops,))
    store = ResultStore(os.path.join(tasks_dir, "results.sqlite"))
    schedule_check_s = float(rospy.get_param("~schedule_check_s", 10.0))
    schedule_grace_s = float(rospy.get_param("~schedule_grace_s", 600.0))
    if not 0 < schedule_check_s <= 60 or not schedule_grace_s >= schedule_check_s:
        raise ValueError("~schedule_check_s must be in (0, 60] s and ~schedule_grace_s at least as long, got %r, %r"
                         % (schedule_check_s, schedule_grace_s))
    status_period = float(rospy.get_param("~status_period", 1.0))
    if status_period <= 0:
        raise ValueError("~status_period must be positive, got %r" % status_period)
    manager = TaskManager(store, os.path.join(tasks_dir, "reports"), config, preset_root, reachable,
                          lambda pose: StepRunner(NODE_NAME, velocity[0], velocity[1], timeouts, pose,
                                                  turn_at_stops), retries,
                          status_period, os.path.join(root, "corrections"), root,
                          Scheduler(store, schedule_grace_s, time.time()), schedule_check_s)
    rospy.loginfo("%s: results in %s" % (NODE_NAME, store.path))
    manager.spin()
