"""The calibration schema: every key a calibration target may carry, its type, range and text form.

One table serves every way a calibration comes in: the calibrate_preset tool's YAML and
calibration_control ``upload`` (target specs), the draft edits (``set_values``, ``set_zero``,
``mark_box``: one key at a time) and preset_calib_info.ini when a preset is loaded. So an upload, an
edit and a file are refused for the same reasons in the same words, each naming the key:

- numbers are finite and of sane size (NaN, Infinity, 1e300 refused; readings within
  +-MAX_ABS_VALUE), angles within +-360 deg, fractions of the box (centre, marks' u, v) in 0..1,
  radius in (0, 1.5] box widths, aspect in [0.05, 20];
- a scale_table has at least 2 [value, angle] entries, values strictly monotonic (angles must
  increase along the sweep: checked with the sweep, see pointer_scale);
- a thermal box's phase is A|B|C|ambient (thermal.diagnosis), its equipment_class one of the
  graded classes, its emissivity in [MIN_EMISSIVITY, 1], its distance in (0, MAX_DISTANCE] m;
- boxes (zoom0 and thermal) are 8 numbers forming a convex TL, TR, BR, BL quad inside their picture;
- text has no control characters (they would break the INI file) and at most MAX_TEXT characters;
  reference patch names are plain file names in the preset directory;
- a key no kind knows (``radus``) is refused as unknown, a key another kind owns as not applying:
  nothing is dropped silently, because preset_calib_info.ini would not keep it;
- a preset has at most MAX_TARGETS targets, and a calibration_control request (an upload's whole
  target list) is at most MAX_REQUEST_BYTES: both refused before any target is looked at (an
  upload's self-check reads every pointer, ~20 ms each; 40,000 targets took 11 minutes).

Pure (no file access, no rospy): callers read the pictures and files. Raises SchemaError.
"""
import math
import numbers
import re

import numpy as np

from inspection_robot.inspection.digital import MAX_CELL_SHIFT, MAX_DIGITS as MAX_DISPLAY_DIGITS, POLARITIES, \
    SPLITS, parse_shown
from inspection_robot.inspection.drum import FONT_NAMES as DRUM_FONTS
from inspection_robot.inspection.gauge import GaugeScale
from inspection_robot.inspection.geometry import quad_inside, quad_is_convex
from inspection_robot.inspection.lamp import LAMP_COLOURS
from inspection_robot.inspection.needle import POINTER_COLOURS
from inspection_robot.thermal.diagnosis import DEFAULT_RULES, MAX_DISTANCE, MIN_EMISSIVITY, PHASE_CHOICES

TARGET_KINDS = ("pointer", "lamp", "switch", "thermal", "digital")
DIGITAL_STYLES = ("segments", "drum")
MAX_ABS_VALUE = 1e9          # a reading (start/end value, scale_table and marks values, normal band)
MAX_ANGLE_DEG = 360.0
MAX_PICTURE_PX = 100000.0    # a thermal box's coordinates when the thermal picture's size is unknown
MAX_TEXT = 200
MAX_DIGITS = 6               # decimal places a reading may be shown with (``digits``)
MAX_TARGETS = 64             # targets per preset: a meter cabinet in one picture has a dozen or two
MAX_REQUEST_BYTES = 1 << 20  # bytes of a calibration_control request: 64 richly described targets take ~150 KB
POINTER_DEFAULTS = {"centre": [0.5, 0.5], "radius": 0.45, "aspect": 1.0, "unit": "", "scale_table": [],
                    "marks": [], "pointer_colour": "", "ignore_colour": ""}
_CONTROL = re.compile(r"[\x00-\x1f\x7f]")
_FILE_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}$")


class SchemaError(ValueError):
    """A calibration key or value outside the schema; the message names the key."""


# --- value checks: (value, key) -> the normalised value ----------------------------------------
def number(value, key, low=-MAX_ABS_VALUE, high=MAX_ABS_VALUE, low_open=False):
    """A finite float in [low, high] (``low_open``: (low, high])."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise SchemaError("%s must be a finite number, got %s" % (key, _short(value)))
    try:
        out = float(value)
    except OverflowError:    # an integer beyond any float
        out = math.inf
    if not math.isfinite(out):
        raise SchemaError("%s must be a finite number, got %s" % (key, _short(value)))
    if out < low or out > high or (low_open and out == low):
        raise SchemaError("%s must be in %s%g, %g], got %r" % (key, "(" if low_open else "[", low, high, out))
    return out


def _list(value, key, what):
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if not isinstance(value, (list, tuple)):
        raise SchemaError("%s must be %s, got %s" % (key, what, _short(value)))
    return value


def _numbers(value, count, key, low=-MAX_ABS_VALUE, high=MAX_ABS_VALUE):
    if isinstance(value, np.ndarray):
        value = value.reshape(-1)
    items = _list(value, key, "a list of %d numbers" % count)
    if len(items) != count:
        raise SchemaError("%s must be a list of %d numbers, got %s" % (key, count, _short(value)))
    return [number(v, key, low, high) for v in items]


def _text(value, key):
    if not isinstance(value, str):
        raise SchemaError("%s must be text, got %s" % (key, _short(value)))
    if len(value) > MAX_TEXT or _CONTROL.search(value):
        raise SchemaError("%s must be at most %d characters without control characters, got %s"
                          % (key, MAX_TEXT, _short(value)))
    return value


def _choice(options, optional=False):
    def check(value, key):
        if (optional and value == "") or value in options:
            return value
        raise SchemaError("%s must be one of %s, got %s" % (key, "|".join(options), _short(value)))
    return check


def _file_name(value, key):
    if not isinstance(value, str) or not _FILE_NAME.match(value):
        raise SchemaError("%s must be a file name in the preset directory (letters, digits, _ . -), got %s"
                          % (key, _short(value)))
    return value


def _picture_path(value, key):
    if not isinstance(value, str) or "\x00" in value:
        raise SchemaError("%s must be a picture path, got %s" % (key, _short(value)))
    return value


def _angle(value, key):
    return number(value, key, -MAX_ANGLE_DEG, MAX_ANGLE_DEG)


def _fractions(value, key):
    return _numbers(value, 2, key, 0.0, 1.0)


def _window(value, key):
    """left, top, right, bottom fractions of a box (a little beyond it allowed), left < right, top < bottom."""
    left, top, right, bottom = _numbers(value, 4, key, -0.5, 1.5)
    if not (left < right and top < bottom):
        raise SchemaError("%s must be [left, top, right, bottom] with left < right and top < bottom, got %s"
                          % (key, _short(value)))
    return [left, top, right, bottom]


def _cell_shifts(value, key):
    """Each digit cell's shift from even spacing, in cells (digit_count of them: checked with it)."""
    items = _list(value, key, "a list of numbers")
    if not 1 <= len(items) <= MAX_DISPLAY_DIGITS:
        raise SchemaError("%s must be a list of 1 to %d numbers, got %s" % (key, MAX_DISPLAY_DIGITS, _short(value)))
    return [number(v, key, -MAX_CELL_SHIFT, MAX_CELL_SHIFT) for v in items]


def _quad(value, key):
    """8 finite numbers, a convex TL, TR, BR, BL quad (inside the picture: checked with its size)."""
    corners = _numbers(value, 8, key, -MAX_PICTURE_PX, MAX_PICTURE_PX)
    if not quad_is_convex(np.reshape(corners, (4, 2))):
        raise SchemaError("%s is not a convex TL,TR,BR,BL quad: %s" % (key, _short(corners)))
    return corners


def _scale_table(value, key):
    """[[value, angle], ...]: empty (a linear scale) or >= 2 entries with strictly monotonic values."""
    what = "a list of [value, angle] pairs"
    entries = [_list(pair, key, what) for pair in _list(value, key, what)]
    table = []
    for pair in entries:
        if len(pair) != 2:
            raise SchemaError("%s entries must be [value, angle], got %s" % (key, _short(pair)))
        table.append([number(pair[0], key + " value"), _angle(pair[1], key + " angle")])
    if len(table) == 1:
        raise SchemaError("%s needs at least 2 entries (or none for a linear scale)" % key)
    values = [v for v, _a in table]
    steps = [b - a for a, b in zip(values, values[1:])]
    if table and not (all(s > 0 for s in steps) or all(s < 0 for s in steps)):
        raise SchemaError("%s values must be strictly monotonic, got %s" % (key, _short(values)))
    return table


def _marks(value, key):
    """[[value, u, v], ...]: the scale marks' positions as fractions of the box."""
    out = []
    for mark in _list(value, key, "a list of [value, u, v] triples"):
        mark = _list(mark, key, "a list of [value, u, v] triples")
        if len(mark) != 3:
            raise SchemaError("%s entries must be [value, u, v] (u, v fractions of the box), got %s"
                              % (key, _short(mark)))
        out.append([number(mark[0], key + " value"), number(mark[1], key + " u", 0.0, 1.0),
                    number(mark[2], key + " v", 0.0, 1.0)])
    return out


def _digits(value, key):
    """Decimal places a reading is shown with: an integer 0..MAX_DIGITS (2.0 from the INI is 2)."""
    out = number(value, key, 0, MAX_DIGITS)
    if out != int(out):
        raise SchemaError("%s must be a whole number of decimal places in [0, %d], got %r" % (key, MAX_DIGITS, out))
    return int(out)


def _whole(value, key, low, high):
    """A whole number in [low, high] (2.0 from the INI is 2)."""
    out = number(value, key, low, high)
    if out != int(out):
        raise SchemaError("%s must be a whole number in [%d, %d], got %r" % (key, low, high, out))
    return int(out)


def _flag(value, key):
    if not isinstance(value, bool):
        raise SchemaError("%s must be true or false, got %s" % (key, _short(value)))
    return value


def _shown(value, key):
    """The text a display shows (inspection.digital.parse_shown's rules)."""
    try:
        parse_shown(value)
    except ValueError as err:
        raise SchemaError("%s: %s" % (key, err))
    return value


def _band(value, key):
    low, high = _numbers(value, 2, key)
    if low > high:
        raise SchemaError("%s must be [low, high], low %g is above high %g" % (key, low, high))
    return [low, high]


def nested_bands_fault(normal, alarm):
    """Why an alarm band [low, high] cannot go with a normal band (it must contain it: a warning lies
    between them), or "" when it can. The one rule for calibrations and task limits (task.spec)."""
    inside = alarm[0] <= normal[0] and alarm[1] >= normal[1]
    return "" if inside else ("alarm band [%g, %g] must contain the normal band [%g, %g] (a warning lies between "
                              "them)" % (alarm[0], alarm[1], normal[0], normal[1]))


def _kind(value, key):
    if value not in TARGET_KINDS:
        raise SchemaError("unknown target kind %s (one of %s)" % (_short(value), "|".join(TARGET_KINDS)))
    return value


# --- text forms in preset_calib_info.ini -----------------------------------------------------
def _num_text(v):
    return "%.12g" % v


def _split(text, sep, count=None):
    parts = [p.strip() for p in text.split(sep)]
    if count is not None and len(parts) != count:
        raise ValueError("expected %d numbers separated by '%s'" % (count, sep))
    return [float(p) for p in parts]


TEXT_FORMS = {
    # name: (to text, from text); an empty text is an absent key (a text key: empty text)
    "text": (lambda v: v, lambda t: t),
    "number": (_num_text, float),
    "flag": (lambda v: "1" if v else "0", lambda t: {"1": True, "0": False}.get(t.strip(), t)),
    "numbers": (lambda v: ",".join(_num_text(x) for x in np.reshape(v, -1)), lambda t: _split(t, ",")),
    "table": (lambda v: ";".join("%s:%s" % (_num_text(a), _num_text(b)) for a, b in v),
              lambda t: [_split(pair, ":", 2) for pair in t.split(";")]),
    "marks": (lambda v: ";".join("%s:%s,%s" % tuple(_num_text(x) for x in m) for m in v),
              lambda t: [[float(m.split(":")[0])] + _split(m.split(":", 1)[1], ",", 2) for m in t.split(";")]),
}


class Field(object):
    """One key: the kinds that take it (None: every kind), its check and its INI text form."""

    def __init__(self, kinds, check, text="text", stored=True):
        self.kinds = kinds
        self.check = check
        self.text = text
        self.stored = stored      # False: only in a target spec (upload / draft), never in the INI


FIELDS = {
    "kind": Field(None, _kind, stored=False),
    "box": Field(None, _quad, "numbers", stored=False),
    "name": Field(None, _text),
    "normal": Field(None, _band, "numbers"),
    "alarm_band": Field(None, _band, "numbers"),   # around normal: between them a warning (task.states)
    "digits": Field(("pointer", "thermal", "digital"), _digits, "number"),
    "start_angle": Field(("pointer",), _angle, "number"),
    "end_angle": Field(("pointer",), _angle, "number"),
    "start_value": Field(("pointer",), number, "number"),
    "end_value": Field(("pointer",), number, "number"),
    "unit": Field(("pointer", "digital"), _text),
    "centre": Field(("pointer",), _fractions, "numbers"),
    "radius": Field(("pointer",), lambda v, k: number(v, k, 0.0, 1.5, low_open=True), "number"),
    "aspect": Field(("pointer",), lambda v, k: number(v, k, 0.05, 20.0), "number"),
    "scale_table": Field(("pointer",), _scale_table, "table"),
    "marks": Field(("pointer",), _marks, "marks"),
    "pointer_colour": Field(("pointer",), _choice(POINTER_COLOURS, optional=True)),
    "ignore_colour": Field(("pointer",), _choice(POINTER_COLOURS, optional=True)),
    "needle_reference": Field(("pointer",), _file_name),   # learned at calibration (inspection.needle_model)
    "colour": Field(("lamp",), _choice(LAMP_COLOURS)),
    "on_reference": Field(("lamp",), _file_name),
    "off_reference": Field(("lamp",), _file_name),
    "on_picture": Field(("lamp",), _picture_path, stored=False),
    "off_picture": Field(("lamp",), _picture_path, stored=False),
    "open_reference": Field(("switch",), _file_name),
    "closed_reference": Field(("switch",), _file_name),
    "open_picture": Field(("switch",), _picture_path, stored=False),
    "closed_picture": Field(("switch",), _picture_path, stored=False),
    "thermal_box": Field(("thermal",), _quad, "numbers"),
    # thermal diagnosis (thermal.diagnosis): the box's phase of its device, or the ambient reference
    "phase": Field(("thermal",), _choice(PHASE_CHOICES, optional=True)),
    "device": Field(("thermal",), _text),
    "equipment_class": Field(("thermal",), _choice(tuple(DEFAULT_RULES), optional=True)),
    "emissivity": Field(("thermal",), lambda v, k: number(v, k, MIN_EMISSIVITY, 1.0), "number"),
    "distance": Field(("thermal",), lambda v, k: number(v, k, 0.0, MAX_DISTANCE, low_open=True), "number"),
    # a seven-segment display (inspection.digital): "shown" (what it shows at calibration) is learned
    # into the rest when the calibration is built
    "shown": Field(("digital",), _shown, stored=False),
    "digit_count": Field(("digital",), lambda v, k: _whole(v, k, 1, MAX_DISPLAY_DIGITS), "number"),
    "polarity": Field(("digital",), _choice(POLARITIES)),
    "slant": Field(("digital",), lambda v, k: number(v, k, -20.0, 20.0), "number"),
    "fill": Field(("digital",), lambda v, k: number(v, k, 0.3, 1.0), "number"),
    "decimals": Field(("digital",), lambda v, k: _whole(v, k, 0, MAX_DISPLAY_DIGITS - 1), "number"),
    "contrast": Field(("digital",), lambda v, k: number(v, k, 0.0, 255.0), "number"),
    "window": Field(("digital",), _window, "numbers"),   # where the cells sit in the box (digital.DisplayModel)
    "cell_shifts": Field(("digital",), _cell_shifts, "numbers"),   # and each one's shift from even spacing
    "split": Field(("digital",), _choice(SPLITS, optional=True)),   # how lit segments are told from dark
    # a counter (discharges of an arrester, breaker operations): its increment since the last patrol is
    # stored, and a count that went down is an alarm (task.patrol)
    "counter": Field(("digital",), _flag, "flag"),
    # a mechanical drum counter (inspection.drum) instead of seven segments: its font and digit height learned
    "style": Field(("digital",), _choice(DIGITAL_STYLES, optional=True)),
    "font": Field(("digital",), _choice(DRUM_FONTS)),
    "glyph": Field(("digital",), lambda v, k: number(v, k, 0.1, 1.0), "number"),
}
REQUIRED = {"pointer": ("start_angle", "end_angle", "start_value", "end_value"), "lamp": ("colour",),
            "switch": ("open_reference", "closed_reference"), "thermal": ("thermal_box",),
            "digital": ("digit_count", "polarity", "slant", "fill", "decimals", "contrast"),
            "drum": ("digit_count", "polarity", "font", "glyph", "decimals", "contrast")}   # a digital style: drum
# a digital model's own keys
STYLE_ONLY = {"segments": ("fill", "slant", "window", "cell_shifts", "split"), "drum": ("font", "glyph")}
PICTURE_STATES = {"lamp": ("on", "off"), "switch": ("open", "closed")}
# written to the INI even when empty or defaulted (the file's long-standing layout)
ALWAYS_WRITTEN = ("centre", "radius", "aspect", "start_angle", "end_angle", "start_value", "end_value", "unit",
                  "scale_table")


def kind_keys(kind, stored=True):
    """The keys a target of ``kind`` takes (``stored``: those preset_calib_info.ini keeps)."""
    return [k for k, f in FIELDS.items() if (f.kinds is None or kind in f.kinds) and (f.stored or not stored)
            and k not in ("kind", "box", "name")]


def check_value(key, value):
    """One key's value, normalised; an unknown key is refused by name."""
    field = FIELDS.get(key)
    if field is None:
        raise SchemaError("unknown key %s (keys: %s)" % (_short(key), ", ".join(sorted(FIELDS))))
    return field.check(value, key)


def _refuse_key(kind, key):
    if key in FIELDS:
        owners = "|".join(FIELDS[key].kinds or TARGET_KINDS)
        return SchemaError("key '%s' does not apply to a %s target (%s only)" % (key, kind, owners))
    return SchemaError("unknown key %s (a %s target takes: %s)"
                       % (_short(key), kind, ", ".join(["box", "kind", "name"] + kind_keys(kind, stored=False))))


def check_params(kind, params, thermal_size=None):
    """The stored parameters of one target (Target's ``params``: no kind, box or name), normalised.

    Every key must belong to ``kind``, the kind's required keys be there, lamp references come in
    pairs, a pointer's scale be consistent (pointer_scale); ``thermal_size`` (w, h): the thermal
    picture the thermal_box must lie in (None: coordinates within 0..MAX_PICTURE_PX). Pointer keys
    left out get POINTER_DEFAULTS.
    """
    kind = _kind(kind, "kind")
    allowed = kind_keys(kind)
    out = {}
    for key, value in params.items():
        if key not in allowed:
            raise _refuse_key(kind, key)
        out[key] = check_value(key, value)
    fault = "" if "alarm_band" not in out else nested_bands_fault(out["normal"], out["alarm_band"]) \
        if "normal" in out else "alarm_band needs a normal band inside it (normal [low, high])"
    if fault:
        raise SchemaError(fault)
    drum = kind == "digital" and out.get("style") == "drum"
    required = REQUIRED["drum" if drum else kind]
    missing = [key for key in required if key not in out]
    if missing:
        raise SchemaError("missing key(s) %s (a %s%s target needs %s)"
                          % (", ".join(missing), kind, " (drum)" if drum else "", ", ".join(required)))
    if kind == "pointer":
        for key, default in POINTER_DEFAULTS.items():
            out.setdefault(key, list(default) if isinstance(default, list) else default)
        pointer_scale(out)
    elif kind == "lamp" and ("on_reference" in out) != ("off_reference" in out):
        raise SchemaError("a lamp needs both on_reference and off_reference (or on_picture and off_picture), "
                          "or neither")
    elif kind == "digital":
        if out["decimals"] >= out["digit_count"]:
            raise SchemaError("decimals %d must be fewer than digit_count %d" % (out["decimals"], out["digit_count"]))
        if "cell_shifts" in out and len(out["cell_shifts"]) != out["digit_count"]:
            raise SchemaError("cell_shifts has %d numbers for %d digits"
                              % (len(out["cell_shifts"]), out["digit_count"]))
        other = [k for k in STYLE_ONLY["segments" if drum else "drum"] if k in out]
        if other:
            raise SchemaError("%s does not apply to a %s display"
                              % (", ".join(sorted(other)), "drum" if drum else "seven-segment"))
    elif kind == "thermal":
        if out.get("device") and not out.get("phase"):
            raise SchemaError("device '%s' needs a phase (%s)" % (out["device"], "|".join(PHASE_CHOICES)))
        corners = np.reshape(out["thermal_box"], (4, 2))
        width, height = thermal_size or (MAX_PICTURE_PX + 1, MAX_PICTURE_PX + 1)
        if not quad_inside(corners, width, height):
            raise SchemaError("thermal_box lies outside the %s thermal picture: %s"
                              % ("%dx%d" % tuple(thermal_size) if thermal_size else "0..%g px" % MAX_PICTURE_PX,
                                 _short(out["thermal_box"])))
    return out


def pointer_scale(params):
    """The GaugeScale of checked pointer parameters; SchemaError when the ends or the table disagree."""
    try:
        return GaugeScale(params["start_angle"], params["end_angle"], params["start_value"], params["end_value"],
                          params.get("scale_table") or None)
    except ValueError as err:
        raise SchemaError("pointer scale: %s" % err)


def check_spec(spec, index, width, height, thermal_size=None):
    """One target spec of an upload or a draft (kind, box, name, the kind's keys, <state>_picture).

    Returns (kind, box 4x2 array in zoom0, name, params, pictures): ``pictures`` {state: path} are
    the reference pictures still to be cut into patches; their patch names
    ``target_<index>_<state>.png`` are already in ``params`` as <state>_reference. ``width`` x
    ``height``: zoom0.jpg, which the box must lie in.
    """
    if not isinstance(spec, dict):
        raise SchemaError("expected an object with kind, box and the kind's keys, got %s" % _short(spec))
    spec = dict(spec)
    for key in ("kind", "box"):
        if key not in spec:
            raise SchemaError("missing key '%s'" % key)
    kind = check_value("kind", spec.pop("kind"))
    box = np.reshape(check_value("box", spec.pop("box")), (4, 2))
    if not quad_inside(box, width, height):
        raise SchemaError("box lies outside the %dx%d picture" % (width, height))
    name = check_value("name", spec.pop("name", ""))
    pictures = {}
    for state in PICTURE_STATES.get(kind, ()):
        picture = spec.pop(state + "_picture", "")
        if picture == "":
            continue
        picture = check_value(state + "_picture", picture)
        if state + "_reference" in spec:
            raise SchemaError("give %s_picture or %s_reference, not both" % (state, state))
        pictures[state] = picture
        spec[state + "_reference"] = "target_%d_%s.png" % (index, state)
    return kind, box, name, check_params(kind, spec, thermal_size), pictures


# --- INI text --------------------------------------------------------------------------------------
def to_text(key, value):
    return TEXT_FORMS[FIELDS[key].text][0](value)


def from_text(key, text):
    """A key's value read from preset_calib_info.ini, checked; None for an empty non-text value."""
    field = FIELDS.get(key)
    if field is None or not field.stored:
        raise SchemaError("unknown key %s" % _short(key))
    if field.text != "text" and not text.strip():
        return None
    try:
        value = TEXT_FORMS[field.text][1](text)
    except (ValueError, IndexError) as err:
        raise SchemaError("%s: cannot read '%s' (%s)" % (key, text, err))
    return check_value(key, value)


def params_to_section(params):
    """{key: text} of stored parameters for a [target_<i>] section: keys with a value, in FIELDS order."""
    out = {}
    for key in FIELDS:
        value = params.get(key)
        empty = value is None or (isinstance(value, (str, list, tuple)) and not value)
        if key in params and FIELDS[key].stored and (key in ALWAYS_WRITTEN or not empty):
            out[key] = to_text(key, value)
    return out


def _short(value, limit=60):
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."
