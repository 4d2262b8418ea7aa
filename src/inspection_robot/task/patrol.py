"""The patrol state machine of task_manager: what to do next, and what a finished step means.

Pure logic on an injected clock: no threads, no ROS. The node asks ``next_step(now)`` for one step
(drive to a stop, inspect one preset, drive home), runs it, and reports ``step_done``; while it
runs, ``interrupt_wanted(step)`` says whether to cancel it. Decisions:

- Place: a task's progress is the set of presets that have rows in the results store (read,
  uncertain or failed), so a restarted task_manager resumes exactly where the last committed
  reading left it.
- Holds (``operator``, ``charge``, ``mode``): any hold stops the patrol between presets, never
  in the middle of one (a running drive is cancelled and driven again later; a running inspection
  finishes). The task is ``paused`` once no step runs. A hold is released only by its own
  reason; the patrol runs when no hold is left. ``mode`` is held while robot_status.mode is not
  task mode (0) or not yet known; pausing never times a task out.
- After any hold or pre-emption the robot drives to its current stop again before the next
  preset (someone else may have moved it).
- A special task pre-empts a running routine one after its current preset; the routine is
  ``suspended`` and resumes at the stop it was at when the special task ends.
- Retries: a failed drive or inspection is retried ``retries`` times, ``retry_delay_s`` apart;
  then the preset (or every remaining preset of an unreachable stop) is recorded as failed with
  the reason and the patrol goes on. A failure while a hold is set counts as an interruption.
- Uncertain readings (the reader gave a value but doubts it): the preset is inspected again
  ``uncertain_retries`` times; a confident attempt is recorded as read, else the last uncertain
  values are recorded with status ``uncertain`` and the reader's reason (also when the later
  attempts fail). Outside its band such a value is a ``check`` alarm, never silence.
"""
from collections import namedtuple

from inspection_robot.command import CommandError
from inspection_robot.interface import MODE_TASK
from inspection_robot.task.spec import Task
from inspection_robot.task.states import (ALARM_ALARM, ALARM_CHECK, ALARM_NORMAL, ALARM_TREND, STATE_CANCELLED,
                                          STATE_DONE, STATE_FAILED, STATE_IDLE, STATE_PAUSED, STATE_RETURNING_HOME,
                                          STATE_RUNNING, STATE_SUSPENDED, STATUS_FAILED, STATUS_READ,
                                          STATUS_UNCERTAIN)
from inspection_robot.task.rows import reading_rows, result_summary
from inspection_robot.task.trend import DEFAULT_TREND, trend_text, trend_warning
from inspection_robot.thermal.diagnosis import DEFAULT_RULES

HOLD_OPERATOR = "operator"
HOLD_CHARGE = "charge"
HOLD_MODE = "mode"
HOLD_BY_DATA = {"": HOLD_OPERATOR, "charge": HOLD_CHARGE}
PERSISTENT_HOLDS = (HOLD_OPERATOR, HOLD_CHARGE)

STEP_MOVE = "move"
STEP_INSPECT = "inspect"
STEP_HOME = "home"

OUTCOME_OK = "ok"
OUTCOME_FAILED = "failed"
OUTCOME_INTERRUPTED = "interrupted"

# task_status fields of an ended task kept until the next task or return_home (eta_s is 0 then)
FINAL_PROGRESS_KEYS = ("priority", "stop", "stops", "stop_name", "preset", "presets", "done", "total",
                       "planned_length_m")

# kind: move | inspect | home; stop / preset_index are 0-based (-1 when not applicable); preset: the
# task's preset entry {"preset", "directory", "targets", "alarms", "foreign"} of an inspection
Step = namedtuple("Step", "kind task_id stop preset_index x y yaw precision preset")


def turns_to_yaw(step, turn_at_stops):
    """Whether a drive ends turned to the step's yaw (move_action with_direction). The home pose (the
    dock lines up on it) and precision stops always; other stops only with ``turn_at_stops``: find_scale
    adds the difference between the preset's recorded heading and the robot's to the pan, so the head
    turns instead of the robot, which on this chassis saves a stop, two wheel switches (1 s each) and
    the spin itself (bench/patrol_drive.py)."""
    return step.kind == STEP_HOME or bool(step.precision) or bool(turn_at_stops)


# what the node measured: values/confidences/pictures per target (calibration order), pose (x, y, yaw)
# or None, optionally foreign = (count, confidence, picture), reasons: per target "" or why the reader
# doubts the value (read_scale's "uncertain: box <i>: <why>"), sources: per target the picture read
# and its box (8 numbers), or None when not known
Inspection = namedtuple("Inspection", "values confidences pictures pose foreign reasons sources")
Inspection.__new__.__defaults__ = (None, None, None)
# uncertain_retries: inspections again of a preset read uncertain before its uncertain values are kept
# thermal_rules: grade rules per equipment class (thermal.diagnosis.check_rules)
PatrolConfig = namedtuple("PatrolConfig", "retry_delay_s home_pose move_estimate_s preset_estimate_s "
                                          "uncertain_retries trend thermal_rules",
                          defaults=(DEFAULT_TREND, DEFAULT_RULES))


class BusyError(CommandError):
    """A task cannot start now (another runs, or the robot returns home): a scheduled run waits."""


class TaskRun(object):
    """One task's place: the presets done, the stop the robot stands at, attempts of the current step."""

    def __init__(self, task, done):
        self.task = task
        self.done = set(done)
        self.at_stop = None
        self.attempts = {}
        self.uncertain = {}         # (stop, preset_index) -> (tries, the last uncertain Inspection)
        self.retry_at = None
        self.last_result = None     # result_summary of this task's last recorded preset

    def remaining(self):
        return [k for k in self.task.preset_keys() if k not in self.done]

    def next_key(self):
        remaining = self.remaining()
        return remaining[0] if remaining else None


class Patrol(object):
    def __init__(self, store, config, now, on_finished=None):
        self.store = store
        self.config = config
        self._on_finished = on_finished or (lambda task_id: None)
        self.holds = set(h for h in store.get_meta("holds", []) if h in PERSISTENT_HOLDS)
        self.holds.add(HOLD_MODE)   # until robot_status says task mode
        self.mode = None
        self.runs = {}              # task id -> TaskRun (the active one and a suspended routine)
        self.active = None
        self.suspended = None
        self.running = None
        self.running_fraction = 0.0  # share of the running drive already driven (move_action feedback)
        self.returning_home = False
        self.home_error = ""
        self.last_result = None
        self.last_task = None       # (task id, state, reason) of the last finished task
        self.last_progress = {}     # its progress fields when it ended (task_status keeps them)
        self.home_reached = False   # return_home arrived after last_task ended: task_status is idle
        self._durations = {STEP_MOVE: [], STEP_INSPECT: []}
        self._recover(now)

    # --- restart recovery ------------------------------------------------------------------------
    def _recover(self, now):
        for row in self.store.unfinished_tasks():
            run = TaskRun(Task.from_dict(row["spec"]), self.store.done_presets(row["task_id"]))
            self.runs[run.task.task_id] = run
            if row["state"] == STATE_SUSPENDED or (self.active is not None and not run.task.special):
                self._suspend(run)
            else:
                if self.active is not None:
                    self._suspend(self.active)
                self.active = run
        if self.active is None and self.suspended is not None:
            self.active, self.suspended = self.suspended, None
            self.store.set_task_state(self.active.task.task_id, STATE_RUNNING)
        self._advance(now)

    def _suspend(self, run):
        run.at_stop = None
        self.suspended = run
        self.store.set_task_state(run.task.task_id, STATE_SUSPENDED)

    # --- commands ------------------------------------------------------------------------------
    def submit(self, task, now):
        """Start ``task`` (checked by spec.parse_task); a special one pre-empts a routine one."""
        if self.returning_home:
            raise BusyError("busy: returning home")
        if task.task_id in self.store.task_ids():   # two submissions of one id racing
            raise CommandError("duplicate task id '%s' (ids are never reused)" % task.task_id)
        if self.active is not None:
            if not task.special or self.active.task.special:
                raise BusyError("busy: task '%s' is running (cancel it first)" % self.active.task.task_id)
            self.store.add_task(task, STATE_RUNNING, now)
            self._suspend(self.active)
        else:
            self.store.add_task(task, STATE_RUNNING, now)
        run = TaskRun(task, ())
        self.runs[task.task_id] = run
        self.active = run
        self.last_task = None

    def pause(self, data):
        hold = self._hold_for(data)
        if hold == HOLD_OPERATOR and self.active is None and not self.returning_home:
            raise CommandError("no task to pause")
        self._add_hold(hold)

    def resume(self, data):
        hold = self._hold_for(data)
        if hold in self.holds:
            self.holds.discard(hold)
            self._save_holds()

    @staticmethod
    def _hold_for(data):
        if data not in HOLD_BY_DATA:
            raise CommandError("data must be '' (operator) or 'charge', got '%s'" % (data[:40],))
        return HOLD_BY_DATA[data]

    def _add_hold(self, hold):
        if hold not in self.holds:
            self.holds.add(hold)
            for run in self.runs.values():
                run.at_stop = None   # the robot may be moved while held: drive to the stop again
            self._save_holds()

    def _save_holds(self):
        self.store.set_meta("holds", sorted(h for h in self.holds if h in PERSISTENT_HOLDS))

    def set_mode(self, mode):
        self.mode = mode
        if mode == MODE_TASK:
            self.holds.discard(HOLD_MODE)
        else:
            self._add_hold(HOLD_MODE)

    def cancel(self, task_id, now, reason="cancelled by the backend"):
        """Cancel ``task_id`` ("" = the active task); a suspended routine then resumes."""
        run = self.active if task_id == "" else self.runs.get(task_id)
        if run is None:
            raise CommandError("no task to cancel" if task_id == "" else "no running or suspended task '%s'" % task_id)
        self._end(run, STATE_CANCELLED, reason, now)

    def return_home(self, now):
        """Cancel every task and drive to the home pose (the operator hold is released)."""
        for run in [r for r in (self.active, self.suspended) if r is not None]:
            self._end(run, STATE_CANCELLED, "return home", now)
        self.returning_home = True
        self.home_error = ""
        if HOLD_OPERATOR in self.holds:
            self.holds.discard(HOLD_OPERATOR)
            self._save_holds()

    # --- stepping ------------------------------------------------------------------------------
    def next_step(self, now):
        """The step to run now, or None (nothing to do, held, waiting to retry, a step running)."""
        if self.running is not None:
            return None
        if self.returning_home:
            if HOLD_MODE in self.holds or HOLD_CHARGE in self.holds:
                return None
            x, y, yaw = self.config.home_pose
            self.running = Step(STEP_HOME, "", -1, -1, x, y, yaw, 0, None)
            return self.running
        run = self.active
        if run is None or self.holds or (run.retry_at is not None and now < run.retry_at):
            return None
        key = run.next_key()
        if key is None:
            return None
        stop = run.task.stops[key[0]]
        if run.at_stop != key[0]:
            self.running = Step(STEP_MOVE, run.task.task_id, key[0], -1, stop["x"], stop["y"], stop["yaw"],
                                stop["precision"], None)
        else:
            preset = stop["presets"][key[1]]
            self.running = Step(STEP_INSPECT, run.task.task_id, key[0], key[1], stop["x"], stop["y"], stop["yaw"],
                                stop["precision"], preset)
        return self.running

    def interrupt_wanted(self, step):
        """True when the running ``step`` should be cancelled now (never an inspection for a hold)."""
        if step.kind == STEP_HOME:
            return not self.returning_home or HOLD_MODE in self.holds or HOLD_CHARGE in self.holds
        if step.task_id not in self.runs:
            return True   # cancelled
        if step.kind == STEP_MOVE:
            return bool(self.holds) or self.active is None or self.active.task.task_id != step.task_id
        return False

    def drive_progress(self, step, fraction):
        """The running drive ``step`` has driven ``fraction`` (0..1) of its planned path: eta_s counts
        only the rest of it, so the ETA falls during a drive instead of standing still."""
        if step is self.running and step.kind == STEP_MOVE and fraction == fraction:
            self.running_fraction = min(1.0, max(0.0, float(fraction)))

    def step_done(self, step, outcome, detail, started, now):
        """Record the end of ``step``: outcome ok (detail: an Inspection for inspect steps), failed
        (detail: the reason) or interrupted. Readings are committed before this returns."""
        if step is self.running:
            self.running = None
            self.running_fraction = 0.0
        reason = detail if outcome != OUTCOME_OK else ""
        self.store.add_step(step.task_id, step.stop, step.preset_index, step.kind, outcome, started, now, reason)
        if outcome == OUTCOME_OK:
            self._durations.setdefault(step.kind, []).append(now - started)
        if step.kind == STEP_HOME:
            self._home_done(outcome, reason)
            return
        run = self.runs.get(step.task_id)
        if run is None:
            return   # cancelled meanwhile; nothing more to record
        if outcome == OUTCOME_FAILED and self.holds:
            outcome = OUTCOME_INTERRUPTED   # e.g. the drive gave up while someone else held the robot
        if outcome == OUTCOME_OK:
            run.attempts.clear()
            run.retry_at = None
            if step.kind == STEP_MOVE:
                run.at_stop = step.stop
            elif not self._uncertain_again(run, step, detail, now):
                run.uncertain.pop((step.stop, step.preset_index), None)
                self._record(run, step.stop, step.preset_index, detail, "", now)
        elif outcome == OUTCOME_FAILED:
            self._failed(run, step, reason, now)
        self._advance(now)

    def _uncertain_again(self, run, step, inspection, now):
        """True when an inspection with uncertain values is to be tried again (``uncertain_retries``
        times per preset, ``retry_delay_s`` apart); the last uncertain one is kept meanwhile, to be
        recorded if the next attempts fail."""
        if not any(inspection.reasons or ()):
            return False
        key = (step.stop, step.preset_index)
        tries = run.uncertain.get(key, (0, None))[0]
        if tries >= self.config.uncertain_retries:
            return False
        run.uncertain[key] = (tries + 1, inspection)
        run.retry_at = now + self.config.retry_delay_s
        return True

    def _failed(self, run, step, reason, now):
        key = (step.kind, step.stop, step.preset_index)
        run.attempts[key] = run.attempts.get(key, 0) + 1
        if run.attempts[key] <= run.task.retries:
            run.retry_at = now + self.config.retry_delay_s
            return
        run.attempts.pop(key)
        run.retry_at = None
        if step.kind == STEP_MOVE:
            for i, j in run.remaining():
                if i == step.stop:
                    self._record(run, i, j, None, "stop unreachable: %s" % reason, now)
        else:
            # an earlier attempt's uncertain values are better than none
            kept = run.uncertain.pop((step.stop, step.preset_index), (0, None))[1]
            self._record(run, step.stop, step.preset_index, kept, "" if kept else reason, now)

    def _home_done(self, outcome, reason):
        if outcome == OUTCOME_OK:
            self.returning_home = False
            self.home_reached = True
        elif outcome == OUTCOME_FAILED and not (HOLD_MODE in self.holds or HOLD_CHARGE in self.holds):
            self.returning_home = False
            self.home_error = reason

    def _record(self, run, stop_index, preset_index, inspection, reason, now):
        stop = run.task.stops[stop_index]
        rows = reading_rows(run.task.task_id, stop_index, stop["name"], preset_index, stop["presets"][preset_index],
                            inspection, reason, now, self.config.thermal_rules)
        targets = stop["presets"][preset_index]["targets"]
        for row in rows:
            if row["target"] < len(targets) and targets[row["target"]].get("counter"):
                self._mark_counter(row)   # a count rises by design: its increment, not its trend, matters
            else:
                self._mark_trend(row)
        self.store.add_readings(rows)   # committed before it is announced
        run.done.add((stop_index, preset_index))
        self.last_result = run.last_result = result_summary(rows)

    def _mark_counter(self, row):
        """A counter's increment since its previous reading; a count that went down (it never should:
        a replaced counter, a misreading) is an alarm, a ``check`` when the reading is uncertain."""
        if row["value"] is None:
            return
        previous = self.store.meter_values(row["target_name"], row["time"], 1)
        if not previous:
            return
        row["increment"] = row["value"] - previous[0][1]
        if row["increment"] < 0:
            row["alarm"] = ALARM_CHECK if row["status"] == STATUS_UNCERTAIN else ALARM_ALARM
            words = ("counter went down from %g to %g since its previous reading (it never should: replaced, "
                     "or misread)" % (previous[0][1], row["value"]))
            row["reason"] = "%s; %s" % (words, row["reason"]) if row["reason"] else words

    def _mark_trend(self, row):
        """A normal reading whose meter drifts toward its band becomes a ``trend`` warning (task/trend.py)."""
        if row["status"] != STATUS_READ or row["alarm"] != ALARM_NORMAL:
            return
        history = self.store.meter_values(row["target_name"], row["time"], self.config.trend.window - 1)
        warning = trend_warning(history + [(row["time"], row["value"])], (row["low"], row["high"]), self.config.trend)
        if warning is not None:
            row["alarm"] = ALARM_TREND
            row["reason"] = trend_text(warning, row["unit"])

    def _advance(self, now):
        run = self.active
        if run is not None and run.next_key() is None:
            counts = [r["status"] for r in self.store.readings(task_id=run.task.task_id, limit=1000000)]
            failed_all = counts and all(s == STATUS_FAILED for s in counts)
            self._end(run, STATE_FAILED if failed_all else STATE_DONE,
                      "every preset failed" if failed_all else "", now)

    def _end(self, run, state, reason, now):
        task_id = run.task.task_id
        self.runs.pop(task_id, None)
        self.store.set_task_state(task_id, state, reason, ended=now)
        if run is self.suspended:
            self.suspended = None
        if run is self.active:
            self.active = None
            if self.suspended is not None:
                self.active, self.suspended = self.suspended, None
                self.active.at_stop = None
                self.store.set_task_state(self.active.task.task_id, STATE_RUNNING)
        self.last_task = (task_id, state, reason)
        self.last_progress = dict((k, v) for k, v in self._progress(run).items() if k in FINAL_PROGRESS_KEYS)
        self.home_reached = False
        self._on_finished(task_id)
        self._advance(now)

    # --- status --------------------------------------------------------------------------------
    def status(self):
        """The task_status dict (see docs/interface.md, Patrol)."""
        out = {"task_id": "", "priority": "", "state": STATE_IDLE, "holds": sorted(self.holds), "stop": 0,
               "stops": 0, "stop_name": "", "preset": 0, "presets": 0, "done": 0, "total": 0,
               "last_result": self.last_result, "eta_s": 0.0,
               "suspended": self.suspended.task.task_id if self.suspended else "", "reason": "",
               "last_ended": None if self.last_task is None else dict(zip(("task_id", "state", "reason"),
                                                                          self.last_task))}
        if self.returning_home:
            out["state"] = STATE_RETURNING_HOME
            return out
        if self.active is None:
            if self.last_task is not None and not self.home_reached:
                out.update(self.last_progress)   # the console's progress bar stays full for a done task
                out["task_id"], out["state"], out["reason"] = self.last_task
            elif self.home_error:
                out["reason"] = "return home failed: %s" % self.home_error
            return out
        out.update(self._progress(self.active))
        out["last_result"] = self.last_result
        return out

    def task_progress(self, task_id):
        """The task_status fields of one running or suspended task (its own last_result; ``reason``
        says who pre-empted a suspended one), or None when it is neither."""
        run = self.runs.get(task_id)
        if run is None:
            return None
        out = {"holds": sorted(self.holds), "reason": ""}
        out.update(self._progress(run))
        if run is self.suspended:
            out["state"] = STATE_SUSPENDED
            if self.active is not None:
                out["reason"] = "pre-empted by special task '%s'" % self.active.task.task_id
                out["eta_s"] = round(out["eta_s"] + self._eta(self.active), 1)
        return out

    def _progress(self, run):
        keys = run.task.preset_keys()
        key = run.next_key() or keys[-1]
        stop = run.task.stops[key[0]]
        return {"task_id": run.task.task_id, "priority": run.task.priority,
                "state": STATE_PAUSED if self.holds and self.running is None else STATE_RUNNING,
                "stop": key[0] + 1, "stops": len(run.task.stops), "stop_name": stop["name"], "preset": key[1] + 1,
                "presets": len(stop["presets"]), "done": len(run.done), "total": len(keys),
                "last_result": run.last_result, "eta_s": round(self._eta(run), 1),
                "planned_length_m": run.task.planned_length_m}

    def _eta(self, run):
        remaining = run.remaining()
        moves = len(set(i for i, _j in remaining)) - (1 if remaining and run.at_stop == remaining[0][0] else 0)
        driving = self.running is not None and self.running.kind == STEP_MOVE and \
            self.running.task_id == run.task.task_id
        moves -= self.running_fraction if driving else 0.0   # the driven part of the running drive
        return moves * self._mean(STEP_MOVE, self.config.move_estimate_s) + \
            len(remaining) * self._mean(STEP_INSPECT, self.config.preset_estimate_s)

    def _mean(self, kind, default):
        values = self._durations.get(kind) or []
        return sum(values[-20:]) / len(values[-20:]) if values else default
