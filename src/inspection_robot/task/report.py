"""Patrol reports: one folder per task with report.csv, report.json and report.html.

report.html is meant for the operator on a 1280-px screen and on A4 paper (print CSS, no
horizontal overflow, checked in Chromium by test/unit/test_report_browser.py): a summary first
(counts, start, end, duration, distance driven against the planned length), then every reading
that needs attention (alarm, check, failed, needs review, trend: the most urgent first), a yard
map (inline SVG: the map's occupied and unknown cells, the driven path, each stop numbered and
coloured by its worst reading), then per stop and preset the annotated pictures beside their
values, each with a small trend. Values are shown rounded to their meter's resolution with their
unit (task.display, the ``display`` column of the CSV and JSON beside the raw ``value``).

Pictures stay where read_scale wrote them and are linked relative to the report's folder
(``../../../pictures/...`` from ``tasks/reports/<id>/``), so a report fetched with its pictures
into the same layout (the data root's, over file_control) shows them; the page has no other
outside reference. report.csv and report.json name files relative to the data root, as every
answer of task_manager does (task.client_view). Files are written with files.write_atomic (mode
644: the report is meant to be read): a reader sees the old report or the new. The JSON summary and
the HTML heading name the robot software's version (git describe of the build).
"""
import csv
import html
import io
import json
import math
import os
import time
import urllib.parse

import numpy as np

from inspection_robot.files import PUBLIC_FILE_MODE, write_atomic
from inspection_robot.nav.gridmap import OCC_OCCUPIED, OCC_UNKNOWN
from inspection_robot.task.alarms import stated_alarm
from inspection_robot.task.client_view import client_row
from inspection_robot.task.report_pictures import preset_figures, sparkline
from inspection_robot.task.states import (ALARM_ALARM, ALARM_CHECK, ALARM_FAILED, ALARM_NONE, ALARM_NORMAL,
                                          ALARM_TREND, ALARM_WARNING, STATUS_FAILED, STATUS_READ, STATUS_UNCERTAIN)
from inspection_robot.task.store import READING_COLUMNS
from inspection_robot.task.track import path_length
from inspection_robot.thermal.diagnosis import GRADES

REPORT_FILES = ("report.csv", "report.json", "report.html")
CSV_COLUMNS = READING_COLUMNS + ("display", "review_display")
# a reading's state in the report, the most urgent first: its alarm, a failure, an uncertain value
# nobody reviewed yet (review), a trend warning; a stop is coloured by its worst reading
STATE_REVIEW = "review"
STATE_NOT_READ = "not read"
STATE_ORDER = (ALARM_ALARM, ALARM_CHECK, ALARM_WARNING, ALARM_FAILED, STATE_REVIEW, ALARM_TREND, ALARM_NORMAL,
               ALARM_NONE)
STATE_RANK = dict((state, i) for i, state in enumerate(STATE_ORDER))
ATTENTION_STATES = (ALARM_ALARM, ALARM_CHECK, ALARM_WARNING, ALARM_FAILED, STATE_REVIEW, ALARM_TREND)
STATE_COLOURS = {ALARM_ALARM: "#c62828", ALARM_CHECK: "#ef6c00", ALARM_WARNING: "#b8860b", ALARM_FAILED: "#616161", STATE_REVIEW: "#6a1b9a",
                 ALARM_TREND: "#f9a825", ALARM_NORMAL: "#2e7d32", ALARM_NONE: "#1565c0", STATE_NOT_READ: "#bdbdbd"}
# a state in the operator's words where its code does not say it (the others read as their code)
STATE_WORDS = {STATE_REVIEW: "needs review", ALARM_NONE: "no limits", STATE_NOT_READ: "not read"}
MAP_CELLS = 240   # the yard map's longer side at most this many cells (coarser cells: any occupied wins)


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


def reading_state(row):
    """The report's state of a reading (STATE_ORDER): the reviewed value's alarm once reviewed."""
    if row["status"] == STATUS_FAILED:
        return ALARM_FAILED
    if needs_review(row):
        return ALARM_CHECK if row["alarm"] == ALARM_CHECK else STATE_REVIEW
    return stated_alarm(row)


def worst_state(rows):
    """The most urgent state of ``rows``; STATE_NOT_READ when there are none."""
    states = [reading_state(r) for r in rows]
    return min(states, key=lambda s: STATE_RANK.get(s, len(STATE_ORDER))) if states else STATE_NOT_READ


def summary(task_row, readings, steps, path=None):
    """The report's summary of a task: counts, times, the route planned and (``path``: the poses
    recorded during it, store.driven_path) the distance driven (null without a recorded path)."""
    states = [reading_state(r) for r in readings]   # a reviewed value counts with its reviewed alarm
    counts = {"readings": len(readings), "read": sum(1 for r in readings if r["status"] == STATUS_READ),
              "uncertain": sum(1 for r in readings if r["status"] == STATUS_UNCERTAIN),
              "needs_review": sum(1 for r in readings if needs_review(r)),
              "failed": sum(1 for r in readings if r["status"] == STATUS_FAILED),
              "alarms": states.count(ALARM_ALARM), "checks": states.count(ALARM_CHECK),
              "warnings": states.count(ALARM_WARNING), "trends": states.count(ALARM_TREND)}
    ended = task_row["ended"]
    return {"task_id": task_row["task_id"], "priority": task_row["priority"], "state": task_row["state"],
            "reason": task_row["reason"], "submitted": task_row["submitted"], "ended": ended,
            "thermal_defects": dict((g, sum(1 for r in readings if r.get("grade") == g)) for g in GRADES),
            "duration_s": round(ended - task_row["submitted"], 1) if ended else None,
            "stops": len(task_row["spec"]["stops"]), "order": task_row["spec"].get("order", "given"),
            "planned_length_m": task_row["spec"].get("planned_length_m"),
            "home_leg_m": task_row["spec"].get("home_leg_m"),
            "distance_driven_m": round(path_length(path), 1) if path else None, "counts": counts,
            "time_by_step_s": dict((k, round(v, 2)) for k, v in step_split(steps).items())}


def write_reports(folder, task_row, readings, steps, data_root, software_version, history=None, path=None,
                  grid=None):
    """Write the three report files of one task into ``folder`` (``readings`` as stored: absolute
    paths); returns {name: path}. ``software_version`` (inspection_robot.version) goes into the JSON
    summary and the HTML heading; ``history`` {target name: [(unix s, value)] oldest first}, each
    meter's recent readings, a small trend beside each reading of the HTML page; ``path`` the poses
    recorded during the task (store.driven_path) and ``grid`` the yard's map (nav.gridmap.GridMap) draw
    the yard map (either may be None: the map shows what it has)."""
    info = summary(task_row, readings, steps, path)
    info["software_version"] = software_version
    paths = dict((name, os.path.join(folder, name)) for name in REPORT_FILES)
    shown_rows = [client_row(r, data_root) for r in readings]
    out = io.StringIO()
    writer = csv.writer(out)
    writer.writerow(CSV_COLUMNS)
    for row in shown_rows:
        writer.writerow(["" if row[c] is None else row[c] for c in CSV_COLUMNS])
    write_atomic(paths["report.csv"], out.getvalue(), mode=PUBLIC_FILE_MODE)
    write_atomic(paths["report.json"], json.dumps({"summary": info, "readings": shown_rows}, indent=1,
                                                  sort_keys=True), mode=PUBLIC_FILE_MODE)
    links = [dict(shown, link=picture_link(row["picture"], folder, data_root),
                  history=(history or {}).get(row["target_name"], []))
             for row, shown in zip(readings, shown_rows)]
    yard = yard_svg(grid, path or [], task_row["spec"]["stops"], links)
    figures = _figures(lambda picture: picture_link(picture, folder, data_root), data_root)
    write_atomic(paths["report.html"], render_html(info, links, yard, task_row["spec"]["stops"], figures),
                 mode=PUBLIC_FILE_MODE)
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


# --- the yard map -----------------------------------------------------------------------------
def map_cells(grid, points, max_cells=MAP_CELLS):
    """The part of ``grid`` (GridMap) with known cells and ``points`` [(x, y)], coarsened to at most
    ``max_cells`` a side: (cells, cell size m, (x, y) of the corner of cell (0, 0)); ``cells`` is
    0 free, 1 occupied, 2 unknown, row 0 at the lowest y (a coarse cell is occupied when any of its
    cells is, unknown when all are)."""
    occ = grid.occupancy
    known_rows, known_cols = np.nonzero(occ != OCC_UNKNOWN)
    rows, cols = [], []
    if known_rows.size:
        rows, cols = [int(known_rows.min()), int(known_rows.max())], [int(known_cols.min()), int(known_cols.max())]
    for x, y in points:
        r, c = grid.world_to_cell(x, y)
        rows.append(min(max(r, 0), grid.height - 1))
        cols.append(min(max(c, 0), grid.width - 1))
    if not rows:
        rows, cols = [0, grid.height - 1], [0, grid.width - 1]
    r0, r1, c0, c1 = max(min(rows) - 2, 0), min(max(rows) + 3, grid.height), max(min(cols) - 2, 0), \
        min(max(cols) + 3, grid.width)
    part = occ[r0:r1, c0:c1]
    factor = max(1, int(math.ceil(max(part.shape) / float(max_cells))))
    h, w = -(-part.shape[0] // factor), -(-part.shape[1] // factor)
    padded = np.full((h * factor, w * factor), OCC_UNKNOWN, np.int16)
    padded[:part.shape[0], :part.shape[1]] = part
    blocks = padded.reshape(h, factor, w, factor).transpose(0, 2, 1, 3).reshape(h, w, factor * factor)
    cells = np.zeros((h, w), np.uint8)
    cells[np.all(blocks == OCC_UNKNOWN, axis=2)] = 2
    cells[np.any(blocks >= OCC_OCCUPIED // 2, axis=2)] = 1
    corner = (grid.origin[0] + c0 * grid.resolution, grid.origin[1] + r0 * grid.resolution)
    return cells, grid.resolution * factor, corner


def _runs_path(mask):
    """An SVG path of the True cells of ``mask`` (row 0 at the bottom), one rectangle per run of a row."""
    parts = []
    height = mask.shape[0]
    for r in range(height):
        row = np.concatenate(([0], mask[r].astype(np.int8), [0]))
        edges = np.nonzero(np.diff(row))[0]
        for a, b in zip(edges[::2], edges[1::2]):
            parts.append("M%d %dh%dv1h-%dz" % (a, height - 1 - r, b - a, b - a))
    return "".join(parts)


def yard_svg(grid, path, stops, readings):
    """The yard map as an inline SVG: occupied and unknown cells of ``grid`` (None: no outline), the
    driven ``path`` [(t, x, y, yaw)], each of ``stops`` (the task's, with x, y) numbered in patrol
    order and coloured by the worst state of its ``readings``. "" when there is nothing to draw."""
    points = [(p[1], p[2]) for p in path] + [(s["x"], s["y"]) for s in stops]
    if grid is not None:
        cells, size, corner = map_cells(grid, points)
        width, height = cells.shape[1] * size, cells.shape[0] * size
    elif points:
        xs, ys = [p[0] for p in points], [p[1] for p in points]
        corner = (min(xs) - 2.0, min(ys) - 2.0)
        width, height = max(xs) - min(xs) + 4.0, max(ys) - min(ys) + 4.0
        cells, size = None, None
    else:
        return ""

    def xy(x, y):   # metres -> the SVG's metres, y down
        return x - corner[0], height - (y - corner[1])
    out = ['<svg class="yard" viewBox="0 0 %.2f %.2f" preserveAspectRatio="xMidYMid meet" role="img" '
           'aria-label="yard map">' % (width, height),
           '<rect width="%.2f" height="%.2f" fill="#fff" stroke="#999" stroke-width="0.5%%"/>' % (width, height)]
    if cells is not None:
        out.append('<g transform="scale(%.4f)">' % size)
        for value, colour in ((2, "#e0e0e0"), (1, "#37474f")):
            d = _runs_path(cells == value)
            if d:
                out.append('<path d="%s" fill="%s"/>' % (d, colour))
        out.append("</g>")
    if len(path) >= 2:
        out.append('<polyline class="driven" fill="none" stroke="#1e88e5" stroke-width="2" '
                   'vector-effect="non-scaling-stroke" stroke-linejoin="round" points="%s"/>'
                   % " ".join("%.2f,%.2f" % xy(p[1], p[2]) for p in path))
    radius = max(width, height) / 70.0
    by_stop = {}
    for row in readings:
        by_stop.setdefault(row["stop"], []).append(row)
    for i, stop in enumerate(stops):
        state = worst_state(by_stop.get(i, []))
        x, y = xy(stop["x"], stop["y"])
        out.append('<g class="stop %s"><title>%d %s: %s</title><circle cx="%.2f" cy="%.2f" r="%.2f" fill="%s" '
                   'stroke="#000" stroke-width="%.2f"/><text x="%.2f" y="%.2f" font-size="%.2f" text-anchor="middle" '
                   'fill="#fff" font-weight="bold">%d</text></g>'
                   % (html.escape(state), i + 1, html.escape(stop["name"]), html.escape(STATE_WORDS.get(state, state)),
                      x, y, radius, STATE_COLOURS[state], radius / 8.0, x, y + radius * 0.4, radius * 1.1, i + 1))
    out.append("</svg>")
    return "".join(out)


# --- the page -----------------------------------------------------------------------------------
CSS = """
*{box-sizing:border-box}
body{font-family:sans-serif;font-size:14px;margin:0 auto;padding:8px 16px;max-width:1240px;overflow-wrap:break-word;
     color:#212121}
h1{font-size:22px;margin:4px 0} h2{font-size:18px;margin:18px 0 6px;border-bottom:2px solid #ccc}
h3{font-size:15px;margin:10px 0 4px} p{margin:4px 0}
table{border-collapse:collapse;width:100%;table-layout:fixed} td,th{border:1px solid #bbb;padding:3px 5px;
     vertical-align:top;text-align:left} th{background:#f0f0f0}
.tiles{display:flex;flex-wrap:wrap;gap:6px;margin:6px 0}
.tile{flex:1 1 80px;border:1px solid #bbb;border-radius:4px;padding:4px 8px;min-width:0}
.tile b{display:block;font-size:22px} .tile.hot{border-color:#c62828;background:#fdecea}
dl.facts{display:grid;grid-template-columns:max-content 1fr;gap:2px 12px;margin:6px 0} dl.facts dt{font-weight:bold}
dl.facts dd{margin:0}
.state{display:inline-block;max-width:100%;padding:0 5px;border-radius:3px;color:#fff;font-size:12px}
tr.alarm td{background:#fdecea} tr.check td{background:#fff3e0} tr.failed td{background:#f5f5f5;color:#8a0000}
tr.review td{background:#f3e5f5} tr.trend td{background:#fffde7} td.value{font-weight:bold}
.why{font-size:12px;color:#555} .thumb{max-width:100%;max-height:90px}
.yardbox{display:flex;flex-wrap:wrap;gap:12px;align-items:flex-start}
svg.yard{flex:1 1 480px;max-width:100%;max-height:520px}
ul.legend{list-style:none;padding:0;margin:0;flex:0 0 auto} ul.legend li{margin:2px 0}
.dot{display:inline-block;width:12px;height:12px;border-radius:6px;margin-right:6px;vertical-align:middle}
.preset{display:flex;flex-wrap:wrap;gap:10px;border:1px solid #ddd;padding:6px;margin:6px 0}
.preset>h3{flex:1 0 100%;margin:0}
.pics{flex:1 1 260px;max-width:38%;min-width:0}
.pics img,.pics svg.view{width:100%;height:auto;display:block;margin-bottom:4px}
.values{flex:1 1 360px;min-width:0}
svg.trend{display:block;max-width:100%}
@page{size:A4;margin:12mm}
@media print{
  body{font-size:10pt;max-width:none;padding:0}
  *{-webkit-print-color-adjust:exact;print-color-adjust:exact}
  h2{break-after:avoid} .preset,tr,.tile{break-inside:avoid} svg.yard{max-height:none}
  a{color:inherit;text-decoration:none}
}
"""


def _when(t):
    return "" if t is None else time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(t))


def _duration(seconds):
    if seconds is None:
        return "not ended"
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    return ("%d h %02d min" % (hours, rest // 60)) if hours else "%d min %02d s" % divmod(rest, 60)


def _metres(value):
    return "not recorded" if value is None else "%.1f m" % value


def _badge(state):
    return '<span class="state" style="background:%s">%s</span>' % (
        STATE_COLOURS[state], html.escape(STATE_WORDS.get(state, state)))


def _band(r):
    """A reading's limits in words: its normal band, and the alarm band around it when it has one."""
    if r["low"] is None:
        return "no limits"
    unit = " " + r["unit"] if r["unit"] else ""
    text = "%g .. %g%s" % (r["low"], r["high"], unit)
    if r.get("alarm_low") is not None:
        text += "; alarm outside %g .. %g%s" % (r["alarm_low"], r["alarm_high"], unit)
    return text


def _value_cell(r):
    """The robot's value as read (rounded), and the operator's when a review settled it."""
    text = html.escape(r["display"] or "no value")
    if r.get("increment") is not None:   # a counter: what it counted since its previous reading
        text += '<div class="why">%+g since the previous reading</div>' % r["increment"]
    if r.get("review_time") is not None:
        text += '<div class="why">reviewed by %s: %s</div>' % (
            html.escape(r["review_by"]), "confirmed" if r["review_value"] == r["value"]
            else html.escape(r["review_display"]))
    return text


def _summary_part(info, rows):
    counts = info["counts"]
    tiles = [("readings", counts["readings"], False), ("read", counts["read"], False),
             ("alarms", counts["alarms"], counts["alarms"] > 0), ("checks", counts["checks"], counts["checks"] > 0),
             ("warnings", counts["warnings"], counts["warnings"] > 0),
             ("failed", counts["failed"], counts["failed"] > 0),
             ("need review", counts["needs_review"], counts["needs_review"] > 0),
             ("trends", counts["trends"], counts["trends"] > 0)]
    defects = info["thermal_defects"]
    tiles += [("%s thermal defects" % grade, defects[grade], True) for grade in reversed(GRADES) if defects[grade]]
    stops_read = len(set(r["stop"] for r in rows if r["status"] != STATUS_FAILED))
    planned = info["planned_length_m"]
    facts = [("state", "%s%s" % (info["state"], ": " + info["reason"] if info["reason"] else "")),
             ("priority", info["priority"]), ("started", _when(info["submitted"])), ("ended", _when(info["ended"])),
             ("duration", _duration(info["duration_s"])),
             ("distance driven", _metres(info["distance_driven_m"])),
             ("planned route", _planned_words(planned, info.get("home_leg_m"), info["order"])),
             ("stops", "%d, %d with readings" % (info["stops"], stops_read)),
             ("uncertain", "%d (%d need review)" % (counts["uncertain"], counts["needs_review"])),
             ("robot software", str(info.get("software_version")))]
    return ('<section class="summary"><h2>Summary</h2><div class="tiles">%s</div><dl class="facts">%s</dl></section>'
            % ("".join('<div class="tile%s"><b>%d</b>%s</div>' % (" hot" if hot else "", n, html.escape(label))
                       for label, n, hot in tiles),
               "".join("<dt>%s</dt><dd>%s</dd>" % (html.escape(k), html.escape(v)) for k, v in facts)))


def _planned_words(planned, home_leg, order):
    """The planned route beside the distance driven: the stops' part (what a patrol drives), the way
    home apart (a patrol ends at its last stop); tasks planned before the home leg was kept say so."""
    if planned is None:
        return "not measured (%s order)" % order
    if home_leg is None:
        return "%.1f m (%s order, from the robot through every stop and home)" % (planned, order)
    return ("%.1f m (%s order, from the robot through every stop; driving home from the last stop would "
            "add %.1f m, which a patrol does not drive)" % (planned - home_leg, order, home_leg))


def _calm_words(rows):
    """What a report without attention says: "normal" only of readings that had limits to be within."""
    unlimited = sum(1 for r in rows if reading_state(r) == ALARM_NONE)
    if not unlimited:
        return "Every reading is within its limits."
    if unlimited == len(rows):
        return "No alarm, but no reading had limits to compare with (no normal band set)."
    return "No alarm: %d reading(s) within their limits, %d without limits (no normal band set)." \
        % (len(rows) - unlimited, unlimited)


def _attention_part(rows):
    urgent = sorted((r for r in rows if reading_state(r) in ATTENTION_STATES),
                    key=lambda r: (STATE_RANK[reading_state(r)], r["stop"], r["preset_index"], r["target"]))
    if not urgent:
        return '<section class="attention"><h2>Needs attention (0)</h2><p>%s</p></section>' % _calm_words(rows)
    body = []
    for r in urgent:
        state = reading_state(r)
        thumb = ('<a href="%s"><img class="thumb" src="%s" alt="%s"></a>' % (html.escape(r["link"]),
                 html.escape(r["link"]), html.escape(r["target_name"])) if r.get("link") else "")
        body.append('<tr class="%s"><td>%s</td><td>%d %s</td><td>%s<div class="why">%s</div></td><td class="value">%s'
                    '</td><td>%s</td><td>%s</td><td>%s</td></tr>'
                    % (html.escape(state), _badge(state), r["stop"] + 1, _breakable(r["stop_name"]),
                       _breakable(r["target_name"]), html.escape(r["kind"]), _value_cell(r), html.escape(_band(r)),
                       _breakable(r["reason"]) + _acknowledged(r), thumb))
    hint = ("<p>Most urgent first. Uncertain values are confirmed or corrected with task_control "
            "<code>review</code> or the console's review queue.</p>")
    return ('<section class="attention"><h2>Needs attention (%d)</h2>%s<table><colgroup><col style="width:9%%">'
            '<col style="width:13%%"><col style="width:19%%"><col style="width:11%%"><col style="width:11%%">'
            '<col style="width:24%%"><col style="width:13%%"></colgroup>'
            '<tr><th>state</th><th>stop</th><th>target</th>'
            '<th>value</th><th>limits</th><th>reason</th><th>picture</th></tr>%s</table></section>'
            % (len(urgent), hint, "".join(body)))


def _acknowledged(row):
    """The acknowledgement of a row's alarm (task.alarms), as a line of the reason cell."""
    if row.get("ack_time") is None:
        return ""
    note = ": " + row["ack_note"] if row.get("ack_note") else ""
    return '<div class="ack">acknowledged by %s, %s%s</div>' % (html.escape(row["ack_by"]), _when(row["ack_time"]),
                                                                html.escape(note))


def _map_part(yard):
    if not yard:
        return ""
    legend = "".join('<li><span class="dot" style="background:%s"></span>%s</li>'
                     % (STATE_COLOURS[s], html.escape(STATE_WORDS.get(s, s))) for s in STATE_ORDER + (STATE_NOT_READ,))
    return ('<section class="map"><h2>Yard map</h2><div class="yardbox">%s<ul class="legend">%s<li>'
            '<span class="dot" style="background:#1e88e5;border-radius:0;height:3px"></span>driven path</li>'
            '<li><span class="dot" style="background:#37474f;border-radius:0"></span>obstacle</li></ul></div>'
            '</section>' % (yard, legend))


def _breakable(name):
    """A target name escaped, with line-break chances after its separators only (never mid-word)."""
    return html.escape(name).replace("/", "/<wbr>").replace("_", "_<wbr>")


def _preset_part(rows, heading, figures):
    """One preset: ``heading`` (the stop's, for its first preset: kept on the page with it), its
    pictures (``figures(rows)``, task.report_pictures) beside its readings' table."""
    first = rows[0]
    body = []
    for number, r in enumerate(rows, 1):
        state = reading_state(r)
        trend = sparkline(r.get("history") or [], (r["low"], r["high"]) if r["low"] is not None else None)
        body.append('<tr class="%s"><td>%d %s<div class="why">%s%s</div></td><td class="value">%s%s</td>'
                    '<td>%s</td><td>%s<div class="why">%s</div></td></tr>'
                    % (html.escape(state), number, _breakable(r["target_name"]), html.escape(r["kind"]),
                       "" if r["confidence"] is None else ", confidence %.0f" % r["confidence"], _value_cell(r), trend,
                       html.escape(_band(r)), _badge(state), _breakable(r["reason"])))
    return ('<div class="preset">%s<div class="pics">%s</div><div class="values"><p class="why">preset %s, %s</p>'
            '<table><colgroup><col style="width:33%%"><col style="width:23%%"><col style="width:18%%">'
            '<col style="width:26%%"></colgroup><tr><th>target</th><th>value, trend</th>'
            '<th>limits</th><th>state</th></tr>%s</table></div></div>'
            % (heading, figures(rows), html.escape(preset_label(first["preset"])), html.escape(_when(first["time"])),
               "".join(body)))


def _stops_part(rows, stops, figures):
    by_stop = {}
    for r in rows:
        by_stop.setdefault(r["stop"], {}).setdefault(r["preset_index"], []).append(r)
    parts = []
    for i in sorted(set(range(len(stops))) | set(by_stop)):
        presets = by_stop.get(i, {})
        name = stops[i]["name"] if i < len(stops) else next(iter(presets.values()))[0]["stop_name"]
        state = worst_state([r for p in presets.values() for r in p])
        heading = '<h3>%d %s %s</h3>' % (i + 1, _breakable(name), _badge(state))
        parts.append('<article class="stop" id="stop-%d">%s</article>'
                     % (i + 1, "".join(_preset_part(sorted(presets[j], key=lambda r: r["target"]),
                                                    heading if k == 0 else "", figures)
                                       for k, j in enumerate(sorted(presets)))
                        or heading + '<p class="why">no readings</p>'))
    return '<section class="stops"><h2>Stops</h2>%s</section>' % "".join(parts)


def render_html(info, readings, yard="", stops=(), figures=None):
    """The report page of a task: ``info`` its summary, ``readings`` client rows with ``link`` (the
    picture's href) and ``history``, ``yard`` the map's SVG (yard_svg; "" for none), ``stops`` the
    task's stops (a stop without readings is listed as such), ``figures(rows)`` a preset's pictures
    (None: each annotated picture once, by its ``link``)."""
    if figures is None:
        links = dict((r["picture"], r["link"]) for r in readings if r.get("link"))
        figures = _figures(links.get, "")
    return ('<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
            '<meta name="viewport" content="width=device-width, initial-scale=1">'
            '<title>Patrol report %(id)s</title><style>%(css)s</style></head><body>\n'
            '<h1>Patrol report %(id)s</h1><p>robot software %(version)s</p>\n%(summary)s\n%(attention)s\n%(map)s\n'
            '%(stops)s\n</body></html>\n'
            % {"id": html.escape(info["task_id"]), "css": CSS,
               "version": html.escape(str(info.get("software_version"))),
               "summary": _summary_part(info, readings), "attention": _attention_part(readings),
               "map": _map_part(yard), "stops": _stops_part(readings, stops, figures)})


def _figures(link_of, data_root):
    """A preset's pictures with its boxes in their states' colours (task.report_pictures)."""
    return lambda rows: preset_figures(rows, lambda p: link_of(p) or "", lambda r: STATE_COLOURS[reading_state(r)],
                                       data_root)
