"""task_control's routines and schedules: save, list and delete them, and the schedule keys of
task_status. Pure Python (part of task.service.TaskService, which serves these handlers and runs
the schedule tick that starts the due runs; the rules are task/schedule.py's)."""
import json

from inspection_robot.command import CommandError, no_data
from inspection_robot.task.schedule import next_run, parse_routine, parse_schedule, routine_task

PLAN_ID = "plan"   # the id a task is checked with when it has none (plan, routine_save)


class ScheduleCommands(object):
    """``lock``: the service's; ``check_task(task_json)``: every submission check of a task (a
    routine is saved only when it would be accepted now)."""

    def __init__(self, store, scheduler, lock, check_task, log, clock):
        self._store = store
        self.scheduler = scheduler
        self._lock = lock
        self._check_task = check_task
        self._log = log
        self._clock = clock
        self.status = {}   # task_status's schedule keys (kept here: task_status is built often, the store asked rarely)
        self.refresh_status()

    def handlers(self):
        """task_control's commands of routines and schedules, name -> handler."""
        return {"routine_save": self._routine_save, "routine_list": no_data(self._routine_list),
                "routine_delete": self._routine_delete, "schedule_set": self._schedule_set,
                "schedule_list": no_data(self._schedule_list), "schedule_delete": self._schedule_delete}

    def _routine_save(self, data):
        name, task = parse_routine(data)
        self._check_task(json.dumps(routine_task(task, PLAN_ID)))
        with self._lock:
            routine = self._store.save_routine(name, task, self._clock())
        self._log("info", "routine '%s' saved (%d stops)" % (name, len(task.get("stops", []))))
        return json.dumps(routine, sort_keys=True)

    def _routine_list(self, _data):
        return json.dumps(self._store.routines(), sort_keys=True)

    def _routine_delete(self, data):
        with self._lock:
            if self._store.routine(data) is None:
                raise CommandError("unknown routine '%s'" % data[:64])
            users = [s["name"] for s in self._store.schedules() if s["routine"] == data]
            if users:
                raise CommandError("routine '%s' is used by schedule(s) %s" % (data, ", ".join(users)))
            self._store.delete_routine(data)
        return json.dumps({"deleted": data})

    def _schedule_set(self, data):
        with self._lock:
            now = self._clock()
            schedule = parse_schedule(data, set(r["name"] for r in self._store.routines()), now,
                                      self.scheduler.tz)
            self._store.set_schedule(schedule, now)
            self.scheduler.forget(schedule["name"])
            self.refresh_status()
            row = next(r for r in self._schedule_rows(now) if r["name"] == schedule["name"])
        self._log("info", "schedule '%s' set: %s" % (schedule["name"], json.dumps(schedule)))
        return json.dumps(row, sort_keys=True)

    def _schedule_list(self, _data):
        with self._lock:
            return json.dumps(self._schedule_rows(self._clock()), sort_keys=True)

    def _schedule_delete(self, data):
        with self._lock:
            if not self._store.delete_schedule(data):
                raise CommandError("unknown schedule '%s'" % data[:64])
            self.scheduler.forget(data)
            self.refresh_status()
        return json.dumps({"deleted": data})

    def _schedule_rows(self, now):
        """schedule_list's rows: each schedule with its next run, last run and missed runs."""
        rows = []
        for s in self._store.schedules():
            row = dict((k, s[k]) for k in ("name", "routine", "time", "weekdays", "date", "enabled") if k in s)
            row["next_run"] = next_run(s, max(now, s["set_at"]), self.scheduler.tz) if s["enabled"] else None
            task = self._store.task(s["last_task_id"]) if s["last_task_id"] else None
            row["last_run"] = None if s["last_at"] is None else {
                "at": s["last_at"], "task_id": s["last_task_id"], "state": task["state"] if task else ""}
            row["missed"] = [{"at": m["at"], "reason": m["reason"]} for m in self._store.missed_runs(s["name"])]
            rows.append(row)
        return rows

    def refresh_status(self):
        """Recompute task_status's schedule keys (after a schedule changed or a run started or was missed)."""
        now = self._clock()
        upcoming = [(next_run(s, max(now, s["set_at"]), self.scheduler.tz), s["name"], s["routine"])
                    for s in self._store.schedules() if s["enabled"]]
        upcoming = sorted(u for u in upcoming if u[0] is not None)
        last = self._store.missed_runs(limit=1)
        self.status = {
            "missed_runs": self._store.get_meta("missed_runs", 0), "last_missed": last[0] if last else None,
            "next_scheduled": {"at": upcoming[0][0], "schedule": upcoming[0][1], "routine": upcoming[0][2]}
            if upcoming else None}
