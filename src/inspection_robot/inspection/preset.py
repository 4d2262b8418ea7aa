"""The preset directory: preset.ini, preset_calib_info.ini, zoomX.xml; atomic writes; loading.

Layout of ``<preset_root>/<preset_id>/<YYYYMMDD_HHMMSS>/`` (documented in docs/interface.md):

- ``preset.ini``  written by preset_scale: sections [preset] [ptz] [camera] [pose] [pictures]
  and, when present, [thermal] and [arm].
- ``zoom0.jpg`` (final zoom) .. ``zoomN.jpg`` (stepping out towards wide), ``thermal.jpg`` and
  the radiometric frame, the arm trajectory file.
- ``preset_calib_info.ini`` written by the calibration tool: [calibration] and one
  [target_<i>] section per target box.
- ``zoom<k>.xml`` written by the calibration tool: every target's box (TL, TR, BR, BL) in
  ``zoom<k>.jpg``.

A new preset directory is filled under a hidden temporary name and renamed at the end (the parent
folder fsynced), so a failure or a power cut never leaves half a preset; a calibration is written
into a copy of the directory that replaces it in one rename (calibration.calibrate,
dir_update.DirUpdate), so it is whole or absent too. Only preset_scale (recording) and the calibration
tool write here; the camera and the imager write into their own capture roots, never into a preset.
"""
import configparser
import io
import os
import shutil
import tempfile
import xml.etree.ElementTree as ET

import numpy as np

from inspection_robot.files import fsync_dir, rename_durable, shown, write_atomic
from inspection_robot.inspection import calibration_schema as schema
from inspection_robot.inspection.calibration_schema import TARGET_KINDS

PRESET_INI = "preset.ini"
CALIB_INI = "preset_calib_info.ini"
CALIB_VERSION = 1


class PresetError(Exception):
    """A missing or corrupt preset or calibration; the message is the reason."""


MAX_PRESET_ID_CHARS = 128


def check_preset_id(preset_id):
    """PresetError unless ``preset_id`` can name the preset's folder: not empty, at most
    MAX_PRESET_ID_CHARS, no ``/``, no leading ``.`` (``.``, ``..`` and hidden in-progress folders), no
    control or unprintable character (a newline would also break preset.ini)."""
    if (not isinstance(preset_id, str) or not preset_id or "/" in preset_id or preset_id.startswith(".")
            or len(preset_id) > MAX_PRESET_ID_CHARS or not preset_id.isprintable()):
        raise PresetError("invalid preset_id '%s' (1-%d printable characters, no '/', not starting with '.')"
                          % (shown(preset_id), MAX_PRESET_ID_CHARS))


def zoom_picture_name(index):
    return "zoom%d.jpg" % index


def zoom_xml_name(index):
    return "zoom%d.xml" % index


def _ini_text(config):
    buf = io.StringIO()
    config.write(buf)
    return buf.getvalue()


class PresetDirWriter(object):
    """Fills ``<root>/<preset_id>/<stamp>/`` under a temporary name; commit() renames it.

    Use as a context manager: leaving the block with an exception removes the temporary directory.
    """

    def __init__(self, root, preset_id, stamp):
        check_preset_id(preset_id)
        self.parent = os.path.join(root, preset_id)
        self.final = os.path.join(self.parent, stamp)
        if os.path.exists(self.final):
            raise PresetError("preset directory already exists: %s" % self.final)
        os.makedirs(self.parent, exist_ok=True)
        self.path = tempfile.mkdtemp(prefix=".tmp_%s_" % stamp, dir=self.parent)

    def file(self, name):
        return os.path.join(self.path, name)

    def commit(self):
        """Rename the filled directory to its final name, durably: its names fsynced first, then
        the rename (rename_durable fsyncs the parent)."""
        fsync_dir(self.path)
        rename_durable(self.path, self.final)
        self.path = self.final
        return self.final

    def abort(self):
        if self.path != self.final and os.path.isdir(self.path):
            shutil.rmtree(self.path, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is not None:
            self.abort()
        return False


# --- preset.ini -------------------------------------------------------------------------------
class PresetInfo(object):
    """Contents of preset.ini."""

    def __init__(self, preset_id, preset_type, infrared, created, pan_deg, tilt_deg, zoom, focus_position,
                 pose, zoom_levels, width=0, height=0, extra_data="", thermal_picture="", thermal_frame="",
                 arm_trajectory=""):
        self.preset_id = preset_id
        self.preset_type = preset_type
        self.infrared = bool(infrared)
        self.created = created
        self.pan_deg = float(pan_deg)
        self.tilt_deg = float(tilt_deg)
        self.zoom = float(zoom)
        self.focus_position = int(focus_position)
        self.pose = tuple(float(v) for v in pose)       # x m, y m, yaw rad (map)
        self.zoom_levels = [float(z) for z in zoom_levels]  # zoom of zoom0.jpg, zoom1.jpg, ...
        self.width = int(width)
        self.height = int(height)
        self.extra_data = extra_data
        self.thermal_picture = thermal_picture
        self.thermal_frame = thermal_frame
        self.arm_trajectory = arm_trajectory

    def to_ini(self):
        c = configparser.ConfigParser(interpolation=None)
        c["preset"] = {"preset_id": self.preset_id, "type": self.preset_type,
                       "infrared": "1" if self.infrared else "0", "created": self.created,
                       "extra_data": self.extra_data}
        c["ptz"] = {"pan_deg": "%.2f" % self.pan_deg, "tilt_deg": "%.2f" % self.tilt_deg}
        c["camera"] = {"zoom": repr(self.zoom), "focus_position": str(self.focus_position),
                       "width": str(self.width), "height": str(self.height)}
        c["pose"] = {"x": "%.4f" % self.pose[0], "y": "%.4f" % self.pose[1], "yaw": "%.5f" % self.pose[2]}
        pictures = {"count": str(len(self.zoom_levels))}
        for i, level in enumerate(self.zoom_levels):
            pictures["zoom%d" % i] = zoom_picture_name(i)
            pictures["zoom%d_level" % i] = repr(level)
        c["pictures"] = pictures
        if self.infrared:
            c["thermal"] = {"picture": self.thermal_picture, "frame": self.thermal_frame}
        if self.arm_trajectory:
            c["arm"] = {"trajectory": self.arm_trajectory}
        return _ini_text(c)

    @classmethod
    def from_ini(cls, text):
        c = configparser.ConfigParser(interpolation=None)
        try:
            c.read_string(text)
            count = c.getint("pictures", "count")
            if count < 1:
                raise ValueError("no pictures")
            levels = [c.getfloat("pictures", "zoom%d_level" % i) for i in range(count)]
            return cls(
                preset_id=c.get("preset", "preset_id"), preset_type=c.get("preset", "type"),
                infrared=c.getint("preset", "infrared"), created=c.get("preset", "created"),
                pan_deg=c.getfloat("ptz", "pan_deg"), tilt_deg=c.getfloat("ptz", "tilt_deg"),
                zoom=c.getfloat("camera", "zoom"), focus_position=c.getint("camera", "focus_position"),
                width=c.getint("camera", "width", fallback=0), height=c.getint("camera", "height", fallback=0),
                pose=(c.getfloat("pose", "x"), c.getfloat("pose", "y"), c.getfloat("pose", "yaw")),
                zoom_levels=levels, extra_data=c.get("preset", "extra_data", fallback=""),
                thermal_picture=c.get("thermal", "picture", fallback=""),
                thermal_frame=c.get("thermal", "frame", fallback=""),
                arm_trajectory=c.get("arm", "trajectory", fallback=""))
        except (configparser.Error, ValueError) as err:
            raise PresetError("corrupt %s: %s" % (PRESET_INI, err))


# --- calibration ------------------------------------------------------------------------------
class Target(object):
    """One calibrated target box: its kind, its parameters and its box in each zoom picture.

    ``boxes``: {zoom index: 4x2 array TL, TR, BR, BL}. ``params``: the kind's keys, checked and
    normalised by inspection.calibration_schema (the one schema of uploads, draft edits and this
    file), which lists them with their ranges. Pointer: centre (pivot as fractions of the box),
    radius (dial radius as a fraction of the box width), aspect (physical width / height of the
    box), start/end angle (deg clockwise from up) and value, unit, scale_table [(value, angle)],
    marks [(value, u, v)] (the scale marks' positions as fractions of the box: the reader fits
    their ellipse to undo an oblique view and find the pivot, see dial_frame.dial_from_marks),
    pointer_colour, ignore_colour, needle_reference (the needle model's file, learned at
    calibration: inspection.needle_model). Lamp: colour, optional on_reference and off_reference (patch
    file names). Switch: open_reference, closed_reference (patch file names in the preset
    directory). Thermal: thermal_box (4x2 in the thermal picture). Any kind: normal [low, high].
    """

    def __init__(self, kind, boxes, name="", thermal_size=None, **params):
        try:
            self.name = schema.check_value("name", name)
            self.params = schema.check_params(kind, params, thermal_size)
        except schema.SchemaError as err:
            raise PresetError("%s: %s" % (kind, err) if kind in TARGET_KINDS else str(err))
        self.kind = kind
        self.boxes = dict((int(k), np.asarray(v, np.float64).reshape(4, 2)) for k, v in boxes.items())
        for k, box in self.boxes.items():
            if not np.all(np.isfinite(box)):
                raise PresetError("the box in %s must be finite numbers" % zoom_xml_name(k))
        self.scale = schema.pointer_scale(self.params) if kind == "pointer" else None
        if kind == "thermal":
            self.params["thermal_box"] = np.asarray(self.params["thermal_box"], np.float64).reshape(4, 2)

    def section(self):
        out = {"kind": self.kind, "name": self.name}
        out.update(schema.params_to_section(self.params))
        return out

    @classmethod
    def from_section(cls, section, boxes):
        """The target of a [target_<i>] section; every key is read through the schema, so a key
        the schema does not know (a typo such as ``radus``) is refused by name."""
        params = {}
        try:
            for key, text in section.items():
                if key not in ("kind", "name"):
                    value = schema.from_text(key, text)
                    if value is not None:
                        params[key] = value
        except schema.SchemaError as err:
            raise PresetError(str(err))
        return cls(section.get("kind", ""), boxes, name=section.get("name", ""), **params)


def boxes_to_xml(zoom_index, level, width, height, targets):
    root = ET.Element("zoom", {"index": str(zoom_index), "level": repr(float(level)), "width": str(width),
                               "height": str(height), "picture": zoom_picture_name(zoom_index)})
    for i, target in enumerate(targets):
        if zoom_index not in target.boxes:
            continue
        elem = ET.SubElement(root, "target", {"index": str(i), "kind": target.kind})
        for corner, (x, y) in zip(("TL", "TR", "BR", "BL"), target.boxes[zoom_index]):
            ET.SubElement(elem, "point", {"corner": corner, "x": "%.2f" % x, "y": "%.2f" % y})
    return ET.tostring(root, encoding="unicode") + "\n"


def boxes_from_xml(text):
    """{target index: 4x2 array} from a zoomX.xml document."""
    root = ET.fromstring(text)
    out = {}
    for elem in root.findall("target"):
        points = elem.findall("point")
        if len(points) != 4:
            raise ValueError("target %s needs 4 points" % elem.get("index"))
        out[int(elem.get("index"))] = np.array([[float(p.get("x")), float(p.get("y"))] for p in points])
    return out


def write_calibration(preset_dir, targets, info):
    """Write preset_calib_info.ini and zoom<k>.xml for every zoom picture of the preset into
    ``preset_dir`` (calibration.calibrate passes the staged copy that then replaces the preset)."""
    c = configparser.ConfigParser(interpolation=None)
    c["calibration"] = {"version": str(CALIB_VERSION), "reference": zoom_picture_name(0),
                        "target_count": str(len(targets))}
    for i, target in enumerate(targets):
        c["target_%d" % i] = target.section()
    for k, level in enumerate(info.zoom_levels):
        write_atomic(os.path.join(preset_dir, zoom_xml_name(k)),
                     boxes_to_xml(k, level, info.width, info.height, targets))
    write_atomic(os.path.join(preset_dir, CALIB_INI), _ini_text(c))


# files a calibration names: reference patches, and a pointer's needle model (inspection.needle_model)
REFERENCE_KEYS = ("on_reference", "off_reference", "open_reference", "closed_reference", "needle_reference")
# loads of a preset an upload may overtake in a row before load_preset gives up: uploads back to back
# (test_calibration_commands' upload storm) overtook a load 5 times in a row once in 5,479 loads beside
# the suites under Noetic's Python; 20 in a row needs an upload faster than every load 20 times
SNAPSHOT_TRIES = 20


class Preset(object):
    """A loaded preset directory: its info, its calibrated targets and file paths. ``references``:
    {file name: bytes} of the reference patches the targets name, read with the calibration (one
    snapshot, see load_preset); ``reference(name)`` answers them."""

    def __init__(self, path, info, targets, references=None):
        self.path = path
        self.info = info
        self.targets = targets
        self.references = dict(references or {})

    @property
    def preset_id(self):
        return self.info.preset_id

    def picture(self, zoom_index):
        return os.path.join(self.path, zoom_picture_name(zoom_index))

    def file(self, name):
        return os.path.join(self.path, name)

    def reference(self, name):
        """The bytes of reference patch ``name`` as loaded with the calibration, None when missing."""
        return self.references.get(name)


def load_info(path):
    ini = os.path.join(path, PRESET_INI)
    if not os.path.isdir(path):
        raise PresetError("preset directory not found: %s" % path)
    if not os.path.isfile(ini):
        raise PresetError("%s missing in %s" % (PRESET_INI, path))
    with open(ini) as f:
        return PresetInfo.from_ini(f.read())


def load_preset(path, need_calibration=True):
    """Load a preset directory; raises PresetError with a reason when anything is missing or corrupt.

    One snapshot: the directory is opened once and every file (preset.ini, preset_calib_info.ini,
    zoom<k>.xml, the reference patches) read relative to that descriptor, so a calibration swapped
    in meanwhile (dir_update.DirUpdate replaces the whole directory) is never mixed with the old one.
    When the path no longer names the directory read once the reading is done (an upload
    overtook it: the old content may be removed while it is read), the load starts again, up to
    SNAPSHOT_TRIES times.
    """
    for _attempt in range(SNAPSHOT_TRIES):
        try:
            dir_fd = os.open(path, os.O_RDONLY | os.O_DIRECTORY)
        except OSError:
            raise PresetError("preset directory not found: %s" % path)
        try:
            try:
                return_value, failure = _load_at(dir_fd, path, need_calibration), None
            except PresetError as err:
                return_value, failure = None, err
            if _names(path, dir_fd):
                if failure is not None:
                    raise failure
                return return_value
        finally:
            os.close(dir_fd)
    raise PresetError("preset %s was replaced %d times while it was read (calibrations uploaded meanwhile); "
                      "try again" % (path, SNAPSHOT_TRIES))


def _names(path, dir_fd):
    """Whether ``path`` still names the directory open as ``dir_fd``."""
    try:
        now, opened = os.stat(path), os.fstat(dir_fd)
    except OSError:
        return False
    return (now.st_dev, now.st_ino) == (opened.st_dev, opened.st_ino)


def _read_at(dir_fd, name, binary=False):
    """The content of ``name`` in the directory open as ``dir_fd``, None when it is missing."""
    try:
        fd = os.open(name, os.O_RDONLY, dir_fd=dir_fd)
    except FileNotFoundError:
        return None
    except OSError as err:
        raise PresetError("cannot read %s: %s" % (name, err.strerror or err))
    with os.fdopen(fd, "rb") as f:
        data = f.read()
    if binary:
        return data
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise PresetError("%s is not UTF-8 text: %s" % (name, err))


def _load_at(dir_fd, path, need_calibration):
    text = _read_at(dir_fd, PRESET_INI)
    if text is None:
        raise PresetError("%s missing in %s" % (PRESET_INI, path))
    info = PresetInfo.from_ini(text)
    targets = []
    calib = _read_at(dir_fd, CALIB_INI)
    if calib is None:
        if need_calibration:
            raise PresetError("preset not calibrated: %s missing in %s" % (CALIB_INI, path))
        return Preset(path, info, targets)
    c = configparser.ConfigParser(interpolation=None)
    try:
        c.read_string(calib)
        count = c.getint("calibration", "target_count")
        if not 0 <= count <= schema.MAX_TARGETS:
            raise ValueError("target_count %d (at most %d)" % (count, schema.MAX_TARGETS))
        boxes = {}
        for k in range(len(info.zoom_levels)):
            xml = _read_at(dir_fd, zoom_xml_name(k))
            if xml is not None:
                boxes[k] = boxes_from_xml(xml)
        if 0 not in boxes:
            raise ValueError("%s missing" % zoom_xml_name(0))
        for i in range(count):
            target_boxes = dict((k, b[i]) for k, b in boxes.items() if i in b)
            if 0 not in target_boxes:
                raise ValueError("target %d has no box in %s" % (i, zoom_xml_name(0)))
            try:
                targets.append(Target.from_section(c["target_%d" % i], target_boxes))
            except PresetError as err:
                raise PresetError("[target_%d] %s" % (i, err))
    except PresetError as err:
        raise PresetError("corrupt calibration in %s: %s" % (path, err))
    except (configparser.Error, ValueError, KeyError, ET.ParseError, TypeError) as err:
        raise PresetError("corrupt calibration in %s: %s" % (path, err))
    if not targets:
        raise PresetError("calibration of %s has no target" % path)
    references = {}
    for target in targets:
        for key in REFERENCE_KEYS:
            name = target.params.get(key)
            if name and name not in references:
                data = _read_at(dir_fd, name, binary=True)
                if data is not None:
                    references[name] = data
    return Preset(path, info, targets, references)
