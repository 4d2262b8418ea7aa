"""The results store: one SQLite file (stdlib sqlite3) holding tasks, readings and step timings.

The file, its -wal and -shm are mode 600 (private_database), whatever the umask.

Crash safety: WAL journal with ``synchronous=FULL``, so a committed transaction survives a killed
process and a power cut; a reading is committed before anyone is told about it. Readings carry a
UNIQUE (task_id, stop, preset_index, target) key: the patrol state machine derives what is left to
do from the store itself (a preset with rows is done), so a restarted task_manager neither repeats
nor loses a reading. One connection shared under a lock (the node's threads are few and short).

Schema changes: columns added after the first release (ADDED_COLUMNS) are added to an older file
when it is opened (``ALTER TABLE ... ADD COLUMN`` in one transaction), so every store opens; old
rows get the columns' defaults (no source picture, not reviewed, no resolution). Tables added
since (routines, schedules, missed_runs; ``poses``: the path a task drove, task.track) are created
when missing (``CREATE TABLE IF NOT EXISTS``): an older task has no path; an older task_manager
ignores them.

The live file is not what a backend should copy: its latest commits sit in ``results.sqlite-wal``
until a checkpoint. ``export`` writes a consistent snapshot (sqlite3's online backup API) as a
plain single file, which file_control serves (docs/interface.md, "Results store and reports").
"""
import json
import os
import sqlite3
import tempfile
import threading
import time

from inspection_robot.files import PUBLIC_FILE_MODE, FileError, fsync_dir, rename_durable

from inspection_robot.task.states import STATUS_READ, STATUS_UNCERTAIN, UNFINISHED_STATES

SCHEMA = """
CREATE TABLE IF NOT EXISTS tasks (
    task_id TEXT PRIMARY KEY, priority TEXT NOT NULL, spec TEXT NOT NULL, state TEXT NOT NULL,
    reason TEXT NOT NULL DEFAULT '', submitted REAL NOT NULL, ended REAL, seq INTEGER NOT NULL);
CREATE TABLE IF NOT EXISTS readings (
    id INTEGER PRIMARY KEY AUTOINCREMENT, task_id TEXT NOT NULL, stop INTEGER NOT NULL,
    stop_name TEXT NOT NULL, preset_index INTEGER NOT NULL, preset TEXT NOT NULL, target INTEGER NOT NULL,
    target_name TEXT NOT NULL, kind TEXT NOT NULL, status TEXT NOT NULL, value REAL, unit TEXT NOT NULL,
    alarm TEXT NOT NULL, low REAL, high REAL, confidence REAL, picture TEXT NOT NULL,
    x REAL, y REAL, yaw REAL, time REAL NOT NULL, reason TEXT NOT NULL,
    UNIQUE (task_id, stop, preset_index, target));
CREATE TABLE IF NOT EXISTS steps (
    id INTEGER PRIMARY KEY AUTOINCREMENT, task_id TEXT NOT NULL, stop INTEGER NOT NULL,
    preset_index INTEGER NOT NULL, kind TEXT NOT NULL, outcome TEXT NOT NULL, started REAL NOT NULL,
    ended REAL NOT NULL, reason TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS routines (name TEXT PRIMARY KEY, task TEXT NOT NULL, saved REAL NOT NULL);
CREATE TABLE IF NOT EXISTS schedules (
    name TEXT PRIMARY KEY, spec TEXT NOT NULL, set_at REAL NOT NULL, last_at REAL, last_task_id TEXT);
CREATE TABLE IF NOT EXISTS missed_runs (
    id INTEGER PRIMARY KEY AUTOINCREMENT, schedule TEXT NOT NULL, at REAL NOT NULL, reason TEXT NOT NULL,
    noted REAL NOT NULL);
CREATE TABLE IF NOT EXISTS poses (
    id INTEGER PRIMARY KEY AUTOINCREMENT, task_id TEXT NOT NULL, time REAL NOT NULL, x REAL NOT NULL,
    y REAL NOT NULL, yaw REAL NOT NULL);
"""
# readings columns added since the first schema, with their declarations: the picture read and its
# box (for the bench's field set), the operator's review of an uncertain value (true value or the
# robot's own when confirmed, its alarm, who, when); the decimal places the value is shown with
# (its meter's resolution when read, task.display; null in older rows); a thermal phase's defect grade
# and its device's diagnosis (JSON, task.rows); an operator's acknowledgement of the row's alarm
# (task.alarms: who, when, a note); a counter's increment since its previous reading (task.patrol); the
# alarm band around the normal one (low, high), between which a value is a warning (task.spec.parse_limits)
ADDED_COLUMNS = (("source_picture", "TEXT NOT NULL DEFAULT ''"), ("roi", "TEXT NOT NULL DEFAULT ''"),
                 ("review_value", "REAL"), ("review_alarm", "TEXT NOT NULL DEFAULT ''"),
                 ("review_by", "TEXT NOT NULL DEFAULT ''"), ("review_time", "REAL"), ("decimals", "INTEGER"),
                 ("grade", "TEXT NOT NULL DEFAULT ''"), ("diagnosis", "TEXT NOT NULL DEFAULT ''"),
                 ("ack_by", "TEXT NOT NULL DEFAULT ''"), ("ack_time", "REAL"), ("ack_note", "TEXT NOT NULL DEFAULT ''"),
                 ("increment", "REAL"), ("alarm_low", "REAL"), ("alarm_high", "REAL"))
INDEXES = """
CREATE INDEX IF NOT EXISTS readings_time ON readings (time);
CREATE INDEX IF NOT EXISTS readings_review ON readings (status, review_time);
CREATE INDEX IF NOT EXISTS readings_meter ON readings (target_name, time);
CREATE INDEX IF NOT EXISTS poses_task ON poses (task_id, id);
"""
READING_COLUMNS = ("id", "task_id", "stop", "stop_name", "preset_index", "preset", "target", "target_name", "kind",
                   "status", "value", "unit", "alarm", "low", "high", "confidence", "picture", "x", "y", "yaw",
                   "time", "reason") + tuple(name for name, _ in ADDED_COLUMNS)
# what a patrol writes (the review and acknowledgement columns are written by set_review and acknowledge only)
WRITTEN_COLUMNS = tuple(c for c in READING_COLUMNS[1:] if not c.startswith(("review_", "ack_")))
# a row's alarm as the report states it (task.report.reading_state): the reviewed value's once reviewed
STATED_ALARM_SQL = "(CASE WHEN review_time IS NOT NULL AND review_alarm != '' THEN review_alarm ELSE alarm END)"
OPTIONAL_COLUMNS = {"decimals": None, "grade": "", "diagnosis": "", "increment": None, "alarm_low": None,
                    "alarm_high": None}   # a row may leave out
STEP_COLUMNS = ("task_id", "stop", "preset_index", "kind", "outcome", "started", "ended", "reason")
EXPORTS_KEPT = 10   # snapshots kept in tasks/exports/ (the oldest removed beyond)


def _optional(row, column):
    value = row.get(column)
    return OPTIONAL_COLUMNS[column] if value is None else value


class StoreError(Exception):
    """The store cannot be opened or written (disk full, permissions, corrupt file)."""


PRIVATE_FILE_MODE = 0o600   # the store and its -wal, -shm: the robot user's (docs/interface.md, "File modes")
SQLITE_SIDE_FILES = ("-wal", "-shm", "-journal")


def private_database(path):
    """Create ``path`` (empty) mode 600 when missing, and take group and other access away from it and
    its journal files when present: SQLite creates a database with the process umask (644 by
    default) and its -wal and -shm with the database's mode, so the database's mode decides all."""
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, PRIVATE_FILE_MODE)
        os.close(fd)
        for name in (path,) + tuple(path + suffix for suffix in SQLITE_SIDE_FILES):
            if os.path.exists(name) and os.stat(name).st_mode & 0o077:
                os.chmod(name, PRIVATE_FILE_MODE)
    except OSError as err:
        raise StoreError("cannot open the results store %s: %s" % (path, err.strerror or err))


class ResultStore(object):
    def __init__(self, path):
        self.path = path
        self._lock = threading.Lock()
        self.commits = 0   # transactions committed by this process: a cache of a count knows when to ask again
        private_database(path)
        try:
            self._db = sqlite3.connect(path, check_same_thread=False, isolation_level=None, timeout=10.0)
            self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute("PRAGMA synchronous=FULL")
            self._db.executescript(SCHEMA)
            self._migrate()
            self._db.executescript(INDEXES)
        except sqlite3.Error as err:
            raise StoreError("cannot open the results store %s: %s" % (path, err))

    def _migrate(self):
        """Add the ADDED_COLUMNS an older store lacks, all or none."""
        have = set(row[1] for row in self._db.execute("PRAGMA table_info(readings)"))
        missing = [(name, declaration) for name, declaration in ADDED_COLUMNS if name not in have]
        if not missing:
            return
        self._db.execute("BEGIN IMMEDIATE")
        try:
            for name, declaration in missing:
                self._db.execute("ALTER TABLE readings ADD COLUMN %s %s" % (name, declaration))
            self._db.execute("COMMIT")
        except sqlite3.Error:
            self._db.execute("ROLLBACK")
            raise

    def close(self):
        with self._lock:
            self._db.close()

    def _write(self, statements):
        """Run [(sql, params)] in one transaction; returns the number of rows changed."""
        with self._lock:
            try:
                self._db.execute("BEGIN IMMEDIATE")
                changed = 0
                for sql, params in statements:
                    changed += self._db.execute(sql, params).rowcount
                self._db.execute("COMMIT")
                self.commits += 1
                return changed
            except sqlite3.Error as err:
                if self._db.in_transaction:
                    self._db.execute("ROLLBACK")
                raise StoreError("results store %s: %s" % (self.path, err))

    def _query(self, sql, params=()):
        with self._lock:
            try:
                return self._db.execute(sql, params).fetchall()
            except sqlite3.Error as err:
                raise StoreError("results store %s: %s" % (self.path, err))

    def export(self, path):
        """Write a consistent snapshot of the whole store to the new file ``path`` (mode 644): every
        committed transaction, none half, in one file without a -wal (rollback journal mode).
        StoreError (nothing left behind) on failure."""
        folder = os.path.dirname(os.path.abspath(path))
        tmp = None
        try:
            os.makedirs(folder, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", suffix=".tmp", dir=folder)
            os.close(fd)
            copy = sqlite3.connect(tmp)
            try:
                with self._lock:
                    self._db.backup(copy)
                copy.execute("PRAGMA journal_mode=DELETE")   # the pages came with the WAL flag: one file
            finally:
                copy.close()
            os.chmod(tmp, PUBLIC_FILE_MODE)
            with open(tmp, "rb") as f:
                os.fsync(f.fileno())
            rename_durable(tmp, path)
        except (sqlite3.Error, OSError, FileError) as err:
            if tmp is not None and os.path.exists(tmp):
                os.unlink(tmp)
            raise StoreError("cannot export the results store to %s: %s" % (path, err))
        fsync_dir(folder)
        return path

    # --- tasks ---------------------------------------------------------------------------------
    def add_task(self, task, state, now):
        seq = self._query("SELECT COALESCE(MAX(seq), 0) + 1 FROM tasks")[0][0]
        self._write([("INSERT INTO tasks (task_id, priority, spec, state, submitted, seq) VALUES (?, ?, ?, ?, ?, ?)",
                      (task.task_id, task.priority, json.dumps(task.to_dict()), state, now, seq))])

    def set_task_state(self, task_id, state, reason="", ended=None):
        self._write([("UPDATE tasks SET state = ?, reason = ?, ended = ? WHERE task_id = ?",
                      (state, reason, ended, task_id))])

    def task_ids(self):
        return set(row[0] for row in self._query("SELECT task_id FROM tasks"))

    def task(self, task_id):
        """{"task_id", "priority", "spec", "state", "reason", "submitted", "ended"} or None."""
        rows = self._query("SELECT task_id, priority, spec, state, reason, submitted, ended FROM tasks "
                           "WHERE task_id = ?", (task_id,))
        return self._task_row(rows[0]) if rows else None

    def tasks(self, limit=100):
        rows = self._query("SELECT task_id, priority, spec, state, reason, submitted, ended FROM tasks "
                           "ORDER BY seq DESC LIMIT ?", (limit,))
        return [self._task_row(r) for r in rows]

    def unfinished_tasks(self):
        """Tasks a killed task_manager left running, paused or suspended, oldest first."""
        rows = self._query("SELECT task_id, priority, spec, state, reason, submitted, ended FROM tasks "
                           "WHERE state IN (?, ?, ?) ORDER BY seq", UNFINISHED_STATES)
        return [self._task_row(r) for r in rows]

    @staticmethod
    def _task_row(row):
        return {"task_id": row[0], "priority": row[1], "spec": json.loads(row[2]), "state": row[3],
                "reason": row[4], "submitted": row[5], "ended": row[6]}

    # --- readings ------------------------------------------------------------------------------
    def add_readings(self, rows):
        """Commit the readings of one preset in one transaction; returns how many were new."""
        statements = [("INSERT OR IGNORE INTO readings (%s) VALUES (%s)"
                       % (", ".join(WRITTEN_COLUMNS), ", ".join("?" * len(WRITTEN_COLUMNS))),
                       tuple(_optional(row, c) if c in OPTIONAL_COLUMNS else row[c] for c in WRITTEN_COLUMNS))
                      for row in rows]
        return self._write(statements)

    def done_presets(self, task_id):
        """{(stop, preset_index)} that already have readings (read, uncertain or failed)."""
        return set(self._query("SELECT DISTINCT stop, preset_index FROM readings WHERE task_id = ?", (task_id,)))

    def readings(self, task_id=None, since=None, until=None, limit=1000, target=None, after_id=None):
        """Readings filtered by task, meter (target name), time range [since, until] (unix s) and
        row id (after ``after_id``: the next page), in recording order."""
        clauses, params = [], []
        for clause, value in (("task_id = ?", task_id), ("target_name = ?", target), ("time >= ?", since),
                              ("time <= ?", until), ("id > ?", after_id)):
            if value is not None:
                clauses.append(clause)
                params.append(value)
        where = (" WHERE " + " AND ".join(clauses)) if clauses else ""
        rows = self._query("SELECT %s FROM readings%s ORDER BY id LIMIT ?" % (", ".join(READING_COLUMNS), where),
                           tuple(params) + (limit,))
        return [dict(zip(READING_COLUMNS, r)) for r in rows]

    def meter_values(self, target_name, before, limit):
        """The newest ``limit`` (time, value) of a meter recorded before ``before`` (unix s): read
        values, and uncertain ones an operator confirmed or corrected (the reviewed value)."""
        rows = self._query("SELECT time, COALESCE(review_value, value) FROM readings "
                           "WHERE target_name = ? AND time < ? AND (status = ? OR review_value IS NOT NULL) "
                           "AND COALESCE(review_value, value) IS NOT NULL ORDER BY time DESC LIMIT ?",
                           (target_name, before, STATUS_READ, max(0, int(limit))))
        return [(float(t), float(v)) for t, v in rows]

    def meter_histories(self, readings, points):
        """{target name: [(unix s, value)] oldest first}: each meter of ``readings`` up to its newest
        reading there, at most ``points`` values (the trend beside a reading in a report)."""
        newest = {}
        for row in readings:
            newest[row["target_name"]] = max(newest.get(row["target_name"], 0.0), row["time"])
        return dict((name, list(reversed(self.meter_values(name, until + 1e-6, points))))
                    for name, until in newest.items())

    def reading(self, row_id):
        """One reading row by its id, or None."""
        rows = self._query("SELECT %s FROM readings WHERE id = ?" % ", ".join(READING_COLUMNS), (row_id,))
        return dict(zip(READING_COLUMNS, rows[0])) if rows else None

    # --- review of uncertain readings ------------------------------------------------------------
    def review_queue(self, task_id=None, limit=100):
        """Uncertain readings nobody reviewed yet, oldest first (optionally of one task)."""
        clause, params = ("", ()) if task_id is None else (" AND task_id = ?", (task_id,))
        rows = self._query("SELECT %s FROM readings WHERE status = ? AND review_time IS NULL%s ORDER BY id LIMIT ?"
                           % (", ".join(READING_COLUMNS), clause), (STATUS_UNCERTAIN,) + params + (limit,))
        return [dict(zip(READING_COLUMNS, r)) for r in rows]

    def set_review(self, row_id, value, alarm, by, now):
        """Settle an uncertain, unreviewed reading: its true ``value`` (the robot's own when the
        operator confirmed it), that value's ``alarm``, who and when. The robot's value stays in
        ``value``. Returns False (nothing written) when the row is not waiting for a review."""
        return self._write([("UPDATE readings SET review_value = ?, review_alarm = ?, review_by = ?, review_time = ? "
                             "WHERE id = ? AND status = ? AND review_time IS NULL",
                             (value, alarm, by, now, row_id, STATUS_UNCERTAIN))]) == 1

    # --- alarms and their acknowledgement (task.alarms) ------------------------------------------
    def alarm_rows(self, states, task_id=None, acknowledged=False, limit=100):
        """Rows whose stated alarm is one of ``states``, unacknowledged (``acknowledged``: those
        acknowledged), newest first (optionally of one task)."""
        clause, params = ("", ()) if task_id is None else (" AND task_id = ?", (task_id,))
        rows = self._query("SELECT %s FROM readings WHERE %s IN (%s) AND ack_time IS %sNULL%s ORDER BY id DESC LIMIT ?"
                           % (", ".join(READING_COLUMNS), STATED_ALARM_SQL, ", ".join("?" * len(states)),
                              "NOT " if acknowledged else "", clause), tuple(states) + params + (limit,))
        return [dict(zip(READING_COLUMNS, r)) for r in rows]

    def alarm_count(self, states):
        """How many rows have a stated alarm in ``states`` and no acknowledgement."""
        return self._query("SELECT COUNT(*) FROM readings WHERE ack_time IS NULL AND %s IN (%s)"
                           % (STATED_ALARM_SQL, ", ".join("?" * len(states))), tuple(states))[0][0]

    def acknowledge(self, row_id, by, note, now):
        """Acknowledge the alarm of an unacknowledged row; False (nothing written) when it already was."""
        return self._write([("UPDATE readings SET ack_by = ?, ack_time = ?, ack_note = ? "
                             "WHERE id = ? AND ack_time IS NULL", (by, now, note, row_id))]) == 1

    # --- the driven path ------------------------------------------------------------------------
    def add_poses(self, task_id, poses):
        """Append [(unix s, x, y, yaw)] (thinned by task.track) to ``task_id``'s path, in one transaction."""
        return self._write([("INSERT INTO poses (task_id, time, x, y, yaw) VALUES (?, ?, ?, ?, ?)",
                             (task_id, float(t), float(x), float(y), float(yaw))) for t, x, y, yaw in poses])

    def driven_path(self, task_id):
        """The poses recorded during ``task_id``, [(unix s, x, y, yaw)] in recording order ([] for a
        task recorded before paths were)."""
        return [tuple(r) for r in self._query("SELECT time, x, y, yaw FROM poses WHERE task_id = ? ORDER BY id",
                                              (task_id,))]

    # --- step timings --------------------------------------------------------------------------
    def add_step(self, task_id, stop, preset_index, kind, outcome, started, ended, reason=""):
        self._write([("INSERT INTO steps (%s) VALUES (?, ?, ?, ?, ?, ?, ?, ?)" % ", ".join(STEP_COLUMNS),
                      (task_id, stop, preset_index, kind, outcome, started, ended, reason))])

    def steps(self, task_id):
        rows = self._query("SELECT %s FROM steps WHERE task_id = ? ORDER BY id" % ", ".join(STEP_COLUMNS), (task_id,))
        return [dict(zip(STEP_COLUMNS, r)) for r in rows]

    # --- small persistent settings (holds) -------------------------------------------------------
    def get_meta(self, key, default=None):
        rows = self._query("SELECT value FROM meta WHERE key = ?", (key,))
        return json.loads(rows[0][0]) if rows else default

    def set_meta(self, key, value):
        self._write([("INSERT OR REPLACE INTO meta (key, value) VALUES (?, ?)", (key, json.dumps(value)))])

    # --- routines and schedules (task/schedule.py) -------------------------------------------------
    def save_routine(self, name, task, now):
        """Store (or replace) a routine: its task JSON without id as the client gave it."""
        self._write([("INSERT OR REPLACE INTO routines (name, task, saved) VALUES (?, ?, ?)",
                      (name, json.dumps(task, sort_keys=True), now))])
        return self.routine(name)

    def routine(self, name):
        rows = self._query("SELECT name, task, saved FROM routines WHERE name = ?", (name,))
        return {"name": rows[0][0], "task": json.loads(rows[0][1]), "saved": rows[0][2]} if rows else None

    def routines(self):
        return [{"name": r[0], "task": json.loads(r[1]), "saved": r[2]}
                for r in self._query("SELECT name, task, saved FROM routines ORDER BY name")]

    def delete_routine(self, name):
        """False when there is no such routine; the caller checks that no schedule uses it."""
        return self._write([("DELETE FROM routines WHERE name = ?", (name,))]) == 1

    def set_schedule(self, schedule, now):
        """Store (or replace) a schedule (task/schedule.parse_schedule's dict); runs before ``now``
        are not its own. Its last run and missed runs stay when it is replaced."""
        self._write([("INSERT INTO schedules (name, spec, set_at) VALUES (?, ?, ?) ON CONFLICT (name) DO UPDATE "
                      "SET spec = excluded.spec, set_at = excluded.set_at",
                      (schedule["name"], json.dumps(schedule, sort_keys=True), now))])

    def schedules(self):
        """[schedule dict + "set_at", "last_at", "last_task_id"] by name."""
        out = []
        for name, spec, set_at, last_at, last_task_id in self._query(
                "SELECT name, spec, set_at, last_at, last_task_id FROM schedules ORDER BY name"):
            row = json.loads(spec)
            row.update(set_at=set_at, last_at=last_at, last_task_id=last_task_id)
            out.append(row)
        return out

    def delete_schedule(self, name):
        """False when there is no such schedule; its missed runs go with it."""
        return self._write([("DELETE FROM schedules WHERE name = ?", (name,)),
                            ("DELETE FROM missed_runs WHERE schedule = ?", (name,))]) >= 1

    def set_schedule_run(self, name, at, task_id):
        self._write([("UPDATE schedules SET last_at = ?, last_task_id = ? WHERE name = ?", (at, task_id, name))])

    def add_missed_runs(self, runs, now, keep):
        """Record missed runs [(schedule, at, reason)] in one transaction (a long stop may have missed
        hundreds), keep the newest ``keep`` per schedule, count them all in meta ``missed_runs``."""
        if not runs:
            return
        count = self.get_meta("missed_runs", 0) + len(runs)
        statements = [("INSERT INTO missed_runs (schedule, at, reason, noted) VALUES (?, ?, ?, ?)",
                       (name, at, reason, now)) for name, at, reason in runs]
        statements += [("DELETE FROM missed_runs WHERE schedule = ? AND id NOT IN (SELECT id FROM missed_runs "
                        "WHERE schedule = ? ORDER BY at DESC, id DESC LIMIT ?)", (name, name, keep))
                       for name in sorted(set(r[0] for r in runs))]
        statements.append(("INSERT OR REPLACE INTO meta (key, value) VALUES (?, ?)",
                           ("missed_runs", json.dumps(count))))
        self._write(statements)

    def missed_runs(self, name=None, limit=20):
        """[{"schedule", "at", "reason"}] newest first (of one schedule or all)."""
        clause, params = ("", ()) if name is None else (" WHERE schedule = ?", (name,))
        return [{"schedule": r[0], "at": r[1], "reason": r[2]} for r in self._query(
            "SELECT schedule, at, reason FROM missed_runs%s ORDER BY at DESC, id DESC LIMIT ?" % clause,
            params + (limit,))]

    def schedule_checked(self):
        """Unix time up to which the scheduler looked for due runs (None: it never ran)."""
        return self.get_meta("schedule_checked")

    def set_schedule_checked(self, at):
        self.set_meta("schedule_checked", at)


def export_snapshot(store, folder, now, keep=EXPORTS_KEPT):
    """task_control ``export_results``: a snapshot ``<folder>/<YYYYMMDD_HHMMSS>.sqlite`` (``_2``,
    ... when one of that second exists); the oldest snapshots beyond ``keep`` are removed. Returns
    the path."""
    stamp = time.strftime("%Y%m%d_%H%M%S", time.localtime(now))
    path, copy = os.path.join(folder, stamp + ".sqlite"), 1
    while os.path.exists(path):
        copy += 1
        path = os.path.join(folder, "%s_%d.sqlite" % (stamp, copy))
    store.export(path)
    snapshots = sorted(name for name in os.listdir(folder) if name.endswith(".sqlite") and not name.startswith("."))
    for name in snapshots[:-keep]:
        try:
            os.unlink(os.path.join(folder, name))
        except OSError:
            pass   # another one next time
    return path
