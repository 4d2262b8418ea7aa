"""The patrol report's page (report.html), in the site's language: a summary, what needs attention, the
yard map, then per stop and preset the pictures beside their readings. Made for a 1280-px screen and A4
paper (print CSS; checked in Chromium by test/unit/test_report_browser.py). Every word goes through
the translator ``tr`` (inspection_robot.i18n: the catalogue the console uses too); the robot's own
reasons stay as the robot wrote them.
"""
import html
import time

from inspection_robot.i18n import ENGLISH
from inspection_robot.task.report_pictures import preset_figures, sparkline
from inspection_robot.task.report_states import (ATTENTION_STATES, STATE_COLOURS, STATE_NOT_READ, STATE_ORDER,
                                                 STATE_RANK, STATE_WORDS, reading_state, worst_state)
from inspection_robot.task.states import ALARM_NONE, STATUS_FAILED
from inspection_robot.thermal.diagnosis import GRADES


def preset_label(directory):
    """``<preset_id>/<stamp>`` of a preset directory."""
    return "/".join(directory.rstrip("/").split("/")[-2:])


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


def _duration(seconds, tr):
    if seconds is None:
        return tr("not ended")
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    if hours:
        return tr("{h} h {min} min", h=hours, min="%02d" % (rest // 60))
    return tr("{min} min {s} s", min=rest // 60, s="%02d" % (rest % 60))


def _metres(value, tr):
    return tr("not recorded") if value is None else "%.1f m" % value


def _state_words(state, tr):
    return tr(STATE_WORDS.get(state, state))


def _badge(state, tr):
    words = html.escape(_state_words(state, tr))
    return '<span class="state" style="background:%s">%s</span>' % (STATE_COLOURS[state], words)


def unit_words(unit, tr=ENGLISH):
    """A unit for people: degrees Celsius as °C (the interface writes ``C``), a count of objects in words."""
    return "°C" if unit == "C" else tr(unit) if unit == "objects" else unit


def display_words(display, row, tr):
    """The robot's ``display`` text (task.display: English words, ``C``) for people: lamp and switch
    states and object counts in the page's language, °C."""
    if row["kind"] in ("lamp", "switch"):
        return tr(display)
    if row["kind"] == "foreign" and display.split(" ")[0].isdigit():
        return tr("{n} object(s)", n=display.split(" ")[0])
    return display[:-2] + " °C" if row["unit"] == "C" and display.endswith(" C") else display


def _band(r, tr):
    """A reading's limits in words: its normal band, and the alarm band around it when it has one."""
    if r["low"] is None:
        return tr("no limits")
    unit = " " + unit_words(r["unit"], tr) if r["unit"] else ""
    text = "%g .. %g%s" % (r["low"], r["high"], unit)
    if r.get("alarm_low") is not None:
        text += "; " + tr("alarm outside {band}", band="%g .. %g%s" % (r["alarm_low"], r["alarm_high"], unit))
    return text


def _value_cell(r, tr):
    """The robot's value as read (rounded), and the operator's when a review settled it."""
    text = html.escape(display_words(r["display"], r, tr) if r["display"] else tr("no value"))
    if r.get("increment") is not None:   # a counter: what it counted since its previous reading
        since = tr("{n} since the previous reading", n="%+g" % r["increment"])
        text += '<div class="why">%s</div>' % html.escape(since)
    if r.get("review_time") is not None:
        text += '<div class="why">%s: %s</div>' % (
            html.escape(tr("reviewed by {name}", name=r["review_by"])), html.escape(tr("confirmed"))
            if r["review_value"] == r["value"] else html.escape(display_words(r["review_display"], r, tr)))
    return text


def _summary_part(info, rows, tr):
    counts = info["counts"]
    tiles = [("readings", counts["readings"], False), ("read", counts["read"], False),
             ("alarms", counts["alarms"], counts["alarms"] > 0), ("checks", counts["checks"], counts["checks"] > 0),
             ("warnings", counts["warnings"], counts["warnings"] > 0),
             ("failed", counts["failed"], counts["failed"] > 0),
             ("need review", counts["needs_review"], counts["needs_review"] > 0),
             ("trends", counts["trends"], counts["trends"] > 0)]
    defects = info["thermal_defects"]
    tiles += [(tr("{grade} thermal defects", grade=tr(grade)), defects[grade], True) for grade in reversed(GRADES)
              if defects[grade]]
    stops_read = len(set(r["stop"] for r in rows if r["status"] != STATUS_FAILED))
    planned = info["planned_length_m"]
    facts = [("state", "%s%s" % (tr(info["state"]), ": " + info["reason"] if info["reason"] else "")),
             ("priority", tr(info["priority"])), ("started", _when(info["submitted"])),
             ("ended", _when(info["ended"])), ("duration", _duration(info["duration_s"], tr)),
             ("distance driven", _metres(info["distance_driven_m"], tr)),
             ("planned route", _planned_words(planned, info.get("home_leg_m"), info["order"], tr)),
             ("stops", tr("{n}, {read} with readings", n=info["stops"], read=stops_read)),
             ("uncertain", tr("{n} ({review} need review)", n=counts["uncertain"], review=counts["needs_review"])),
             ("robot software", str(info.get("software_version")))]
    return ('<section class="summary"><h2>%s</h2><div class="tiles">%s</div><dl class="facts">%s</dl></section>'
            % (html.escape(tr("Summary")),
               "".join('<div class="tile%s"><b>%d</b>%s</div>' % (" hot" if hot else "", n, html.escape(tr(label)))
                       for label, n, hot in tiles),
               "".join("<dt>%s</dt><dd>%s</dd>" % (html.escape(tr(k)), html.escape(v)) for k, v in facts)))


def _planned_words(planned, home_leg, order, tr):
    """The planned route beside the distance driven: the stops' part (what a patrol drives), the way
    home apart (a patrol ends at its last stop); tasks planned before the home leg was kept say so."""
    order = tr(order)
    if planned is None:
        return tr("not measured ({order} order)", order=order)
    if home_leg is None:
        return tr("{m} m ({order} order, from the robot through every stop and home)", m="%.1f" % planned,
                  order=order)
    return tr("{m} m ({order} order, from the robot through every stop; driving home from the last stop would "
              "add {home} m, which a patrol does not drive)", m="%.1f" % (planned - home_leg), order=order,
              home="%.1f" % home_leg)


def _calm_words(rows, tr):
    """What a report without attention says: "normal" only of readings that had limits to be within."""
    unlimited = sum(1 for r in rows if reading_state(r) == ALARM_NONE)
    if not unlimited:
        return tr("Every reading is within its limits.")
    if unlimited == len(rows):
        return tr("No alarm, but no reading had limits to compare with (no normal band set).")
    return tr("No alarm: {within} reading(s) within their limits, {without} without limits (no normal band set).",
              within=len(rows) - unlimited, without=unlimited)


def _attention_part(rows, tr):
    urgent = sorted((r for r in rows if reading_state(r) in ATTENTION_STATES),
                    key=lambda r: (STATE_RANK[reading_state(r)], r["stop"], r["preset_index"], r["target"]))
    heading = html.escape(tr("Needs attention ({n})", n=len(urgent)))
    if not urgent:
        return '<section class="attention"><h2>%s</h2><p>%s</p></section>' % (heading, html.escape(_calm_words(rows,
                                                                                                               tr)))
    body = []
    for r in urgent:
        state = reading_state(r)
        thumb = ('<a href="%s"><img class="thumb" src="%s" alt="%s"></a>' % (html.escape(r["link"]),
                 html.escape(r["link"]), html.escape(r["target_name"])) if r.get("link") else "")
        body.append('<tr class="%s"><td>%s</td><td>%d %s</td><td>%s<div class="why">%s</div></td><td class="value">%s'
                    '</td><td>%s</td><td>%s</td><td>%s</td></tr>'
                    % (html.escape(state), _badge(state, tr), r["stop"] + 1, _breakable(r["stop_name"]),
                       _breakable(r["target_name"]), html.escape(tr(r["kind"])), _value_cell(r, tr),
                       html.escape(_band(r, tr)), _breakable(r["reason"]) + _acknowledged(r, tr), thumb))
    hint = "<p>%s</p>" % html.escape(tr(
        "Most urgent first. Uncertain values are confirmed or corrected with task_control review or the console's "
        "review queue."))
    return ('<section class="attention"><h2>%s</h2>%s<table><colgroup><col style="width:9%%">'
            '<col style="width:13%%"><col style="width:19%%"><col style="width:11%%"><col style="width:11%%">'
            '<col style="width:24%%"><col style="width:13%%"></colgroup><tr>%s</tr>%s</table></section>'
            % (heading, hint, "".join("<th>%s</th>" % html.escape(tr(h)) for h in
                                      ("state", "stop", "target", "value", "limits", "reason", "picture")),
               "".join(body)))


def _acknowledged(row, tr):
    """The acknowledgement of a row's alarm (task.alarms), as a line of the reason cell."""
    if row.get("ack_time") is None:
        return ""
    note = ": " + row["ack_note"] if row.get("ack_note") else ""
    return '<div class="ack">%s%s</div>' % (html.escape(tr("acknowledged by {name}, {when}", name=row["ack_by"],
                                                           when=_when(row["ack_time"]))), html.escape(note))


def _map_part(yard, tr):
    if not yard:
        return ""
    legend = "".join('<li><span class="dot" style="background:%s"></span>%s</li>'
                     % (STATE_COLOURS[s], html.escape(_state_words(s, tr))) for s in STATE_ORDER + (STATE_NOT_READ,))
    return ('<section class="map"><h2>%s</h2><div class="yardbox">%s<ul class="legend">%s<li>'
            '<span class="dot" style="background:#1e88e5;border-radius:0;height:3px"></span>%s</li>'
            '<li><span class="dot" style="background:#37474f;border-radius:0"></span>%s</li></ul></div>'
            '</section>' % (html.escape(tr("Yard map")), yard, legend, html.escape(tr("driven path")),
                            html.escape(tr("obstacle"))))


def _breakable(name):
    """A target name escaped, with line-break chances after its separators only (never mid-word)."""
    return html.escape(name).replace("/", "/<wbr>").replace("_", "_<wbr>")


def _preset_part(rows, heading, figures, tr):
    """One preset: ``heading`` (the stop's, for its first preset: kept on the page with it), its
    pictures (``figures(rows)``, task.report_pictures) beside its readings' table."""
    first = rows[0]
    body = []
    for number, r in enumerate(rows, 1):
        state = reading_state(r)
        trend = sparkline(r.get("history") or [], (r["low"], r["high"]) if r["low"] is not None else None)
        kind = tr(r["kind"]) + ("" if r["confidence"] is None else ", " + tr("confidence {c}",
                                                                             c="%.0f" % r["confidence"]))
        body.append('<tr class="%s"><td>%d %s<div class="why">%s</div></td><td class="value">%s%s</td>'
                    '<td>%s</td><td>%s<div class="why">%s</div></td></tr>'
                    % (html.escape(state), number, _breakable(r["target_name"]), html.escape(kind),
                       _value_cell(r, tr), trend, html.escape(_band(r, tr)), _badge(state, tr),
                       _breakable(r["reason"])))
    return ('<div class="preset">%s<div class="pics">%s</div><div class="values"><p class="why">%s</p>'
            '<table><colgroup><col style="width:33%%"><col style="width:23%%"><col style="width:18%%">'
            '<col style="width:26%%"></colgroup><tr>%s</tr>%s</table></div></div>'
            % (heading, figures(rows), html.escape(tr("preset {preset}, {when}", preset=preset_label(first["preset"]),
                                                      when=_when(first["time"]))),
               "".join("<th>%s</th>" % html.escape(tr(h)) for h in ("target", "value, trend", "limits", "state")),
               "".join(body)))


def _stops_part(rows, stops, figures, tr):
    by_stop = {}
    for r in rows:
        by_stop.setdefault(r["stop"], {}).setdefault(r["preset_index"], []).append(r)
    parts = []
    for i in sorted(set(range(len(stops))) | set(by_stop)):
        presets = by_stop.get(i, {})
        name = stops[i]["name"] if i < len(stops) else next(iter(presets.values()))[0]["stop_name"]
        state = worst_state([r for p in presets.values() for r in p])
        heading = '<h3>%d %s %s</h3>' % (i + 1, _breakable(name), _badge(state, tr))
        parts.append('<article class="stop" id="stop-%d">%s</article>'
                     % (i + 1, "".join(_preset_part(sorted(presets[j], key=lambda r: r["target"]),
                                                    heading if k == 0 else "", figures, tr)
                                       for k, j in enumerate(sorted(presets)))
                        or heading + '<p class="why">%s</p>' % html.escape(tr("no readings"))))
    return '<section class="stops"><h2>%s</h2>%s</section>' % (html.escape(tr("Stops")), "".join(parts))


def render_html(info, readings, yard="", stops=(), figures=None, tr=ENGLISH, language="en"):
    """The report page of a task: ``info`` its summary, ``readings`` client rows with ``link`` (the
    picture's href) and ``history``, ``yard`` the map's SVG (yard_svg; "" for none), ``stops`` the
    task's stops (a stop without readings is listed as such), ``figures(rows)`` a preset's pictures
    (None: each annotated picture once, by its ``link``), ``tr`` the translator of ``language``."""
    if figures is None:
        links = dict((r["picture"], r["link"]) for r in readings if r.get("link"))
        figures = figures_of(links.get, "")
    title = html.escape(tr("Patrol report {id}", id=info["task_id"]))
    return ('<!DOCTYPE html>\n<html lang="%(lang)s"><head><meta charset="utf-8">'
            '<meta name="viewport" content="width=device-width, initial-scale=1">'
            '<title>%(title)s</title><style>%(css)s</style></head><body>\n'
            '<h1>%(title)s</h1><p>%(version)s</p>\n%(summary)s\n%(attention)s\n%(map)s\n'
            '%(stops)s\n</body></html>\n'
            % {"lang": html.escape(language), "title": title, "css": CSS,
               "version": html.escape(tr("robot software {version}", version=info.get("software_version"))),
               "summary": _summary_part(info, readings, tr), "attention": _attention_part(readings, tr),
               "map": _map_part(yard, tr), "stops": _stops_part(readings, stops, figures, tr)})


def figures_of(link_of, data_root):
    """A preset's pictures with its boxes in their states' colours (task.report_pictures)."""
    return lambda rows: preset_figures(rows, lambda p: link_of(p) or "", lambda r: STATE_COLOURS[reading_state(r)],
                                       data_root)
