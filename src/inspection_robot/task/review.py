"""Queries of the results store and the operator's review of uncertain readings, without ROS.

``parse_query`` checks the JSON of query_results and review_queue (one set of rules for both);
``parse_review`` the JSON of ``review``; ``review`` settles one reading: the correction file
first (the bench's field set, docs/interface.md "Uncertain readings and their review"), then the store,
so a refused or failed review leaves neither behind.
"""
import os

from inspection_robot.command import CommandError, parse_json
from inspection_robot.files import write_json_atomic
from inspection_robot.task.spec import check_task_id
from inspection_robot.task.states import STATUS_UNCERTAIN, alarm_state
from inspection_robot.task.store import StoreError

MAX_QUERY_ROWS = 5000
MAX_REVIEWER_CHARS = 64
REVIEW_KEYS = ("id", "value", "by")


def _is_number(value):
    return not isinstance(value, bool) and isinstance(value, (int, float))


def parse_query(data, keys, default_limit):
    """The filters of a query: a dict with ``keys`` (a subset of task_id, target, from, to, after_id,
    limit) and the
    limit set (``default_limit`` when absent). ``data`` "" means no filter."""
    query = parse_json(data or "{}", "query")
    if not isinstance(query, dict) or set(query) - set(keys):
        raise CommandError("query must be a JSON object with keys %s" % ", ".join(keys))
    for key in ("from", "to"):
        if query.get(key) is not None and not _is_number(query[key]):
            raise CommandError("%s must be a unix time in seconds" % key)
    limit = query.get("limit", default_limit)
    if isinstance(limit, bool) or not isinstance(limit, int) or not 1 <= limit <= MAX_QUERY_ROWS:
        raise CommandError("limit must be an integer in [1, %d]" % MAX_QUERY_ROWS)
    for key in ("task_id", "target"):
        if query.get(key) is not None and not isinstance(query[key], str):
            raise CommandError("%s must be a string" % key)
    after_id = query.get("after_id")
    if after_id is not None and (isinstance(after_id, bool) or not isinstance(after_id, int) or after_id < 0):
        raise CommandError("after_id must be a row id (an integer >= 0)")
    query["limit"] = limit
    return query


def parse_review(data):
    """(row id, true value or None to confirm, reviewer) of a ``review`` command."""
    request = parse_json(data, "review")
    if not isinstance(request, dict) or set(request) != set(REVIEW_KEYS):
        raise CommandError("review must be a JSON object with keys %s" % ", ".join(REVIEW_KEYS))
    row_id, value, by = request["id"], request["value"], request["by"]
    if isinstance(row_id, bool) or not isinstance(row_id, int) or row_id < 1:
        raise CommandError("id must be a reading's id (a positive integer)")
    if value is not None and not _is_number(value):
        raise CommandError("value must be a number (the true reading) or null (the robot's value confirmed)")
    return row_id, None if value is None else float(value), person(by, "reviewer")


def person(by, role):
    """``by`` stripped, when it names a person (1-MAX_REVIEWER_CHARS printable characters): who
    reviewed or acknowledged a reading; CommandError naming the ``role`` otherwise."""
    if not isinstance(by, str) or not by.strip() or len(by) > MAX_REVIEWER_CHARS or not by.isprintable():
        raise CommandError("by must be the %s's name: 1-%d printable characters" % (role, MAX_REVIEWER_CHARS))
    return by.strip()


def roi_numbers(text):
    """A row's ``roi`` ("x1,y1,...,x4,y4") as 8 floats, [] when not known."""
    return [float(v) for v in text.split(",")] if text else []


def correction_record(row, true_value, by, now):
    """The correction file of a reviewed row: what the bench needs to read the picture again (the
    picture read, its box, the preset directory holding the calibration) and score it."""
    return {"id": row["id"], "task_id": row["task_id"], "time": row["time"], "preset": row["preset"],
            "target": row["target"], "target_name": row["target_name"], "kind": row["kind"], "unit": row["unit"],
            "picture": row["source_picture"], "roi": roi_numbers(row["roi"]), "annotated_picture": row["picture"],
            "value": row["value"], "confidence": row["confidence"], "reason": row["reason"],
            "true_value": true_value, "confirmed": true_value == row["value"], "by": by, "reviewed": now}


def correction_path(folder, row):
    """``<folder>/<task_id>.<row id>.json``: unique across stores (task ids are never reused)."""
    return os.path.join(folder, "%s.%d.json" % (check_task_id(row["task_id"]), row["id"]))


def review(store, folder, data, now):
    """Settle one uncertain reading (the ``review`` command); returns (row after review, file path).
    CommandError (nothing written) for a bad request, a row that does not wait for review, or a
    correction file that cannot be written."""
    row_id, value, by = parse_review(data)
    row = store.reading(row_id)
    if row is None:
        raise CommandError("no reading with id %d" % row_id)
    if row["status"] != STATUS_UNCERTAIN:
        raise CommandError("reading %d does not need review (status %s)" % (row_id, row["status"]))
    if row["review_time"] is not None:
        raise CommandError("reading %d was already reviewed by %s" % (row_id, row["review_by"]))
    true_value = row["value"] if value is None else value
    band = None if row["low"] is None else (row["low"], row["high"])
    alarm_band = None if row["alarm_low"] is None else (row["alarm_low"], row["alarm_high"])
    path = correction_path(folder, row)
    write_json_atomic(path, correction_record(row, true_value, by, now))   # FileError is a CommandError
    try:
        settled = store.set_review(row_id, true_value, alarm_state(true_value, band, alarm_band=alarm_band), by, now)
    except StoreError:
        os.unlink(path)
        raise
    if not settled:   # reviewed meanwhile by another caller
        os.unlink(path)
        raise CommandError("reading %d was already reviewed" % row_id)
    return store.reading(row_id), path
