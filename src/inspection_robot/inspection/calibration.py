"""The calibration tool's library: turns target descriptions into preset_calib_info.ini + zoomX.xml.

A target description (a dict, e.g. one entry of the YAML the command-line tool reads, or what a
web page would post) has ``kind`` (pointer | lamp | switch | thermal), ``box`` (8 numbers: TL,
TR, BR, BL in zoom0.jpg) and the kind's keys (inspection.calibration_schema: the keys, their
ranges, refusals by name). Switch targets give
``open_picture`` / ``closed_picture``: pictures of the same view with the switch open / closed,
from which reference patches are cut; lamps may give ``on_picture`` / ``off_picture`` likewise.
Boxes in the wider zoom pictures follow from the zoom levels and the camera's optics (the pictures
share the optical centre).
"""
import os
import re

import numpy as np

from inspection_robot.lazy import lazy_import
from inspection_robot.dir_update import DirUpdate
from inspection_robot.files import write_atomic, write_json_atomic
from inspection_robot.inspection import calibration_schema as schema
from inspection_robot.inspection.preset import (REFERENCE_KEYS, TARGET_KINDS, PresetError, Target, load_info,
                                                write_calibration, zoom_picture_name)
from inspection_robot.inspection.digital import FULL_BOX, parse_shown
from inspection_robot.inspection.digital_learn import learn_display
from inspection_robot.inspection.drum import learn_drum
from inspection_robot.inspection.geometry import quad_inside
from inspection_robot.inspection.lamp import lamp_patch
from inspection_robot.inspection.needle import ANGLE_STEP_DEG
from inspection_robot.inspection.needle_model import NeedleModel
from inspection_robot.inspection.pointer import GENERIC, PointerReader
from inspection_robot.inspection.readers import ReadFailed
from inspection_robot.inspection.switch import switch_patch
from inspection_robot.inspection.reading import decode_reference, learn_pointer, read_pointer
from inspection_robot.thermal.diagnosis import DiagnosisError, thermal_groups

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load

MAX_REFERENCE_BYTES = 16 << 20   # a reference file named in the preset directory (patches are ~10 KB)


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


def _thermal_size(preset_dir, info):
    """(w, h) of the preset's thermal picture, None when it has none (thermal boxes are then only
    bounded, see calibration_schema)."""
    if not info.thermal_picture:
        return None
    image = cv2.imread(os.path.join(preset_dir, info.thermal_picture), cv2.IMREAD_UNCHANGED)
    return None if image is None else (image.shape[1], image.shape[0])


def build_targets(preset_dir, specs, optics):
    """Validate ``specs`` against the calibration schema; return (info, targets, patches):
    ``patches`` are the reference patches {file name: image} the targets name, not yet written (a
    bad spec leaves the preset untouched)."""
    info = load_info(preset_dir)
    width, height = _picture_size(preset_dir, info)
    if not isinstance(specs, (list, tuple)):
        raise PresetError("targets must be a list of target objects")
    if not specs:
        raise PresetError("no targets given")
    if len(specs) > schema.MAX_TARGETS:
        raise PresetError("%d targets given, at most %d per preset" % (len(specs), schema.MAX_TARGETS))
    thermal = any(isinstance(s, dict) and s.get("kind") == "thermal" for s in specs)
    thermal_size = _thermal_size(preset_dir, info) if thermal else None
    targets, patches = [], {}
    zoom0 = None
    for i, spec in enumerate(specs):
        if isinstance(spec, dict) and spec.get("kind") == "digital" and "shown" in spec:
            if zoom0 is None:
                zoom0 = cv2.imread(os.path.join(preset_dir, zoom_picture_name(0)), cv2.IMREAD_COLOR)
            spec = _learned_display(spec, i, zoom0, width, height)
        try:
            kind, box, name, params, pictures = schema.check_spec(spec, i, width, height, thermal_size)
        except schema.SchemaError as err:
            kind = spec.get("kind") if isinstance(spec, dict) and spec.get("kind") in TARGET_KINDS else None
            raise PresetError("target %d%s: %s" % (i, " (%s)" % kind if kind else "", err))
        for state, picture in sorted(pictures.items()):
            image = cv2.imread(picture) if picture else None
            if image is None:
                raise PresetError("target %d: %s_picture missing or unreadable: %s" % (i, state, picture))
            patches[params[state + "_reference"]] = switch_patch(image, box) if kind == "switch" \
                else lamp_patch(image, box)
        for state in ("on", "off", "open", "closed", "needle"):
            reference = params.get(state + "_reference")
            if state not in pictures and reference:
                _check_reference(preset_dir, i, kind, state, reference)
        targets.append(Target(kind, derive_zoom_boxes(box, info.zoom_levels, optics, width, height),
                              name=name, thermal_size=thermal_size, **params))
    try:
        thermal_groups([(i, t.params.get("phase", ""), t.params.get("device", ""))
                        for i, t in enumerate(targets) if t.kind == "thermal"])
    except DiagnosisError as err:
        raise PresetError("thermal phases: %s" % err)
    return info, targets, patches


def _learned_display(spec, index, image, width, height):
    """A digital target spec whose ``shown`` (the text the display shows in zoom0.jpg) is replaced by
    the display model learned from the picture (inspection.digital_learn.learn_display, or learn_drum for
    ``style: drum``: a model the picture reads back under as that text). PresetError names what
    failed."""
    spec = dict(spec)
    shown = spec.pop("shown")
    try:
        schema.check_value("shown", shown)
        box = np.reshape(schema.check_value("box", spec.get("box")), (4, 2))
    except schema.SchemaError as err:
        raise PresetError("target %d (digital): %s" % (index, err))
    if image is None:
        raise PresetError("target %d (digital): zoom0.jpg missing or unreadable: a display is learned from it" % index)
    if not quad_inside(box, width, height):
        raise PresetError("target %d (digital): box lies outside the %dx%d picture" % (index, width, height))
    cells, decimals, _value = parse_shown(shown)
    drum = spec.get("style") == "drum"
    try:   # each learns only a model the picture reads back under as typed, without doubt
        model = learn_drum(image, box, cells, decimals) if drum else learn_display(image, box, shown)
    except ReadFailed as err:
        raise PresetError("target %d (digital): %s" % (index, err))
    spec.update(digit_count=model.digit_count, polarity=model.polarity, decimals=model.decimals,
                contrast=model.contrast)
    if drum:
        spec.update(font=model.font, glyph=model.glyph)
    else:
        spec.update(slant=model.slant_deg, fill=model.fill)
        if tuple(model.window) != FULL_BOX:
            spec["window"] = list(model.window)
        if any(model.shifts):
            spec["cell_shifts"] = list(model.shifts)
        if model.split != "gap":
            spec["split"] = model.split
    return spec


def _check_reference(preset_dir, index, kind, state, name):
    """A reference patch named in the preset directory must be there and decode as the reader
    decodes it (reading.decode_reference): a text file refused now, not at patrol time."""
    try:
        with open(os.path.join(preset_dir, name), "rb") as f:
            data = f.read(MAX_REFERENCE_BYTES + 1)
    except OSError:
        data = None
    _check_reference_data(index, kind, state, name, data)


def _check_reference_data(index, kind, state, name, data):
    """The check of _check_reference on a file's bytes (None: not there)."""
    if data is None:
        raise PresetError("target %d: %s_reference %s is not in the preset directory" % (index, state, name))
    if len(data) > MAX_REFERENCE_BYTES:
        raise PresetError("target %d: %s_reference %s is larger than %d bytes: not a reference patch"
                          % (index, state, name, MAX_REFERENCE_BYTES))
    if state == "needle":   # decoded as the reader decodes it: a picture of the wrong shape is no model
        if NeedleModel.decode(data, ANGLE_STEP_DEG) is None:
            raise PresetError("target %d: needle_reference %s is not a needle model the reader can decode (it is "
                              "learned at calibration: give the value shown instead)" % (index, name))
    elif decode_reference(data, kind) is None:
        raise PresetError("target %d: %s_reference %s is not a picture the reader can decode (PNG, JPEG, ...)"
                          % (index, state, name))


def check_references(preset):
    """Every reference file a loaded preset's calibration names (a lamp's or switch's patches, a
    needle model) is in its snapshot and decodes as the reader decodes it; PresetError naming the
    first that does not. task_manager checks this when a task is submitted, so a file lost or
    damaged since calibration refuses the task before the robot drives to the stop."""
    for i, target in enumerate(preset.targets):
        for key in REFERENCE_KEYS:
            name = target.params.get(key)
            if name:
                _check_reference_data(i, target.kind, key[:-len("_reference")], name, preset.reference(name))


def _refuse_shared_files(targets, written):
    """A file calibration writes for target i (``target_<i>_<what>.png``: a patch cut from its
    picture, its learned needle model) must be named by no other target: an uploaded lamp reference
    called ``target_2_needle.png`` would be overwritten by target 2's model and read as a lamp."""
    for i, target in enumerate(targets):
        for key, name in sorted(target.params.items()):
            owner = re.match(r"target_(\d+)_", str(name)) if key.endswith("_reference") else None
            if owner and name in written and int(owner.group(1)) != i:
                raise PresetError("target %d: %s %s is the name of a file calibration writes for target %s: "
                                  "choose another name" % (i, key, name, owner.group(1)))


def calibrate(preset_dir, specs, optics, draft=None, check=None):
    """Write the calibration of ``preset_dir``; returns the Target list. Raises PresetError and
    writes nothing when any target is bad, or when ``check(preset_dir, targets)`` (a SelfCheck)
    refuses the built targets.

    All or nothing: the reference patches, zoom<k>.xml, preset_calib_info.ini and (``draft`` not
    None) the draft are written into a copy of the preset directory that replaces it in one rename
    (dir_update.DirUpdate); an I/O failure (FileError) leaves the old calibration as it was.
    """
    preset_dir = os.path.realpath(preset_dir)
    info, targets, patches = build_targets(preset_dir, specs, optics)
    if check is not None:
        check(preset_dir, targets)
    encoded = dict(check.patches) if check is not None else {}   # the needle models it learned
    _refuse_shared_files(targets, list(encoded) + list(patches))
    for name, patch in sorted(patches.items()):
        ok, data = cv2.imencode(".png", patch)
        if not ok:
            raise PresetError("cannot encode reference patch %s" % name)
        encoded[name] = data.tobytes()
    with DirUpdate(preset_dir) as update:
        for name, data in sorted(encoded.items()):
            write_atomic(update.file(name), data)
        write_calibration(update.path, targets, info)
        if draft is not None:
            write_json_atomic(update.file(DRAFT_FILE), draft)
        update.commit()
    return targets


SELF_CHECK_FS = 0.02   # the reader may differ from the operator's expected value by this share of full scale


class SelfCheck(object):
    """Reads every pointer target on the calibration picture (zoom0.jpg) as soon as its calibration
    is built, before it is written, and learns each pointer's needle model there
    (inspection.needle_model): the operator sees what the reader makes of the meter they just
    calibrated, beside the value they see (``results``).

    With ``expected`` (one value or None per target, calibration order) the model is learned from the
    needle at that value, and the calibration is refused with the reason, unless ``force``, when no
    needle lies there, when the model cannot tell it from another pointer, or when the reader
    without a model confidently reads another value (more than SELF_CHECK_FS of full scale away): a
    wrong scale point, a box on the wrong meter, a pivot the reader cannot use, or the value of a
    drag or set pointer typed for the live needle's shows at calibration, not in a patrol. Without
    a value the model is learned from the reader's own confident reading; a target it cannot learn
    keeps the line fit alone (``needle_model`` in its result says which). ``patches``: the models'
    PNG files {name: bytes}, written with the calibration.
    """

    def __init__(self, expected=None, force=False, reader=None):
        self.expected = expected
        self.force = bool(force)
        self._reader = reader
        self.results = []
        self.patches = {}

    def __call__(self, preset_dir, targets):
        expected = self.expected or [None] * len(targets)
        if len(expected) != len(targets):
            raise PresetError("expected has %d value(s) for %d target(s): give one per target (null for none)"
                              % (len(expected), len(targets)))
        picture = os.path.join(preset_dir, zoom_picture_name(0))
        image = cv2.imread(picture, cv2.IMREAD_COLOR) if os.path.isfile(picture) else None
        if self._reader is None:
            self._reader = PointerReader()
        problems = []
        for i, (target, value) in enumerate(zip(targets, expected)):
            if target.kind != "pointer":
                if value is not None:
                    problems.append("target %d (%s) is a %s: expected values are for pointer targets"
                                    % (i, target.name, target.kind))
                continue
            entry = self._read(i, target, image, value)
            self.results.append(entry)
            low, high = sorted((target.scale.start_value, target.scale.end_value))
            if value is not None and not low <= value <= high:
                problems.append("target %d (%s): you expect %.4g, outside its scale %.4g .. %.4g"
                                % (i, target.name, value, target.scale.start_value, target.scale.end_value))
                continue
            if value is not None and entry["read"] is None:
                problems.append("target %d (%s): the reader cannot read the calibration picture: %s"
                                % (i, target.name, entry["reason"]))
            elif value is not None and entry["apart_fs_pct"] > 100.0 * SELF_CHECK_FS and not entry["reason"]:
                problems.append("target %d (%s): the reader reads %.4g on the calibration picture, you expect %.4g: "
                                "%.1f %% of full scale apart (at most %g %%); check the scale points, the box and "
                                "the pivot, and that %.4g is the live needle's value, not a drag or set pointer's"
                                % (i, target.name, entry["read"], value, entry["apart_fs_pct"],
                                   100.0 * SELF_CHECK_FS, value))
            problem = self._learn(i, target, image, value, entry)
            if problem:
                problems.append("target %d (%s): %s" % (i, target.name, problem))
        if problems and not self.force:
            raise PresetError("; ".join(problems) + " (force: true applies it anyway)")

    def _read(self, index, target, image, expected, model=None):
        entry = {"target": index, "name": target.name, "read": None, "confidence": None, "expected": expected,
                 "apart_fs_pct": None, "reason": "", "needle_model": GENERIC}
        if image is None:
            entry["reason"] = "zoom0.jpg missing or unreadable"
            return entry
        try:
            reading = read_pointer(self._reader, target, image, target.boxes[0], model)
        except ReadFailed as err:
            entry["reason"] = str(err)
            return entry
        entry.update(read=round(float(reading.value), 6), confidence=round(float(reading.confidence), 1),
                     reason=reading.detail.get("reason", ""))
        if expected is not None:
            full_scale = abs(target.scale.end_value - target.scale.start_value)
            entry["apart_fs_pct"] = round(100.0 * abs(reading.value - expected) / full_scale, 2)
        return entry

    def _learn(self, index, target, image, expected, entry):
        """Learns the target's needle model (see the class docstring) and reads the picture again with
        it, as a patrol will (``entry`` updated); returns why the given value's needle could not be
        learned, "" otherwise."""
        value = expected
        if value is None and entry["read"] is not None and not entry["reason"]:
            value = entry["read"]          # the reader's own confident reading
        if value is None or entry["read"] is None:
            return ""
        try:
            model = learn_pointer(self._reader, target, image, target.boxes[0], value)
        except ReadFailed as err:
            entry["needle_model"] = "%s; not learned: %s" % (GENERIC, err)
            return str(err) if expected is not None else ""
        name = "target_%d_needle.png" % index
        target.params["needle_reference"] = schema.check_value("needle_reference", name)
        self.patches[name] = model.encode()
        entry.update(self._read(index, target, image, expected, model), line_fit_read=entry["read"],
                     needle_model="learned from %s" % ("the value given" if expected is not None
                                                       else "the reader's own reading"))
        return ""


# --- the calibration tool's operations, one target at a time ----------------------------------
# A draft is the list of target specs being built (the format calibrate() takes); the operations
# below edit it one field group at a time (what the tool's operator does with the mouse), and
# calibrate(draft) applies it. Each value is checked by the calibration schema as it comes in;
# what depends on the whole target (its kind's keys, the scale) is checked by apply.
# Shared by tools/calibrate_preset.py and the calibration_control commands
# (inspection/calibration_commands.py).
DRAFT_FILE = "calibration_draft.json"
VALUE_FIELDS = tuple(sorted(k for k in schema.FIELDS if k not in ("kind", "box")))
PICTURE_FIELDS = tuple("%s_picture" % state for states in schema.PICTURE_STATES.values() for state in states)


def _checked(key, value):
    try:
        return schema.check_value(key, value)
    except schema.SchemaError as err:
        raise PresetError(str(err))


def _target(draft, index, may_append=False):
    if isinstance(index, bool) or not isinstance(index, int):
        raise PresetError("target must be an integer index, got %r" % (index,))
    top = len(draft) if may_append else len(draft) - 1
    if not 0 <= index <= top:
        raise PresetError("target %d does not exist (the draft has %d target(s)%s)"
                          % (index, len(draft), "; mark_box %d adds one" % len(draft) if not may_append else ""))
    if index == len(draft):
        if len(draft) >= schema.MAX_TARGETS:
            raise PresetError("the draft has %d targets, at most %d per preset" % (len(draft), schema.MAX_TARGETS))
        draft.append({"kind": "pointer"})
    return draft[index]


def mark_box(draft, index, box):
    """Set target ``index``'s box (8 numbers TL,TR,BR,BL in zoom0.jpg px); index len(draft) adds a
    pointer target."""
    box = _checked("box", box)
    _target(draft, index, may_append=True)["box"] = box


def set_meter_type(draft, index, kind):
    """Change the target's kind; returns the keys it had that the new kind does not take, which
    are removed (apply would refuse them, and no edit can remove a key)."""
    if kind not in TARGET_KINDS:
        raise PresetError("meter type must be one of %s, got %r" % ("|".join(TARGET_KINDS), kind))
    target = _target(draft, index)
    keep = set(schema.kind_keys(kind, stored=False)) | {"kind", "box", "name"}
    dropped = sorted(k for k in target if k not in keep)
    for key in dropped:
        del target[key]
    target["kind"] = kind
    return dropped


def set_zero(draft, index, angle_deg, value):
    """The scale's start: the needle at ``angle_deg`` (clockwise from up) reads ``value``."""
    angle, value = _checked("start_angle", angle_deg), _checked("start_value", value)
    target = _target(draft, index)
    target["start_angle"], target["start_value"] = angle, value


def set_full_scale(draft, index, angle_deg, value):
    angle, value = _checked("end_angle", angle_deg), _checked("end_value", value)
    target = _target(draft, index)
    target["end_angle"], target["end_value"] = angle, value


def set_values(draft, index, values):
    """Set further keys of a target (any key of the calibration schema but kind and box, e.g. name,
    unit, scale_table, centre, radius, colour, thermal_box, <state>_picture); each value is
    checked, an unknown key is refused by name."""
    if not isinstance(values, dict) or not values:
        raise PresetError("values must be a non-empty object")
    for key in values:
        if key not in VALUE_FIELDS:
            raise PresetError("unknown key %r (allowed: %s)" % (key, ", ".join(VALUE_FIELDS)))
    checked = dict((key, _checked(key, value)) for key, value in values.items())
    _target(draft, index).update(checked)


def remove_target(draft, index):
    _target(draft, index)
    del draft[index]
