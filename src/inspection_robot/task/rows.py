"""The results-store rows of one inspected preset, and the last_result summary of them.

A row per target (plus one for foreign objects when asked); a value the reader doubts is kept with
status ``uncertain`` and the reader's reason. Thermal targets that name a phase of a device are
diagnosed together (thermal.diagnosis, DL/T 664): each phase's row carries the device's
``diagnosis`` (JSON), the hottest phase's row its defect ``grade``, and a defect is an alarm
(a ``check`` when its reading is uncertain) whose reason is the criterion that fired.
"""
import json
import math

from inspection_robot.task.display import row_display
from inspection_robot.task.spec import split_limits
from inspection_robot.task.states import (ALARM_ALARM, ALARM_CHECK, STATUS_FAILED, STATUS_READ, STATUS_UNCERTAIN,
                                          alarm_state, target_unit)
from inspection_robot.thermal.diagnosis import (DEFAULT_CLASS, DEFAULT_RULES, DiagnosisError, GRADE_NONE, diagnose,
                                                object_temperature, thermal_groups)


def reading_rows(task_id, stop_index, stop_name, preset_index, preset, inspection, reason, now,
                 thermal_rules=DEFAULT_RULES):
    """The store rows of one preset (``inspection`` None: every target failed with ``reason``);
    ``thermal_rules``: the grade rules per equipment class (thermal.diagnosis.check_rules)."""
    rows = []
    targets = preset["targets"]
    pose = inspection.pose if inspection is not None and inspection.pose else (None, None, None)
    values = [None] * len(targets)
    if inspection is not None:
        values = [float(v) if math.isfinite(float(v)) else None for v in inspection.values[:len(targets)]]
    findings = thermal_findings(targets, values, thermal_rules)
    for k, target in enumerate(targets):
        band = preset["alarms"].get(target["name"])
        value = confidence = None
        picture = doubt = ""
        source = None
        if inspection is not None:
            value, confidence = float(inspection.values[k]), float(inspection.confidences[k])
            picture = inspection.pictures[k] if k < len(inspection.pictures) else ""
            doubt = inspection.reasons[k] if inspection.reasons else ""
            source = inspection.sources[k] if inspection.sources else None
        finding = findings.get(k)
        if finding is not None:
            value = finding["value"]
        unit = target_unit(target["kind"], target.get("unit", ""))   # also for tasks stored without it
        row = _row(task_id, stop_index, stop_name, preset_index, preset, k, target["name"], target["kind"],
                   value, unit, band, confidence, picture, pose, now, doubt or reason, bool(doubt), source,
                   target.get("decimals"))
        if finding is not None:
            _apply_finding(row, finding)
        rows.append(row)
    if preset.get("foreign"):
        foreign = inspection.foreign if inspection is not None else None
        value, confidence, picture = (float(foreign[0]), float(foreign[1]), foreign[2]) if foreign else (None, None, "")
        rows.append(_row(task_id, stop_index, stop_name, preset_index, preset, len(targets), "foreign",
                         "foreign", value, "objects", [0.0, 0.0], confidence, picture, pose, now,
                         reason or ("" if foreign else "no foreign-object result"), decimals=0))
    return rows


def thermal_findings(targets, values, rules=DEFAULT_RULES):
    """{target index: finding} for the phase boxes of ``targets`` (the task's resolved targets) read
    as ``values`` (degC, None: not read). A finding: ``value`` (corrected for the box's emissivity
    and distance when it has them and its device an ambient box), ``grade`` (the hottest phase's only) and
    ``diagnosis`` (what the device's phases, ambient and criteria gave)."""
    thermal = [(k, t.get("phase", ""), t.get("device", "")) for k, t in enumerate(targets)
               if t["kind"] == "thermal"]
    try:
        groups = thermal_groups(thermal)
    except DiagnosisError:   # a calibration checked at upload cannot: a stored task edited by hand
        return {}
    out = {}
    for device, (phases, ambient_index) in groups.items():
        ambient = values[ambient_index] if ambient_index is not None else None
        corrected, notes = {}, []
        for phase, k in phases.items():
            if values[k] is None:
                notes.append("phase %s not read" % phase)
                continue
            emissivity, distance = targets[k].get("emissivity", 1.0), targets[k].get("distance", 0.0)
            corrected[phase] = values[k]
            if emissivity < 1.0 or distance > 0.0:
                if ambient is None:
                    notes.append("emissivity and distance of phase %s not applied: no ambient reading" % phase)
                    continue
                try:
                    corrected[phase] = object_temperature(values[k], emissivity, ambient, distance)
                except DiagnosisError as err:
                    notes.append("phase %s: %s" % (phase, err))
        if not corrected:
            continue
        class_name = next((targets[k].get("equipment_class") for k in phases.values()
                           if targets[k].get("equipment_class")), DEFAULT_CLASS)
        found = diagnose(corrected, ambient, rules[class_name], class_name)
        diagnosis = {"device": device, "class": class_name, "grade": found.grade, "rule": found.rule,
                     "hot_phase": found.hot_phase, "t1": _round(found.t1), "t2": _round(found.t2),
                     "t0": _round(found.t0), "rise": _round(found.rise), "diff": _round(found.diff),
                     "delta_t": _round(found.delta_t), "phases": dict((p, _round(t)) for p, t in corrected.items()),
                     "apparent": dict((p, _round(values[k])) for p, k in phases.items() if values[k] is not None),
                     "notes": notes}
        for phase, k in phases.items():
            if phase in corrected:
                out[k] = {"value": corrected[phase], "diagnosis": diagnosis,
                          "grade": found.grade if phase == found.hot_phase else GRADE_NONE}
    return out


def _apply_finding(row, finding):
    row["diagnosis"] = json.dumps(finding["diagnosis"], sort_keys=True)
    row["grade"] = finding["grade"]
    if finding["grade"] == GRADE_NONE or row["status"] == STATUS_FAILED:
        return
    d = finding["diagnosis"]
    context = "phase %s %.1f C" % (d["hot_phase"], d["t1"])
    if d["t2"] is not None:
        context += ", coolest sister %.1f C" % d["t2"]
    if d["t0"] is not None:
        context += ", ambient %.1f C" % d["t0"]
    words = "%s (%s)" % (d["rule"], context)
    row["alarm"] = ALARM_CHECK if row["status"] == STATUS_UNCERTAIN else ALARM_ALARM
    row["reason"] = "%s; %s" % (words, row["reason"]) if row["reason"] else words


def _round(value):
    return None if value is None else round(float(value), 2)


def _row(task_id, stop_index, stop_name, preset_index, preset, target, name, kind, value, unit, limits, confidence,
         picture, pose, now, reason, uncertain=False, source=None, decimals=None):
    """``limits``: the target's (task.spec.parse_limits) or None; ``source``: {"picture": the picture
    read, "roi": its box (8 numbers)} or None; ``decimals``: the target's resolution (task.display;
    None for tasks stored before targets carried it)."""
    normal, alarm = split_limits(limits)
    if value is not None and not math.isfinite(value):
        value, reason, uncertain = None, "reading is not a finite number", False
    status = STATUS_FAILED if value is None else STATUS_UNCERTAIN if uncertain else STATUS_READ
    return {"task_id": task_id, "stop": stop_index, "stop_name": stop_name, "preset_index": preset_index,
            "preset": preset["directory"], "target": target, "target_name": name, "kind": kind,
            "status": status, "value": value, "unit": unit, "alarm": alarm_state(value, normal, uncertain, alarm),
            "low": normal[0] if normal else None, "high": normal[1] if normal else None,
            "alarm_low": alarm[0] if alarm else None, "alarm_high": alarm[1] if alarm else None,
            "confidence": confidence, "picture": picture, "x": pose[0], "y": pose[1], "yaw": pose[2], "time": now,
            "reason": reason, "source_picture": source["picture"] if source else "",
            "roi": ",".join("%.1f" % v for v in source["roi"]) if source else "", "decimals": decimals,
            "grade": GRADE_NONE, "diagnosis": ""}


def result_summary(rows):
    """last_result of task_status: the preset just recorded, its values, alarms and doubts."""
    return {"stop": rows[0]["stop"] + 1, "preset": rows[0]["preset"],
            "readings": [{"target": r["target_name"], "value": r["value"], "unit": r["unit"], "alarm": r["alarm"],
                          "status": r["status"], "reason": r["reason"], "display": row_display(r)["display"]}
                         for r in rows],
            "alarms": sum(1 for r in rows if r["alarm"] in (ALARM_ALARM, ALARM_CHECK)),
            "uncertain": sum(1 for r in rows if r["status"] == STATUS_UNCERTAIN),
            "failed": sum(1 for r in rows if r["status"] == STATUS_FAILED),
            "reason": next((r["reason"] for r in rows if r["status"] == STATUS_FAILED), "")}
