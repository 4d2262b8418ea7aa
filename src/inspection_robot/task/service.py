"""task_manager's whole task life without ROS: commands, the patrol loop, schedules, results, status.

The node (nodes/task_manager.py) only wires a TaskService: it serves ``table`` on task_control and
task_cmd/task_ack, feeds robot_status (``on_robot_status``) and virtual_obstacle_map
(``on_virtual_map``), hands task_action requests to ``action_request``, calls ``status_tick`` and
``schedule_timer`` from timers and runs ``spin`` on its main thread. Everything else comes in
through the constructor: the results store, the scheduler, the reachability check, the step
runner (task/ros_steps.py in the node; tests pass a fake), ``publish_status(text)`` for
task_status, ``log(level, text)`` (info, warn, error) and the clocks.

Threads: commands (service and topic threads), the timers and the action worker meet the patrol
loop under one re-entrant lock; the loop runs a step (a drive may take minutes) outside it and
waits on the lock's condition when nothing is to do, so every change wakes it. Checking a task's
presets and route takes the lock only to read the known ids: it must not stall the loop.

Files, under the data root (the robot's state directory): the store and reports under tasks/
(reports/<task_id>/, snapshots for the backend in tasks/exports/), review corrections in
corrections/. Answers name files relative to the data root (task.client_view); refusals have its
location taken out (files.hide_root).

task_status (JSON, latched) is published at once on every change and at least every
``status_period`` s while nothing changes; the goals of task_action get the same progress as
feedback. A task that ends gets its report at once, then its goal (if any) ends
(task/action.py maps both).

A task_action goal is handed in as an object with ``request`` (the GeneralGoal: type, data,
sender), ``id`` (its goal id), ``accept()``, ``feedback(event_code, data)``,
``end(end, ret_code, data, text)`` (end: task.action's END_*) and ``refuse(ret_code, data, text)``.
"""
import json
import os
import threading
import time
import traceback
from collections import namedtuple

import numpy as np

from inspection_robot.command import CommandError, CommandTable, no_data
from inspection_robot.files import hide_root, root_relative
from inspection_robot.i18n import ENGLISH
from inspection_robot.task.action import END_SUCCEEDED, check_goal_type, goal_end, goal_feedback, goal_refused
from inspection_robot.task.alarms import OpenAlarms
from inspection_robot.task.checks import resolve_preset
from inspection_robot.task.client_view import client_progress
from inspection_robot.task.patrol import OUTCOME_FAILED, OUTCOME_OK, BusyError, Patrol
from inspection_robot.task.report import summary
from inspection_robot.task.result_commands import ResultCommands
from inspection_robot.task.route import plan_route, route_points
from inspection_robot.task.schedule import local_zone, routine_task
from inspection_robot.task.schedule_commands import PLAN_ID, ScheduleCommands
from inspection_robot.task.spec import parse_task
from inspection_robot.task.states import ENDED_STATES
from inspection_robot.task.store import StoreError
from inspection_robot.task.track import PathThinner

IDLE_WAIT_S = 0.5          # the loop looks again this often when nothing is to do (every change wakes it)
ERROR_PAUSE_S = 1.0        # the loop waits this long after a failed round (a full disk must not spin)
STEP_TIMINGS = ("find", "read")   # the parts of an inspection the step runner times, stored in this order

# patrol: task.patrol.PatrolConfig; preset_root: presets (absolute); default_retries: a task's
# retries when it names none; status_period: s, task_status republished at least this often
# translation: (language, translator) of the reports (inspection_robot.i18n), English unless given
ServiceConfig = namedtuple("ServiceConfig", "patrol data_root preset_root default_retries status_period translation",
                           defaults=(("en", ENGLISH),))


class TaskService(object):
    def __init__(self, config, store, scheduler, reachable, runner_factory, publish_status, log,
                 clock=time.time, monotonic=time.monotonic):
        """``runner_factory(current_pose)``: the step runner (``run(step, interrupted, progress)``),
        given a callable for the robot's latest pose; ``reachable``: task.checks.Reachability."""
        self._lock = threading.RLock()
        self._wake = threading.Condition(self._lock)
        self.store = store
        self._open_alarms = OpenAlarms(store, monotonic)
        self._config = config
        self._data_root = config.data_root   # answers name files relative to it; taken out of refusals
        self._reachable = reachable
        self._publish = publish_status
        self._log = log
        self._clock = clock
        self._monotonic = monotonic
        self._quiet_until = {}   # throttled log line -> monotonic time before which it is not repeated
        self._pose = None
        self._tracks = {}   # task id -> PathThinner: poses of the path it drove, not yet stored
        self._overhead_s = 0.0
        self._last_status = None
        self._last_status_time = 0.0
        self._goals = {}   # task id -> task_action goal (only tasks submitted as an action)
        self.results = ResultCommands(store, config.data_root, reachable.costmap.grid, self._lock, self._store_paths,
                                      log, clock, config.translation)
        self.patrol = Patrol(store, config.patrol, clock(), on_finished=self._on_finished)
        self._runner = runner_factory(lambda: self._pose)
        self._scheduler = scheduler
        self.schedules = ScheduleCommands(store, scheduler, self._lock, self._checked_task, log, clock)
        handlers = {
            "submit": self._submit, "pause": self._changing(self.patrol.pause),
            "resume": self._changing(self.patrol.resume),
            "cancel": self._changing(lambda data: self.patrol.cancel(data, self._clock())),
            "return_home": no_data(self._changing(lambda _data: self.patrol.return_home(self._clock()))),
            "query_status": no_data(lambda d: self._status_json()), "plan": self._plan,
        }
        handlers.update(self.results.handlers())
        handlers.update(self.schedules.handlers())
        self.table = CommandTable(handlers)

    def _log_throttled(self, period_s, level, text, key):
        """``text`` logged at most once per ``period_s`` for each ``key`` (a loop must not flood the log)."""
        now = self._monotonic()
        if now >= self._quiet_until.get(key, now):
            self._quiet_until[key] = now + period_s
            self._log(level, text)

    # --- inputs --------------------------------------------------------------------------------
    def on_robot_status(self, pose, mode):
        """robot_status: ``pose`` (x, y, yaw), None when it carried none, and the robot's mode."""
        if pose is not None:
            self._pose = pose
        with self._lock:
            active = self.patrol.active
            if self._pose is not None and active is not None:
                task_id = active.task.task_id
                track = self._tracks.get(task_id)
                if track is None:
                    track = self._tracks[task_id] = PathThinner(task_id)
                track.add(self._clock(), *self._pose)
            if mode != self.patrol.mode:
                self.patrol.set_mode(mode)
                self._changed()

    def on_virtual_map(self, width, height, resolution, data):
        """move_base's virtual obstacle cells (virtual_obstacle_map, row-major int8), checked against the map."""
        cells = np.asarray(data, dtype=np.int8)
        grid = self._reachable.costmap.grid
        if (height, width) != (grid.height, grid.width) or cells.size != grid.height * grid.width \
                or abs(resolution - grid.resolution) > 1e-9:
            self._log_throttled(30.0, "error", "virtual_obstacle_map is %dx%d at %.3f m, the map %dx%d at %.3f m: "
                                "ignored (task_manager and move_base must load the same map)"
                                % (width, height, resolution, grid.width, grid.height, grid.resolution), "virtual")
            return
        self._reachable.set_virtual(cells.reshape(grid.height, grid.width) > 0)

    def _changed(self):
        self.publish_status()
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
        preset_root, root = self._config.preset_root, self._data_root
        task = parse_task(data, lambda name: resolve_preset(preset_root, name, root), self._reachable,
                          self._config.default_retries, known, default_id)
        start, home = self._route_ends()
        plan_route(task, start, home, self._reachable.path_length)
        return task

    def _route_ends(self):
        """Where a route starts (the robot; the home pose while its pose is unknown) and ends (home)."""
        pose, home = self._pose, self.patrol.config.home_pose
        return (pose or home)[:2], home[:2]

    def _submit(self, data, goal=None):
        """Check and start a task; ``goal``: its task_action goal, accepted with it."""
        with self._lock:
            known = self.store.task_ids()
        task = self._checked_task(data, known)
        with self._lock:
            self.patrol.submit(task, self._clock())
            if goal is not None:
                goal.accept()
                self._goals[task.task_id] = goal
            self._changed()
            return self._status_json()

    # --- planning and the schedule tick (routines and schedules: task/schedule_commands.py) ----------
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

    def schedule_timer(self):
        """The schedule timer's tick: ``schedule_tick`` now, a bug logged and tried again next tick."""
        try:
            self.schedule_tick(self._clock())
        except Exception as err:  # boundary: a bug in one tick is logged, the next tick tries again
            self._log("error", "schedule tick: %s\n%s" % (err, traceback.format_exc()))

    def schedule_tick(self, now):
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
                    self._scheduler.started_run(run, self._clock())
            except BusyError:   # a task started while this one was checked: it waits on
                with self._lock:
                    self._scheduler.busy_run(run)
            except CommandError as err:
                reason = str(hide_root(err, self._data_root))
                with self._lock:
                    self._scheduler.failed_run(run, reason, self._clock())
                missed.append((run, reason))
            else:
                self._log("info", "schedule '%s' started task %s" % (run.schedule, run.task_id))
        for run, reason in missed:
            self._log("warn", "schedule '%s' missed its run of %s (task %s): %s" % (
                run.schedule, time.strftime("%Y-%m-%d %H:%M", time.localtime(run.at)), run.task_id, reason))
        if start or missed:
            with self._lock:
                self.schedules.refresh_status()
                self._changed()

    # --- task_action -----------------------------------------------------------------------------
    def action_request(self, request):
        """One task_action request, ("goal" | "cancel", goal), taken in arrival order."""
        kind, goal = request
        if kind == "goal":
            self._on_goal(goal)
        else:
            self._on_cancel(goal)

    def action_refused(self, request):
        """A request that found the queue full: a goal is rejected at once (a cancel is dropped)."""
        kind, goal = request
        if kind == "goal":
            reason = "busy: too many task_action requests waiting"
            ret_code, data = goal_refused(reason)
            goal.refuse(ret_code, data, reason)

    def _on_goal(self, goal):
        request = goal.request
        try:
            check_goal_type(request.type)
            self._submit(request.data, goal)
        except CommandError as err:
            reason = hide_root(err, self._data_root)
            ret_code, data = goal_refused(reason)
            goal.refuse(ret_code, data, reason)
            self._log("warn", "task_action goal from %s refused: %s" % (request.sender or "?", err))
        except Exception as err:  # boundary: a bug refuses this goal, the node lives on
            self._log("error", "task_action goal raised %s\n%s" % (err, traceback.format_exc()))
            ret_code, data = goal_refused(hide_root("internal error: %s" % (err,), self._data_root))
            goal.refuse(ret_code, data, "internal error")

    def _on_cancel(self, goal):
        with self._lock:
            task_id = next((t for t, g in self._goals.items() if g.id == goal.id), None)
            if task_id is None or task_id not in self.patrol.runs:
                return
            self.patrol.cancel(task_id, self._clock(), "cancelled by the action client")
            self._changed()

    def _end_goal(self, task_id, report_path):
        goal = self._goals.pop(task_id, None)
        if goal is None:
            return
        row = self.store.task(task_id)
        end, ret_code, data = goal_end(summary(row, self.store.readings(task_id=task_id, limit=10 ** 9), ()),
                                       root_relative(report_path, self._data_root))
        goal.end(end, ret_code, data, row["state"] if end == END_SUCCEEDED else row["reason"])

    def _on_finished(self, task_id):
        """A task ended: its report is written at once (a failure is logged, the patrol goes on),
        then its task_action goal, if any, ends."""
        report = ""
        try:
            report = self.results.write_report(task_id)["report.html"]
            self._log("info", "task %s ended, report %s" % (task_id, report))
        except (CommandError, OSError, StoreError) as err:   # FileError is a CommandError
            self._log("error", "cannot write the report of %s: %s" % (task_id, err))
        self._end_goal(task_id, report)

    # --- status --------------------------------------------------------------------------------
    def _status_json(self):
        status = client_progress(self.patrol.status(), self._data_root)
        status["overhead_s"] = round(self._overhead_s, 3)
        status["store"] = root_relative(self.store.path, self._data_root)
        status["open_alarms"] = self._open_alarms.count()
        status.update(self.schedules.status)
        status["time_zone"] = local_zone(self._clock(), self.schedules.scheduler.tz)
        if status["task_id"] and status["state"] in ENDED_STATES:
            status["report"] = root_relative(os.path.join(self.results.reports_dir, status["task_id"], "report.html"),
                                             self._data_root)
        return json.dumps(status, sort_keys=True)

    def status_tick(self):
        """The status timer's tick (also while a step runs, when the loop is blocked in it): task_status
        when due, and the driven paths into the store."""
        with self._lock:
            self.publish_status()
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
                    self._log_throttled(10.0, "warn", "path of %s not stored yet: %s" % (tid, err), "paths")
            if track.dropped:
                self._log("warn", "%d pose(s) of the path of %s dropped (the store took none for too long)"
                          % (track.dropped, tid))
                track.dropped = 0
            if ended and not track.pending:
                del self._tracks[tid]   # ended and stored

    def publish_status(self, force=False):
        """task_status (and each goal's feedback) when it changed, is due again, or ``force``."""
        with self._lock:
            text = self._status_json()
            now = self._monotonic()
            if force or text != self._last_status or now - self._last_status_time > self._config.status_period:
                self._publish(text)
                self._last_status, self._last_status_time = text, now
                for task_id, goal in self._goals.items():
                    progress = self.patrol.task_progress(task_id)
                    if progress is not None:
                        goal.feedback(*goal_feedback(client_progress(progress, self._data_root)))

    # --- the patrol loop -----------------------------------------------------------------------
    def spin(self, running, sleep):
        """The patrol loop while ``running()``: one step after the other; ``sleep(s)`` after a failed round."""
        while running():
            try:
                self.once()
            except StoreError as err:   # disk full, permissions: keep trying, loudly
                self._log_throttled(10.0, "error", str(err), "loop")
                sleep(ERROR_PAUSE_S)
            except Exception as err:  # boundary: the patrol loop outlives any one step
                self._log("error", "patrol loop: %s\n%s" % (err, traceback.format_exc()))
                sleep(ERROR_PAUSE_S)

    def once(self):
        """Run the next step, or wait up to IDLE_WAIT_S for a change when there is none."""
        tick = self._monotonic()
        with self._lock:
            step = self.patrol.next_step(self._clock())
            if step is None:
                self.publish_status()
                self._overhead_s += self._monotonic() - tick
                self._wake.wait(IDLE_WAIT_S)
                return
            self.publish_status()
        self._overhead_s += self._monotonic() - tick
        started = self._clock()
        self._log("info", "%s %s stop %d preset %d" % (step.task_id, step.kind, step.stop + 1, step.preset_index + 1))
        try:
            outcome, detail, timings = self._runner.run(step, lambda: self._interrupt_wanted(step),
                                                        lambda fraction: self._drive_progress(step, fraction))
        except Exception as err:  # boundary: a bug in one step fails that step, the patrol goes on
            self._log("error", "%s step raised %s\n%s" % (step.kind, err, traceback.format_exc()))
            outcome, detail, timings = OUTCOME_FAILED, "internal error: %s" % (err,), {}
        tick = self._monotonic()
        ended = self._clock()
        with self._lock:
            self.patrol.step_done(step, outcome, detail, started, ended)
            offset = started
            for kind in STEP_TIMINGS:
                if kind in timings:
                    self.store.add_step(step.task_id, step.stop, step.preset_index, kind, outcome, offset,
                                        offset + timings[kind])
                    offset += timings[kind]
            if outcome != OUTCOME_OK:
                self._log("warn", "%s %s stop %d: %s: %s" % (step.task_id, step.kind, step.stop + 1, outcome, detail))
            self._overhead_s += self._monotonic() - tick
            self.publish_status(force=True)

    def _drive_progress(self, step, fraction):
        with self._lock:   # eta_s falls with it; the status timer publishes the change
            self.patrol.drive_progress(step, fraction)

    def _interrupt_wanted(self, step):
        with self._lock:
            return self.patrol.interrupt_wanted(step)
