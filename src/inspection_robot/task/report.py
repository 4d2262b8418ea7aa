"""Patrol reports: one folder per task with report.csv, report.json and report.html.

The HTML page opens with the readings that need review (uncertain values nobody settled yet, with
the reader's reason and the annotated picture), then lists every other reading with its picture,
alarms and checks first and highlighted, failures with their reason. Pictures stay where
read_scale wrote them and are linked relative to the report's folder (``../../../pictures/...``
from ``tasks/reports/<id>/``), so a report fetched with its pictures into the same layout (the
data root's, over file_control) shows them. report.csv and report.json name files relative to the
data root, as every answer of task_manager does (task.client_view). Files are written with
files.write_atomic (mode 644: the report is meant to be read): a reader sees the old report or the new.
The JSON summary and the HTML heading name the robot software's version (git describe of the build).
"""
import csv
import html
import io
import json
import os
import time
import urllib.parse

from inspection_robot.files import PUBLIC_FILE_MODE, write_atomic
from inspection_robot.task.client_view import client_row
from inspection_robot.task.states import (ALARM_ALARM, ALARM_CHECK, ALARM_ORDER, STATUS_FAILED, STATUS_READ,
                                          STATUS_UNCERTAIN)
from inspection_robot.task.store import READING_COLUMNS

REPORT_FILES = ("report.csv", "report.json", "report.html")
ALARM_RANK = dict((alarm, i) for i, alarm in enumerate(ALARM_ORDER))


def needs_review(row):
    """An uncertain value nobody has confirmed or corrected yet."""
    return row["status"] == STATUS_UNCERTAIN and row.get("review_time") is None


def step_split(steps):
    """Seconds spent per step kind (move, inspect, home) and per outcome, for the summary."""
    split = {}
    for step in steps:
        key = step["kind"]
        split[key] = split.get(key, 0.0) + max(0.0, step["ended"] - step["started"])
    return split


def summary(task_row, readings, steps):
    counts = {"readings": len(readings), "read": sum(1 for r in readings if r["status"] == STATUS_READ),
              "uncertain": sum(1 for r in readings if r["status"] == STATUS_UNCERTAIN),
              "needs_review": sum(1 for r in readings if needs_review(r)),
              "failed": sum(1 for r in readings if r["status"] == STATUS_FAILED),
              "alarms": sum(1 for r in readings if r["alarm"] == ALARM_ALARM),
              "checks": sum(1 for r in readings if r["alarm"] == ALARM_CHECK)}
    ended = task_row["ended"]
    return {"task_id": task_row["task_id"], "priority": task_row["priority"], "state": task_row["state"],
            "reason": task_row["reason"], "submitted": task_row["submitted"], "ended": ended,
            "duration_s": round(ended - task_row["submitted"], 1) if ended else None,
            "stops": len(task_row["spec"]["stops"]), "order": task_row["spec"].get("order", "given"),
            "planned_length_m": task_row["spec"].get("planned_length_m"), "counts": counts,
            "time_by_step_s": dict((k, round(v, 2)) for k, v in step_split(steps).items())}


def write_reports(folder, task_row, readings, steps, data_root, software_version, history=None):
    """Write the three report files of one task into ``folder`` (``readings`` as stored: absolute
    paths); returns {name: path}. ``software_version`` (inspection_robot.version) goes into the JSON
    summary and the HTML heading; ``history`` {target name: [(unix s, value)] oldest first}, each
    meter's recent readings, a small trend beside each reading of the HTML page."""
    info = summary(task_row, readings, steps)
    info["software_version"] = software_version
    paths = dict((name, os.path.join(folder, name)) for name in REPORT_FILES)
    shown_rows = [client_row(r, data_root) for r in readings]
    out = io.StringIO()
    writer = csv.writer(out)
    writer.writerow(READING_COLUMNS)
    for row in shown_rows:
        writer.writerow(["" if row[c] is None else row[c] for c in READING_COLUMNS])
    write_atomic(paths["report.csv"], out.getvalue(), mode=PUBLIC_FILE_MODE)
    write_atomic(paths["report.json"], json.dumps({"summary": info, "readings": shown_rows}, indent=1,
                                                  sort_keys=True), mode=PUBLIC_FILE_MODE)
    links = [dict(shown, link=picture_link(row["picture"], folder, data_root),
                  history=(history or {}).get(row["target_name"], []))
             for row, shown in zip(readings, shown_rows)]
    write_atomic(paths["report.html"], render_html(info, links), mode=PUBLIC_FILE_MODE)
    return paths


def picture_link(picture, folder, data_root):
    """The href of a picture in a report written to ``folder``: relative to it, as a URL path, so a
    report fetched with its pictures into the data root's layout shows them (a relative
    ``picture`` is taken relative to ``data_root``)."""
    if not picture:
        return ""
    path = os.path.realpath(os.path.join(data_root, picture))   # an absolute picture stays itself
    return urllib.parse.quote(os.path.relpath(path, os.path.realpath(folder)))


def preset_label(directory):
    """``<preset_id>/<stamp>`` of a preset directory."""
    return "/".join(directory.rstrip("/").split("/")[-2:])


def _fmt(value, digits=4):
    return "" if value is None else ("%.*g" % (digits, value))


def _value_text(r):
    """The robot's value, and the operator's when a review settled it."""
    text = "%s %s" % (_fmt(r["value"], 6), r["unit"])
    if r.get("review_time") is not None:
        text += " (reviewed by %s: %s)" % (r["review_by"], "confirmed" if r["review_value"] == r["value"]
                                           else "%s %s" % (_fmt(r["review_value"], 6), r["unit"]))
    return text


SPARK_W, SPARK_H = 90, 24


def sparkline(points, band=None):
    """A small inline SVG of a meter's recent values (oldest first), its band's limits dashed; ""
    for fewer than two points."""
    if len(points) < 2:
        return ""
    values = [v for _t, v in points] + [b for b in (band or ()) if b is not None]
    lo, hi = min(values), max(values)
    span = (hi - lo) or 1.0
    t0, t1 = points[0][0], points[-1][0]

    def xy(t, v):
        return (2 + (t - t0) / ((t1 - t0) or 1.0) * (SPARK_W - 4), SPARK_H - 2 - (v - lo) / span * (SPARK_H - 4))
    lines = "".join('<line x1="0" y1="%.1f" x2="%d" y2="%.1f" stroke="#c62828" stroke-dasharray="2,2"/>'
                    % (xy(t0, b)[1], SPARK_W, xy(t0, b)[1]) for b in (band or ()) if b is not None)
    path = " ".join("%.1f,%.1f" % xy(t, v) for t, v in points)
    return ('<svg class="trend" width="%d" height="%d" viewBox="0 0 %d %d">%s<polyline fill="none" stroke="#1565c0" '
            'points="%s"/></svg>' % (SPARK_W, SPARK_H, SPARK_W, SPARK_H, lines, path))


def _table_rows(rows):
    esc = html.escape
    body = []
    for r in rows:
        band = "" if r["low"] is None else "%s .. %s" % (_fmt(r["low"]), _fmt(r["high"]))
        picture = ('<a href="%s"><img src="%s" alt="%s"></a>'
                   % (esc(r["link"]), esc(r["link"]), esc(r["target_name"])) if r.get("link") else "")
        trend = sparkline(r.get("history") or [], (r["low"], r["high"]) if r["low"] is not None else None)
        body.append('<tr class="%s%s"><td>%d %s</td><td>%s</td><td>%s (%s)</td><td>%s</td><td>%s</td><td>%s</td>'
                    '<td>%s</td><td>%s</td><td>%s</td><td>%s</td><td>%s</td></tr>'
                    % (esc(r["alarm"]), "" if r["status"] == STATUS_READ else " " + esc(r["status"]),
                       r["stop"] + 1, esc(r["stop_name"]),
                       esc(preset_label(r["preset"])), esc(r["target_name"]), esc(r["kind"]), esc(_value_text(r)),
                       trend, band, esc(r["alarm"]), _fmt(r["confidence"], 3),
                       time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(r["time"])), esc(r["reason"]), picture))
    return "\n".join(body)


def render_html(info, readings):
    esc = html.escape
    rows = sorted(readings, key=lambda r: (ALARM_RANK.get(r["alarm"], 9), r["stop"], r["preset_index"], r["target"]))
    review = [r for r in rows if needs_review(r)]
    rest = [r for r in rows if not needs_review(r)]
    counts = info["counts"]
    head = ("<tr><th>stop</th><th>preset</th><th>target</th><th>value</th><th>trend</th><th>normal band</th>"
            "<th>alarm</th>"
            "<th>confidence</th><th>time</th><th>reason</th><th>picture</th></tr>")
    review_part = ("<h2>Needs review (%d)</h2>\n<p>Values the reader doubts: the reason says why. Confirm or "
                   "correct each one (task_control <code>review</code>, or the console's review queue).</p>\n"
                   "<table>%s\n%s\n</table>\n" % (len(review), head, _table_rows(review))) if review else ""
    return """<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>Patrol report %(id)s</title>
<style>
body{font-family:sans-serif;margin:1em} table{border-collapse:collapse} td,th{border:1px solid #999;padding:3px 6px}
tr.alarm td{background:#f8c0c0;font-weight:bold} tr.check td{background:#fde0b0;font-weight:bold}
tr.uncertain td{font-style:italic} tr.failed td{background:#eee;color:#a00}
img{max-width:240px;max-height:160px}
</style></head><body>
<h1>Patrol report %(id)s</h1>
<p>priority %(priority)s, state <b>%(state)s</b> %(reason)s; %(stops)d stops (%(route)s); %(readings)d readings:
%(read)d read, %(uncertain)d uncertain (%(needs_review)d need review), <b>%(alarms)d alarm(s)</b>,
<b>%(checks)d check(s)</b>, %(failed)d failed; duration %(duration)s s; robot software %(version)s</p>
%(review)s<h2>Readings</h2>
<table>%(head)s
%(body)s
</table></body></html>
""" % {"id": esc(info["task_id"]), "priority": esc(info["priority"]), "state": esc(info["state"]),
       "reason": esc(info["reason"]), "stops": info["stops"], "readings": counts["readings"], "read": counts["read"],
       "route": esc("%s order, planned route %s" % (info["order"], "%.1f m" % info["planned_length_m"]
                                                    if info["planned_length_m"] is not None else "not measured")),
       "uncertain": counts["uncertain"], "needs_review": counts["needs_review"], "alarms": counts["alarms"],
       "checks": counts["checks"], "failed": counts["failed"], "duration": info["duration_s"], "review": review_part,
       "head": head, "body": _table_rows(rest), "version": esc(str(info.get("software_version")))}
