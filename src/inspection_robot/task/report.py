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
import urllib.parse

import numpy as np

from inspection_robot.files import PUBLIC_FILE_MODE, write_atomic
from inspection_robot.i18n import ENGLISH
from inspection_robot.nav.gridmap import OCC_OCCUPIED, OCC_UNKNOWN
from inspection_robot.task.client_view import client_row
from inspection_robot.task.report_html import figures_of, render_html
from inspection_robot.task.report_states import (STATE_COLOURS, STATE_WORDS, needs_review, reading_state,
                                                 worst_state)
from inspection_robot.task.states import (ALARM_ALARM, ALARM_CHECK, ALARM_TREND, ALARM_WARNING, STATUS_FAILED,
                                          STATUS_READ, STATUS_UNCERTAIN)
from inspection_robot.task.store import READING_COLUMNS
from inspection_robot.task.track import path_length
from inspection_robot.thermal.diagnosis import GRADES

REPORT_FILES = ("report.csv", "report.json", "report.html")
CSV_COLUMNS = READING_COLUMNS + ("display", "review_display")
MAP_CELLS = 240   # the yard map's longer side at most this many cells (coarser cells: any occupied wins)


def step_split(steps):
    """Seconds spent per step kind (move, inspect, home) and per outcome, for the summary."""
    split = {}
    for step in steps:
        key = step["kind"]
        split[key] = split.get(key, 0.0) + max(0.0, step["ended"] - step["started"])
    return split


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
                  grid=None, tr=ENGLISH, language="en"):
    """Write the three report files of one task into ``folder`` (``readings`` as stored: absolute
    paths); returns {name: path}. ``software_version`` (inspection_robot.version) goes into the JSON
    summary and the HTML heading; ``history`` {target name: [(unix s, value)] oldest first}, each
    meter's recent readings, a small trend beside each reading of the HTML page; ``path`` the poses
    recorded during the task (store.driven_path) and ``grid`` the yard's map (nav.gridmap.GridMap) draw
    the yard map (either may be None: the map shows what it has); ``tr`` translates report.html's words
    into ``language`` (inspection_robot.i18n: the site's language), report.csv and report.json stay
    the interface's."""
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
    yard = yard_svg(grid, path or [], task_row["spec"]["stops"], links, tr)
    figures = figures_of(lambda picture: picture_link(picture, folder, data_root), data_root)
    write_atomic(paths["report.html"], render_html(info, links, yard, task_row["spec"]["stops"], figures, tr,
                                                   language),
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


def yard_svg(grid, path, stops, readings, tr=ENGLISH):
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
           'aria-label="%s">' % (width, height, html.escape(tr("Yard map"))),
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
                   % (html.escape(state), i + 1, html.escape(stop["name"]),
                      html.escape(tr(STATE_WORDS.get(state, state))), x, y, radius, STATE_COLOURS[state],
                      radius / 8.0, x, y + radius * 0.4, radius * 1.1, i + 1))
    out.append("</svg>")
    return "".join(out)
