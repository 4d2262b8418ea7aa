"""task_control's results side: stored tasks and readings, the review queue and reviews, result
snapshots and reports. Pure Python (part of task.service.TaskService, which serves these handlers).

Files, under the data root: reports in tasks/reports/<task_id>/, snapshots for the backend in
tasks/exports/, review corrections in corrections/; answers name them relative to the data root
(task.client_view).
"""
import json
import os

from inspection_robot.command import CommandError, no_data
from inspection_robot.files import root_relative
from inspection_robot.i18n import ENGLISH
from inspection_robot.task.alarms import ALARM_STATES, acknowledge, parse_alarms_query
from inspection_robot.task.client_view import client_row
from inspection_robot.task.report import write_reports
from inspection_robot.task.review import parse_query, review
from inspection_robot.task.spec import check_task_id
from inspection_robot.task.store import StoreError, export_snapshot
from inspection_robot.version import version

QUERY_KEYS = ("task_id", "target", "from", "to", "after_id", "limit")
REVIEW_QUEUE_KEYS = ("task_id", "limit")
REPORT_TREND_POINTS = 20   # a meter's readings up to this task's drawn beside each of its readings in the report


class ResultCommands(object):
    """``lock``: the service's (a review, and the path stored before a report, run under it);
    ``store_path(task_id)``: stores the task's driven path kept so far, so its report draws all of it;
    ``grid``: the map the reports draw the yard on; ``translation``: (language, translator) of the
    reports' words (inspection_robot.i18n)."""

    def __init__(self, store, data_root, grid, lock, store_path, log, clock, translation=("en", ENGLISH)):
        self._store = store
        self._data_root = data_root
        self.reports_dir = os.path.join(data_root, "tasks", "reports")
        self._exports_dir = os.path.join(data_root, "tasks", "exports")
        self._corrections_dir = os.path.join(data_root, "corrections")
        self._grid = grid
        self._lock = lock
        self._store_path = store_path
        self._log = log
        self._clock = clock
        self._language, self._tr = translation

    def handlers(self):
        """task_control's commands of the results side, name -> handler."""
        return {"query_tasks": no_data(self._query_tasks), "query_results": self._query_results,
                "report": self._report, "review_queue": self._review_queue, "review": self._review,
                "export_results": no_data(self._export_results), "alarms": self._alarms,
                "acknowledge": self._acknowledge}

    def _query_tasks(self, _data):
        return json.dumps([{"task_id": t["task_id"], "priority": t["priority"], "state": t["state"],
                            "reason": t["reason"], "submitted": t["submitted"], "ended": t["ended"]}
                           for t in self._store.tasks()])

    def _query_results(self, data):
        query = parse_query(data, QUERY_KEYS, 1000)
        return json.dumps([client_row(r, self._data_root) for r in self._store.readings(
            query.get("task_id"), query.get("from"), query.get("to"), query["limit"], query.get("target"),
            query.get("after_id"))])

    def _review_queue(self, data):
        query = parse_query(data, REVIEW_QUEUE_KEYS, 100)
        return json.dumps([client_row(r, self._data_root)
                           for r in self._store.review_queue(query.get("task_id"), query["limit"])])

    def _review(self, data):
        with self._lock:   # one review at a time: two for one row must not race over its file
            try:
                row, path = review(self._store, self._corrections_dir, data, self._clock())
            except StoreError as err:
                raise CommandError(str(err))
        self._log("info", "reading %d reviewed by %s: %s (robot %s), %s" % (
            row["id"], row["review_by"], row["review_value"], row["value"], path))
        return json.dumps(dict(client_row(row, self._data_root), correction=root_relative(path, self._data_root)))

    def _alarms(self, data):
        task_id, acknowledged, limit = parse_alarms_query(data)
        return json.dumps([client_row(r, self._data_root)
                           for r in self._store.alarm_rows(ALARM_STATES, task_id, acknowledged, limit)])

    def _acknowledge(self, data):
        with self._lock:
            try:
                row = acknowledge(self._store, data, self._clock())
            except StoreError as err:
                raise CommandError(str(err))
        note = ": " + row["ack_note"] if row["ack_note"] else ""
        self._log("info", "alarm of reading %d (%s, %s) acknowledged by %s%s"
                  % (row["id"], row["target_name"], row["alarm"], row["ack_by"], note))
        return json.dumps(client_row(row, self._data_root))

    def _export_results(self, _data):
        """A consistent snapshot of the results store for file_control (the live file's latest
        commits sit in its -wal)."""
        try:
            path = export_snapshot(self._store, self._exports_dir, self._clock())
        except StoreError as err:
            raise CommandError(str(err))
        return json.dumps({"path": root_relative(path, self._data_root), "size": os.path.getsize(path)},
                          sort_keys=True)

    def _report(self, data):
        if self._store.task(data) is None:
            raise CommandError("unknown task '%s'" % data[:64])
        try:
            return json.dumps(dict((name, root_relative(path, self._data_root))
                                   for name, path in self.write_report(data).items()))
        except OSError as err:
            raise CommandError("cannot write the report: %s" % err)

    def write_report(self, task_id):
        """Write the task's report files; returns file name -> path."""
        # the id names the folder: an id stored before ids were restricted ('..') must not escape reports/
        folder = os.path.join(self.reports_dir, check_task_id(task_id))
        with self._lock:
            self._store_path(task_id)
        readings = self._store.readings(task_id=task_id, limit=10 ** 9)
        return write_reports(folder, self._store.task(task_id), readings, self._store.steps(task_id), self._data_root,
                             version(), self._store.meter_histories(readings, REPORT_TREND_POINTS),
                             self._store.driven_path(task_id), self._grid, self._tr, self._language)
