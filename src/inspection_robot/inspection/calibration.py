"""The calibration tool's library: turns target descriptions into preset_calib_info.ini + zoomX.xml.

A target description (a dict, e.g. one entry of the YAML the command-line tool reads, or what a
web page would post) has ``kind`` (pointer | lamp | switch | thermal), ``box`` (8 numbers: TL,
TR, BR, BL in zoom0.jpg) and the kind's parameters (see preset.Target). Switch targets give
``open_picture`` / ``closed_picture``: pictures of the same view with the switch open / closed,
from which reference patches are cut; lamps may give ``on_picture`` / ``off_picture`` likewise.
Boxes in the wider zoom pictures follow from the zoom levels and the camera's optics (the pictures
share the optical centre).
"""
import os

import numpy as np

from inspection_robot.lazy import lazy_import
from inspection_robot.inspection.geometry import quad_inside, quad_is_convex
from inspection_robot.files import write_atomic
from inspection_robot.inspection.preset import TARGET_KINDS, PresetError, Target, load_info, write_calibration
from inspection_robot.inspection.readers import lamp_patch, switch_patch

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load


def derive_zoom_boxes(box0, zoom_levels, optics, width, height):
    """{zoom index: quad} of a box given in zoom0 for every zoom picture (pure zoom about the centre)."""
    box0 = np.asarray(box0, np.float64).reshape(4, 2)
    centre = np.array([(width - 1) / 2.0, (height - 1) / 2.0])
    f0 = optics.focal_px(zoom_levels[0], width)
    return dict((k, centre + (box0 - centre) * optics.focal_px(level, width) / f0)
                for k, level in enumerate(zoom_levels))


def _picture_size(preset_dir, info):
    if info.width > 0 and info.height > 0:
        return info.width, info.height
    image = cv2.imread(os.path.join(preset_dir, "zoom0.jpg"))
    if image is None:
        raise PresetError("zoom0.jpg missing or unreadable in %s" % preset_dir)
    return image.shape[1], image.shape[0]


def build_targets(preset_dir, specs, optics):
    """Validate ``specs``; return (info, targets, patches): ``patches`` are the reference patches
    {file name: image} the targets name, not yet written (a bad spec leaves the preset untouched)."""
    info = load_info(preset_dir)
    width, height = _picture_size(preset_dir, info)
    if not specs:
        raise PresetError("no targets given")
    targets, patches = [], {}
    for i, spec in enumerate(specs):
        if not isinstance(spec, dict):
            raise PresetError("target %d: expected an object with kind, box and parameters" % i)
        spec = dict(spec)
        kind = spec.pop("kind", None)
        try:
            box = np.asarray(spec.pop("box"), np.float64).reshape(4, 2)
        except (KeyError, TypeError, ValueError) as err:
            raise PresetError("target %d: box must be 8 numbers TL,TR,BR,BL (%s)" % (i, err))
        if not np.all(np.isfinite(box)):
            raise PresetError("target %d: box must be finite numbers" % i)
        if not quad_is_convex(box):
            raise PresetError("target %d: box is not a convex TL,TR,BR,BL quad" % i)
        if not quad_inside(box, width, height):
            raise PresetError("target %d: box lies outside the %dx%d picture" % (i, width, height))
        states = {"switch": ("open", "closed"), "lamp": ("on", "off")}.get(kind, ())
        if kind == "lamp" and not any(spec.get(state + "_picture") for state in states):
            states = ()   # lamp references are optional
        for state in states:
            picture = spec.pop(state + "_picture", None)
            image = cv2.imread(picture) if isinstance(picture, str) and picture else None
            if image is None:
                raise PresetError("target %d: %s_picture missing or unreadable: %s" % (i, state, picture))
            name = "target_%d_%s.png" % (i, state)
            patches[name] = switch_patch(image, box) if kind == "switch" else lamp_patch(image, box)
            spec[state + "_reference"] = name
        name = str(spec.pop("name", ""))
        try:
            targets.append(Target(kind, derive_zoom_boxes(box, info.zoom_levels, optics, width, height),
                                  name=name, **spec))
        except (KeyError, TypeError, ValueError) as err:
            raise PresetError("target %d (%s): bad or missing parameter: %s" % (i, kind, err))
    return info, targets, patches


def calibrate(preset_dir, specs, optics):
    """Write the calibration of ``preset_dir``; returns the Target list. Raises PresetError and
    writes nothing when any target is bad."""
    info, targets, patches = build_targets(preset_dir, specs, optics)
    for name, patch in sorted(patches.items()):
        ok, data = cv2.imencode(".png", patch)
        if not ok:
            raise PresetError("cannot encode reference patch %s" % name)
        write_atomic(os.path.join(preset_dir, name), data.tobytes())
    write_calibration(preset_dir, targets, info)
    return targets


# --- the calibration tool's operations, one target at a time ----------------------------------
# A draft is the list of target specs being built (the format calibrate() takes); the operations
# below edit it one field group at a time (what the tool's operator does with the mouse), and
# calibrate(draft) applies it. Shared by tools/calibrate_preset.py and the calibration_control
# commands (inspection/calibration_commands.py).
DRAFT_FILE = "calibration_draft.json"
POINTER_FIELDS = {"name": str, "unit": str, "centre": "pair", "radius": float, "aspect": float,
                  "scale_table": "table"}
VALUE_FIELDS = dict(POINTER_FIELDS, colour=str, thermal_box="box",
                    open_picture=str, closed_picture=str, on_picture=str, off_picture=str)
PICTURE_FIELDS = ("open_picture", "closed_picture", "on_picture", "off_picture")


def _number(value, name):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise PresetError("%s must be a finite number, got %r" % (name, value))
    return float(value)


def _numbers(value, count, name):
    if not isinstance(value, (list, tuple)) or len(value) != count:
        raise PresetError("%s must be a list of %d numbers, got %r" % (name, count, value))
    return [_number(v, name) for v in value]


def _check_field(name, value, kind):
    if kind is str:
        if not isinstance(value, str):
            raise PresetError("%s must be a string, got %r" % (name, value))
        return value
    if kind is float:
        return _number(value, name)
    if kind == "pair":
        return _numbers(value, 2, name)
    if kind == "box":
        return _numbers(value, 8, name)
    if not isinstance(value, list):
        raise PresetError("%s must be a list of [value, angle] pairs, got %r" % (name, value))
    return [_numbers(pair, 2, name + " entry") for pair in value]


def _target(draft, index, may_append=False):
    if isinstance(index, bool) or not isinstance(index, int):
        raise PresetError("target must be an integer index, got %r" % (index,))
    top = len(draft) if may_append else len(draft) - 1
    if not 0 <= index <= top:
        raise PresetError("target %d does not exist (the draft has %d target(s)%s)"
                          % (index, len(draft), "; mark_box %d adds one" % len(draft) if not may_append else ""))
    if index == len(draft):
        draft.append({"kind": "pointer"})
    return draft[index]


def mark_box(draft, index, box):
    """Set target ``index``'s box (8 numbers TL,TR,BR,BL in zoom0.jpg px); index len(draft) adds a
    pointer target."""
    _target(draft, index, may_append=True)["box"] = _numbers(box, 8, "box")


def set_meter_type(draft, index, kind):
    if kind not in TARGET_KINDS:
        raise PresetError("meter type must be one of %s, got %r" % ("|".join(TARGET_KINDS), kind))
    _target(draft, index)["kind"] = kind


def set_zero(draft, index, angle_deg, value):
    """The scale's start: the needle at ``angle_deg`` (clockwise from up) reads ``value``."""
    target = _target(draft, index)
    target["start_angle"], target["start_value"] = _number(angle_deg, "angle"), _number(value, "value")


def set_full_scale(draft, index, angle_deg, value):
    target = _target(draft, index)
    target["end_angle"], target["end_value"] = _number(angle_deg, "angle"), _number(value, "value")


def set_values(draft, index, values):
    """Set further parameters of a target (name, unit, scale_table, centre, radius, aspect, colour,
    thermal_box, <state>_picture); unknown names are refused."""
    if not isinstance(values, dict) or not values:
        raise PresetError("values must be a non-empty object")
    unknown = sorted(set(values) - set(VALUE_FIELDS))
    if unknown:
        raise PresetError("unknown value(s) %s (allowed: %s)" % (", ".join(unknown), ", ".join(sorted(VALUE_FIELDS))))
    checked = dict((name, _check_field(name, value, VALUE_FIELDS[name])) for name, value in values.items())
    _target(draft, index).update(checked)


def remove_target(draft, index):
    _target(draft, index)
    del draft[index]
