"""calibration_control: the calibration tool's operations as commands, so a backend or the console
can calibrate a recorded preset without a shell on the robot.

Every command takes a JSON object whose ``preset`` names a preset directory (relative to the data
root, e.g. ``presets/p1/20260101_120000``; the older form relative to the first preset root,
``p1/20260101_120000``, is accepted too; or absolute) inside the preset roots. The operations
edit a draft (``calibration_draft.json`` in the preset directory) one target at a time, exactly
as the command-line tool does (inspection.calibration); ``apply`` validates the whole draft against the
calibration schema (inspection.calibration_schema) and writes ``preset_calib_info.ini`` +
``zoom<k>.xml`` + reference patches; ``upload`` does the same with a complete target list in one
request (and makes it the draft). A bad draft or upload fails with the reason and writes nothing;
the files of a good one replace the old calibration in one rename (dir_update.DirUpdate), so an I/O
failure leaves the old one whole. Pictures a target names (switch/lamp references) must lie inside
the readable roots; a reference file named in the preset directory must decode as the reader
decodes it. A request larger than calibration_schema.MAX_REQUEST_BYTES, or more than MAX_TARGETS
targets, is refused before anything else is looked at, and a hidden preset folder (one being
recorded or calibrated) is refused.
"""
import json
import os
import threading

import numpy as np

from inspection_robot.command import CommandError, CommandTable, parse_json
from inspection_robot.data_layout import under
from inspection_robot.files import FileError, confine_data_path, confine_path, read_json, refuse_hidden, \
    root_relative, write_json_atomic
from inspection_robot.inspection import calibration
from inspection_robot.inspection import calibration_schema as schema
from inspection_robot.inspection.preset import PresetError, load_info, load_preset


def _plain(value):
    """JSON-safe copy of target parameters (numpy arrays, tuples)."""
    if isinstance(value, np.ndarray):
        return [float(v) for v in value.reshape(-1)]
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return dict((k, _plain(v)) for k, v in value.items())
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    return value


SELF_CHECK_FIELDS = ("expected", "force")   # optional fields of apply and upload (calibration.SelfCheck)


class CalibrationCommands(object):
    """``data_root``: the robot's data root; ``preset_roots``: where presets may be calibrated;
    ``picture_roots``: where reference pictures may be read; ``optics``: camera.optics.ZoomOptics."""

    def __init__(self, data_root, preset_roots, picture_roots, optics):
        self.data_root = os.path.realpath(os.path.expanduser(data_root))
        self.preset_roots = [under(self.data_root, r) for r in preset_roots]
        self.picture_roots = [under(self.data_root, r) for r in picture_roots]
        # errors name the roots as a client does (relative to the data root), never resolved
        self.preset_root_names = [self._name(r) for r in self.preset_roots]
        self.picture_root_names = [self._name(r) for r in self.picture_roots]
        self.optics = optics
        # one command at a time: an apply replaces the preset directory, and an edit saved into
        # the old one meanwhile would be lost (the service and its topic twin run on two threads)
        self._lock = threading.Lock()
        locked = self._locked
        self.table = CommandTable(dict((name, locked(handler)) for name, handler in {
            "get": self.get,
            "mark_box": self._edit(("box",), lambda d, i, f: calibration.mark_box(d, i, f["box"])),
            "set_meter_type": self._edit(("kind",), lambda d, i, f: {
                "dropped": calibration.set_meter_type(d, i, f["kind"])}),
            "set_zero": self._edit(("angle", "value"),
                                   lambda d, i, f: calibration.set_zero(d, i, f["angle"], f["value"])),
            "set_full_scale": self._edit(("angle", "value"),
                                         lambda d, i, f: calibration.set_full_scale(d, i, f["angle"], f["value"])),
            "set_values": self._edit(("values",), lambda d, i, f: calibration.set_values(d, i, f["values"])),
            "remove_target": self._edit((), calibration.remove_target),
            "clear_draft": self.clear_draft,
            "apply": self.apply,
            "upload": self.upload,
        }.items()))

    def _locked(self, handler):
        def run(data):
            with self._lock:
                return handler(data)
        return run

    # --- helpers ---------------------------------------------------------------------------------
    def _fields(self, data, allowed, optional=()):
        size = len(data.encode("utf-8", "surrogatepass")) if isinstance(data, str) else 0
        if size > schema.MAX_REQUEST_BYTES:   # before any parsing: the size alone refuses it
            raise CommandError("request of %d bytes refused, at most %d (a preset has at most %d targets)"
                               % (size, schema.MAX_REQUEST_BYTES, schema.MAX_TARGETS))
        fields = parse_json(data)
        if not isinstance(fields, dict):
            raise CommandError('data must be a JSON object, e.g. {"preset": "presets/p1/20260101_120000"}')
        known = set(allowed) | set(optional) | {"preset"}
        unknown = sorted(set(fields) - known)
        if unknown:
            raise CommandError("unknown field(s) %s (allowed: %s)" % (", ".join(unknown), ", ".join(sorted(known))))
        missing = [name for name in ("preset",) + tuple(allowed) if name not in fields]
        if missing:
            raise CommandError("missing field(s) %s" % ", ".join(missing))
        preset = fields["preset"]
        if not isinstance(preset, str) or not preset:
            raise CommandError("preset must be the preset directory, e.g. presets/p1/20260101_120000")
        path = confine_data_path(preset, self.preset_roots, self.data_root, root_names=self.preset_root_names)
        # a hidden folder is an in-progress one (a recording's .tmp_*, a calibration's .<stamp>.update.*)
        refuse_hidden(preset, path, [os.path.realpath(r) for r in self.preset_roots])
        try:
            load_info(path)
        except PresetError as err:
            raise CommandError(str(err))
        return path, fields

    def _draft(self, path):
        draft = read_json(os.path.join(path, calibration.DRAFT_FILE))
        if draft is None:
            return []
        if not isinstance(draft, list) or not all(isinstance(t, dict) for t in draft):
            raise FileError("corrupt %s in %s: expected a list of targets" % (calibration.DRAFT_FILE, path))
        return draft

    def _save_draft(self, path, draft):
        write_json_atomic(os.path.join(path, calibration.DRAFT_FILE), draft)

    def _edit(self, names, operation):
        """A command applying ``operation(draft, target, fields)`` to the stored draft."""
        def handler(data):
            path, fields = self._fields(data, ("target",) + tuple(names))
            draft = self._draft(path)
            try:
                if names:
                    extra = operation(draft, fields["target"], fields)
                else:
                    extra = operation(draft, fields["target"])
            except PresetError as err:
                raise CommandError(str(err))
            self._save_draft(path, draft)
            answer = {"preset": self._name(path), "draft": draft}
            answer.update(extra if isinstance(extra, dict) else {})
            return json.dumps(answer, sort_keys=True)
        return handler

    def _name(self, path):
        return root_relative(path, self.data_root)

    def _confined_specs(self, specs):
        if not isinstance(specs, list):
            raise CommandError("targets must be a list of target objects")
        if len(specs) > schema.MAX_TARGETS:   # before any target is looked at
            raise CommandError("calibration refused, nothing written: %d targets given, at most %d per preset"
                               % (len(specs), schema.MAX_TARGETS))
        out = []
        for i, spec in enumerate(specs):
            if not isinstance(spec, dict):
                raise CommandError("target %d: expected an object with kind, box and parameters" % i)
            spec = dict(spec)
            for name in calibration.PICTURE_FIELDS:
                if spec.get(name):
                    if not isinstance(spec[name], str):
                        raise CommandError("target %d: %s must be a path" % (i, name))
                    spec[name] = confine_path(spec[name], self.picture_roots, base=self.data_root,
                                              root_names=self.picture_root_names)
            out.append(spec)
        return out

    def _calibrate(self, path, specs, fields, draft=None):
        check = self._self_check(fields)
        try:
            targets = calibration.calibrate(path, self._confined_specs(specs), self.optics, draft, check)
        except PresetError as err:
            raise CommandError("calibration refused, nothing written: %s" % err)
        except FileError as err:
            raise CommandError("calibration not written, the preset is unchanged: %s" % err)
        return json.dumps({"preset": self._name(path), "targets": len(targets),
                           "kinds": [t.kind for t in targets], "self_check": check.results}, sort_keys=True)

    @staticmethod
    def _self_check(fields):
        expected, force = fields.get("expected"), fields.get("force", False)
        if expected is not None and not (isinstance(expected, list) and all(
                v is None or isinstance(v, (int, float)) and not isinstance(v, bool) for v in expected)):
            raise CommandError("expected must be a list with one number (or null) per target, in calibration order")
        if not isinstance(force, bool):
            raise CommandError("force must be true or false")
        return calibration.SelfCheck(expected, force)

    # --- commands --------------------------------------------------------------------------------
    def get(self, data):
        """{"preset"} -> {"preset", "info", "calibrated", "targets", "draft"}."""
        path, _fields = self._fields(data, ())
        try:
            preset = load_preset(path, need_calibration=False)
        except PresetError as err:
            raise CommandError(str(err))
        info = preset.info
        targets = [dict(_plain(t.params), kind=t.kind, name=t.name, box=_plain(t.boxes[0]))
                   for t in preset.targets]
        for target in targets:
            target.pop("scale", None)
        return json.dumps({
            "preset": self._name(path), "calibrated": bool(targets), "targets": targets,
            "draft": self._draft(path),
            "info": {"preset_id": info.preset_id, "type": info.preset_type, "infrared": info.infrared,
                     "created": info.created, "pan_deg": info.pan_deg, "tilt_deg": info.tilt_deg,
                     "zoom": info.zoom, "focus_position": info.focus_position, "pose": list(info.pose),
                     "zoom_levels": info.zoom_levels, "width": info.width, "height": info.height,
                     "extra_data": info.extra_data}}, sort_keys=True)

    def clear_draft(self, data):
        path, _fields = self._fields(data, ())
        self._save_draft(path, [])
        return json.dumps({"preset": self._name(path), "draft": []})

    def apply(self, data):
        """{"preset", "expected"?, "force"?}: calibrate the preset from its draft (SelfCheck)."""
        path, fields = self._fields(data, (), SELF_CHECK_FIELDS)
        return self._calibrate(path, self._draft(path), fields)

    def upload(self, data):
        """{"preset", "targets": [spec, ...], "expected"?, "force"?}: calibrate from a complete target
        list (the tool's YAML as JSON); on success the list also becomes the draft."""
        path, fields = self._fields(data, ("targets",), SELF_CHECK_FIELDS)
        return self._calibrate(path, fields["targets"], fields, draft=fields["targets"])
