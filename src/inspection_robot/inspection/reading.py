"""read_scale's work without ROS: validate a request, read every box, detect foreign objects,
write annotated pictures.

Request rules (docs/interface.md, Inspection): ``roi_vertex`` has 8 numbers per calibrated target
(calibration order); ``filename`` has one entry per target, or one entry for all targets when
none is thermal, or two entries [visible picture, thermal frame] when some are, optionally
followed by the same form again: the second look, in which every pointer is read again
(inspection.looks);
``roi_vertex_thermal`` has 8 numbers per thermal target. ``foreign_filename`` lists pictures to
search for foreign objects (foreign_detect 1 or 2), one result per picture.
"""
import os
import re
from collections import namedtuple

import numpy as np

from inspection_robot.lazy import lazy_import
from inspection_robot.files import PUBLIC_FILE_MODE, FileError, confine_path, write_atomic
from inspection_robot.command import CommandError
from inspection_robot.inspection.digital import display_model, read_display
from inspection_robot.inspection.drum import drum_model, own_digits, read_drum
from inspection_robot.inspection.foreign import detect_foreign
from inspection_robot.inspection.geometry import quad_inside, quad_is_convex, quad_overlap, quads_from_flat, \
    rectify, transform_quad
from inspection_robot.inspection.locate import LocateError, Locator
from inspection_robot.inspection.looks import combine_looks
from inspection_robot.inspection.preset import PresetError, load_preset, zoom_picture_name
from inspection_robot.inspection.lamp import read_lamp
from inspection_robot.inspection.needle import MIN_FOCUS_RATIO, check_face, focus_ratio
from inspection_robot.inspection.needle_model import NeedleModel
from inspection_robot.inspection.pointer import PointerReader
from inspection_robot.inspection.readers import Reading, ReadFailed
from inspection_robot.inspection.switch import face_similarity, read_switch
from inspection_robot.inspection.thermal_max import read_thermal_max
from inspection_robot.interface import FOREIGN_DETECT_BOTH, FOREIGN_DETECT_FOREIGN, FOREIGN_DETECT_READ

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load

ReadOutcome = namedtuple("ReadOutcome", "scale possibility picture_path foreign_scale foreign_possibility "
                                        "foreign_picture_path uncertain")

RESULT_UNCERTAIN = "uncertain"
MIN_FACE_SIMILARITY = 0.2   # below: the box does not show the calibrated gauge


def _calibration_picture(preset, target):
    """The picture ``target`` was calibrated on (the preset's zoom0.jpg, where its box was drawn), None
    when it has no box there or the picture is gone."""
    return cv2.imread(preset.picture(0), cv2.IMREAD_COLOR) if 0 in target.boxes else None


def result_text(outcome, success):
    """ReadScaleAck.result for a served request: ``success``, or ``uncertain: box <i>: <why>; ...``
    when a reading's confidence is under the reader's threshold."""
    reasons = ["box %d: %s" % (i, why) for i, why in enumerate(outcome.uncertain) if why]
    return "%s: %s" % (RESULT_UNCERTAIN, "; ".join(reasons)) if reasons else success


def uncertain_reasons(result, count, success):
    """The reverse of result_text for ``count`` boxes: per box "" or the reason its reading is
    uncertain. ValueError for a result that is neither ``success`` nor result_text's uncertain form."""
    reasons = [""] * count
    if result == success:
        return reasons
    prefix = RESULT_UNCERTAIN + ": "
    parts = re.split(r"(?:^|; )box (\d+): ", result[len(prefix):]) if result.startswith(prefix) else [result]
    if len(parts) < 3 or parts[0]:
        raise ValueError("unexpected read_scale result '%s'" % result[:200])
    for index, why in zip(parts[1::2], parts[2::2]):
        if int(index) >= count or not why:
            raise ValueError("read_scale result names box %s of %d: '%s'" % (index, count, result[:200]))
        reasons[int(index)] = why
    return reasons


def request_filenames(kinds, picture, thermal_frame="", second_look=""):
    """ReadScaleCmd.filename for a find result of a preset whose targets are of ``kinds``: one entry
    per target (a thermal target's the thermal frame), followed by one per target again with the
    second look's picture when find_scale took one. Always one per target: a shorter form can fit
    two readings (``[picture, second]`` is also one picture per target of a 2-target preset, which
    then reads its second target in the later picture with boxes found in the first)."""
    looks = [picture] + ([second_look] if second_look else [])
    return [thermal_frame if kind == "thermal" else look for look in looks for kind in kinds]


class ReadError(Exception):
    """The whole request cannot be served; the message is the reason."""


def load_frame(path):
    """A radiometric frame in deg C: .npy (float deg C), .csv (deg C), or 16-bit .png/.tiff (0.01 K)."""
    ext = os.path.splitext(path)[1].lower()
    try:
        if ext == ".npy":
            return np.load(path, allow_pickle=False).astype(np.float32)
        if ext == ".csv":
            return np.loadtxt(path, delimiter=",", dtype=np.float32, ndmin=2)
        if ext in (".png", ".tif", ".tiff"):
            raw = cv2.imread(path, cv2.IMREAD_UNCHANGED)
            if raw is None or raw.dtype != np.uint16:
                raise ValueError("not a 16-bit image")
            return raw.astype(np.float32) / 100.0 - 273.15
    except (OSError, ValueError) as err:
        raise ReadError("unreadable thermal frame %s: %s" % (path, err))
    raise ReadError("unsupported thermal frame format: %s" % path)


def decode_reference(data, kind):
    """The image of a reference patch's file content (``data``: bytes, None when missing) as the
    reader uses it: colour for a lamp, grey for a switch; None when it does not decode. The one
    decoder of references: the reader's, and calibration's check at upload."""
    if not data:
        return None
    flags = cv2.IMREAD_COLOR if kind == "lamp" else cv2.IMREAD_GRAYSCALE
    return cv2.imdecode(np.frombuffer(data, np.uint8), flags)


def _zoom_index_from_name(path, count):
    match = re.match(r"zoom(\d+)", os.path.basename(path))
    if match and int(match.group(1)) < count:
        return int(match.group(1))
    return None


class ScaleReader(object):
    def __init__(self, preset_roots, picture_roots, picture_root, locator=None, pointer=None, foreign_region=2.5):
        """``preset_roots``/``picture_roots``: allowed roots of preset directories / input pictures;
        ``picture_root``: where annotated results go (``<picture_root>/<preset_id>/``);
        ``foreign_region``: foreign objects are searched in the targets' bounding box grown by this factor."""
        self.foreign_region = float(foreign_region)
        self.preset_roots = list(preset_roots)
        self.picture_roots = list(picture_roots)
        self.picture_root = picture_root
        self.locator = locator or Locator("orb")
        self.pointer = pointer or PointerReader()

    def _path(self, path, roots, what):
        try:
            return confine_path(path, roots)
        except CommandError as err:
            raise ReadError("%s: %s" % (what, err))

    def _image(self, path):
        image = cv2.imread(path, cv2.IMREAD_COLOR)
        if image is None:
            raise ReadError("picture missing or unreadable: %s" % path)
        return image

    def read(self, directory, foreign_detect, filenames, foreign_filenames, roi_vertex, roi_vertex_thermal,
             stamp):
        """Serve one request; returns ReadOutcome or raises ReadError. ``stamp``: YYYYMMDD_HHMMSS."""
        if foreign_detect not in (FOREIGN_DETECT_READ, FOREIGN_DETECT_FOREIGN, FOREIGN_DETECT_BOTH):
            raise ReadError("foreign_detect must be 0, 1 or 2, got %s" % foreign_detect)
        preset_dir = self._path(directory, self.preset_roots, "directory")
        try:
            preset = load_preset(preset_dir, need_calibration=foreign_detect != FOREIGN_DETECT_FOREIGN)
        except PresetError as err:
            raise ReadError(str(err))
        out_dir = os.path.join(self.picture_root, preset.preset_id)
        outcome = ReadOutcome([], [], [], [], [], [], [])
        if foreign_detect in (FOREIGN_DETECT_READ, FOREIGN_DETECT_BOTH):
            self._read_boxes(preset, filenames, roi_vertex, roi_vertex_thermal, out_dir, stamp, outcome)
        if foreign_detect in (FOREIGN_DETECT_FOREIGN, FOREIGN_DETECT_BOTH):
            self._foreign(preset, foreign_filenames, out_dir, stamp, outcome)
        return outcome

    def _read_boxes(self, preset, filenames, roi_vertex, roi_vertex_thermal, out_dir, stamp, outcome):
        targets = preset.targets
        try:
            quads = quads_from_flat(roi_vertex)
            thermal_quads = quads_from_flat(roi_vertex_thermal)
        except ValueError as err:
            raise ReadError(str(err))
        if len(quads) != len(targets):
            raise ReadError("roi_vertex has %d box(es), the calibration %d target(s)" % (len(quads), len(targets)))
        thermal_ids = [i for i, t in enumerate(targets) if t.kind == "thermal"]
        if len(thermal_quads) != len(thermal_ids):
            raise ReadError("roi_vertex_thermal has %d box(es), the calibration %d thermal target(s)"
                            % (len(thermal_quads), len(thermal_ids)))
        per_box, second_looks = _pictures_per_box(list(filenames), targets, thermal_ids)
        paths = [self._path(f, self.picture_roots, "filename") for f in per_box]
        second_paths = [self._path(f, self.picture_roots, "filename") if f else None for f in second_looks]
        images, frames = {}, {}
        thermal_iter = iter(thermal_quads)
        for i, (target, quad, path) in enumerate(zip(targets, quads, paths)):
            if target.kind == "thermal":
                if path not in frames:
                    frames[path] = load_frame(path)
                frame = frames[path]
                tquad = next(thermal_iter)
                _check_quad(tquad, frame.shape, "thermal box %d" % i)
                try:
                    reading = read_thermal_max(frame, tquad, target.params.get("phase", ""))
                except ValueError as err:
                    raise ReadError("thermal box %d: %s" % (i, err))
                annotated = cv2.applyColorMap(_to_u8(frame), cv2.COLORMAP_INFERNO)
                draw_quad = tquad
            else:
                if path not in images:
                    images[path] = self._image(path)
                image = images[path]
                _check_quad(quad, image.shape, "box %d" % i, partly_outside=target.kind == "pointer")
                try:
                    reading = self.read_target(preset, target, image, quad)
                except ReadFailed as err:
                    raise ReadError("box %d: %s" % (i, err))
                if second_paths[i]:
                    reading = combine_looks(reading, self._second_look(preset, target, second_paths[i], quad, images),
                                            target.scale.full_scale)
                annotated = image.copy()
                draw_quad = quad
            outcome.scale.append(float(reading.value))
            outcome.possibility.append(round(float(reading.confidence), 1))
            why = reading.detail.get("reason", "")   # every reader but the thermal one may doubt its value
            outcome.uncertain.append(why)
            # a needle on its stop pin reads the scale's end: the picture says so (pointer.py, step 4)
            stop = (reading.detail or {}).get("stop", "").split(" (")[0] if target.kind == "pointer" else ""
            _annotate(annotated, draw_quad, "%s %s %.4g (%d%%)%s%s" % (
                target.kind, target.name, reading.value, reading.confidence, " uncertain" if why else "",
                ", " + stop if stop else ""))
            outcome.picture_path.append(_save(annotated, out_dir, "%s_read_%02d.jpg" % (stamp, i)))

    def _second_look(self, preset, target, path, quad, images):
        """The pointer read again in the second look's picture at the same box (taken from the
        same pose a moment later); a picture or box that cannot be read gives a reading without a
        value and its reason, for combine_looks."""
        if path not in images:
            images[path] = self._image(path)
        image = images[path]
        _check_quad(quad, image.shape, "box in the second look %s" % os.path.basename(path), partly_outside=True)
        try:
            return self.read_target(preset, target, image, quad)
        except ReadFailed as err:
            return Reading(float("nan"), 0.0, {"reason": str(err)})

    def read_target(self, preset, target, image, quad):
        """One pointer, lamp or switch target of ``preset`` read in ``quad`` of ``image`` (also the
        bench's replay of a reviewed reading); ReadFailed when it cannot be read."""
        p = target.params
        if target.kind == "pointer":
            reference = self._check_same_gauge(preset, target, image, quad)
            reading = read_pointer(self.pointer, target, image, quad, self._needle_model(preset, p))
            return reading if reference is None else _doubt_focus(reading, image, quad, reference, target.boxes[0])
        if target.kind == "digital" and p.get("style") == "drum":
            return self._read_drum(preset, target, image, quad)
        if target.kind == "digital":
            return read_display(image, quad, display_model(p))
        if target.kind == "lamp":
            refs = None
            if p.get("on_reference"):
                refs = [self._reference_patch(preset, p[key], "lamp")
                        for key in ("on_reference", "off_reference")]
            return read_lamp(image, quad, p["colour"], references=refs)
        refs = [self._reference_patch(preset, p[key], "switch")
                for key in ("open_reference", "closed_reference")]
        return read_switch(image, quad, refs[0], refs[1])

    @staticmethod
    def _read_drum(preset, target, image, quad):
        """A drum counter read with its own print, cut from the calibration picture (drum.own_digits);
        the stroke font alone, and the detail says why, when that picture is gone or reads otherwise."""
        model = drum_model(target.params)
        reference = _calibration_picture(preset, target)
        own = own_digits(reference, target.boxes[0], model) if reference is not None else None
        reading = read_drum(image, quad, model, own)
        if own is None:
            why = "the calibration picture no longer reads as calibrated" if reference is not None else "no picture"
            reading.detail["own"] = "not used: " + why
        return reading

    @staticmethod
    def _check_same_gauge(preset, target, image, quad):
        """A box that shows something else than the calibrated gauge (a wrong picture, the head
        pointing elsewhere, a covered meter) fails rather than giving a number. The calibration
        picture, None when the preset has none."""
        reference = _calibration_picture(preset, target)
        if reference is None:
            return None
        check_face(rectify(image, quad, 128))
        similarity = face_similarity(image, quad, reference, target.boxes[0])
        if similarity < MIN_FACE_SIMILARITY:
            raise ReadFailed("the box does not show the calibrated gauge (similarity %.2f to the preset's "
                             "picture, %.2f needed)" % (similarity, MIN_FACE_SIMILARITY))
        return reference

    def _needle_model(self, preset, params):
        """The target's NeedleModel, None when its calibration has none; a model named but missing or
        corrupt fails the request (never a silent fall back to the line fit alone)."""
        name = params.get("needle_reference")
        if not name:
            return None
        model = NeedleModel.decode(preset.reference(name), self.pointer.inner_band.step_deg)
        if model is None:
            raise ReadError("needle model missing or corrupt: %s (calibrate the preset again)" % preset.file(name))
        return model

    @staticmethod
    def _reference_patch(preset, name, kind):
        ref = decode_reference(preset.reference(name), kind)
        if ref is None:
            raise ReadError("%s reference missing or unreadable: %s" % (kind, preset.file(name)))
        return ref

    def _foreign(self, preset, foreign_filenames, out_dir, stamp, outcome):
        if not foreign_filenames:
            raise ReadError("foreign_detect asks for foreign objects but foreign_filename is empty")
        count = len(preset.info.zoom_levels)
        for j, name in enumerate(foreign_filenames):
            path = self._path(name, self.picture_roots, "foreign_filename")
            image = self._image(path)
            index = _zoom_index_from_name(path, count)
            candidates = [index] if index is not None else list(range(count))
            best = None
            for k in candidates:
                reference = cv2.imread(preset.picture(k), cv2.IMREAD_COLOR)
                if reference is None:
                    continue
                try:
                    located = self.locator.locate(reference, image, [_full_quad(reference)], align=False)
                except LocateError:
                    continue
                if best is None or located.inliers > best[1].inliers:
                    best = (reference, located, k)
            if best is None:
                raise ReadError("foreign_filename %d: no reference picture of the preset matches %s"
                                % (j, zoom_picture_name(candidates[0]) if len(candidates) == 1 else "it"))
            # targets change by design (needles, lamps): leave them out, with a margin
            mapped = [transform_quad(best[1].homography, t.boxes[best[2]]) for t in preset.targets
                      if best[2] in t.boxes]
            exclude = [_grow(q, 1.15) for q in mapped]
            # search the equipment around the targets: farther away, parallax after a pose error
            # makes one homography a poor alignment of the 3-D scene. The equipment is where the
            # scene agrees with the registration (the inlier matches): the fence and sky behind
            # it drift with every stop off the preset pose and are left out.
            region = _grow(_bounding_quad(mapped), self.foreign_region) if mapped else None
            region = _equipment_region(region, best[1].points, image.shape)
            found = detect_foreign(best[0], image, best[1].homography, region=region, exclude=exclude)
            annotated = image.copy()
            for obj in found:
                _annotate(annotated, obj.quad, "foreign %d%%" % obj.confidence, (0, 0, 255))
            outcome.foreign_scale.append(float(len(found)))
            evidence = max([f.confidence for f in found]) if found else min(100.0, best[1].inliers)
            outcome.foreign_possibility.append(round(float(evidence), 1))
            outcome.foreign_picture_path.append(_save(annotated, out_dir, "%s_foreign_%02d.jpg" % (stamp, j)))


def _pictures_per_box(files, targets, thermal_ids):
    """(picture per target, second look per target: a path or "") from ReadScaleCmd.filename: one
    entry per target, one for all (no thermal target), [picture, thermal frame]; or one of these
    forms followed by the same form again for the second look (docs/interface.md, read_scale). The
    single forms are matched first, so a list is never read two ways. Only pointer targets take a
    second look; the entries of the others are ignored there."""
    count = len(targets)

    def single(part):
        if len(part) == count:
            return list(part)
        if len(part) == 1 and not thermal_ids:
            return list(part) * count
        if len(part) == 2 and thermal_ids and count != 2:
            return [part[1] if t.kind == "thermal" else part[0] for t in targets]
        return None
    first = single(files)
    if first is not None:
        return first, [""] * count
    half = len(files) // 2
    first, second = (single(files[:half]), single(files[half:])) if len(files) % 2 == 0 else (None, None)
    if first is None or second is None:
        raise ReadError("filename has %d entries for %d target(s) (%d thermal): give one per target, one "
                        "for all, or [picture, thermal frame]; or one of these followed by the same form for "
                        "the second look" % (len(files), count, len(thermal_ids)))
    return first, [s if t.kind == "pointer" else "" for t, s in zip(targets, second)]


def _doubt_focus(reading, image, quad, reference, reference_quad):
    """``reading`` made uncertain when its box is far less sharp than in the calibration picture: a
    needle out of focus or shaken is read where its blur is darkest, not where it is."""
    ratio = focus_ratio(image, quad, reference, reference_quad)
    if ratio >= MIN_FOCUS_RATIO:
        return reading
    why = "picture out of focus or shaken: %.0f %% of the calibration picture's sharpness" % (100.0 * ratio)
    reason = reading.detail.get("reason")
    detail = dict(reading.detail, reason="%s; %s" % (reason, why) if reason else why)
    return Reading(reading.value, min(reading.confidence, 40.0), detail)


def read_pointer(reader, target, image, quad, model=None):
    """A pointer target's Reading in ``image`` at ``quad`` with the calibration's dial parameters and
    this meter's needle model (None: the line fit alone); ReadFailed when there is no needle to read."""
    p = target.params
    return reader.read(image, quad, target.scale, p.get("centre", (0.5, 0.5)), p.get("radius", 0.45),
                       p.get("aspect", 1.0), p.get("pointer_colour", ""), p.get("ignore_colour", ""),
                       p.get("marks") or None, model)


def learn_pointer(reader, target, image, quad, value):
    """This pointer target's NeedleModel from ``image`` showing ``value`` (ReadFailed: why not)."""
    p = target.params
    return reader.learn(image, quad, target.scale, value, p.get("centre", (0.5, 0.5)), p.get("radius", 0.45),
                        p.get("aspect", 1.0), p.get("pointer_colour", ""), p.get("ignore_colour", ""),
                        p.get("marks") or None)


def _equipment_region(region, points, shape):
    """The search region cut down to the grown bounding box of the registration's inlier points
    (the equipment plane); ``region`` unchanged when there are too few of them."""
    if points is None or len(points) < 8:
        return region
    lo, hi = points.min(axis=0), points.max(axis=0)
    box = _grow(_bounding_quad([np.array([lo, hi])]), 1.1)
    if region is None:
        return box
    x0, y0 = np.maximum(box.min(axis=0), np.asarray(region).min(axis=0))
    x1, y1 = np.minimum(box.max(axis=0), np.asarray(region).max(axis=0))
    if x1 <= x0 or y1 <= y0:
        return region
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])


def _grow(quad, factor):
    centre = np.asarray(quad).mean(axis=0)
    return centre + (np.asarray(quad) - centre) * factor


def _bounding_quad(quads):
    pts = np.vstack(quads)
    x0, y0 = pts.min(axis=0)
    x1, y1 = pts.max(axis=0)
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])


def _full_quad(image):
    h, w = image.shape[:2]
    return [[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]]


def _check_quad(quad, shape, what, partly_outside=False):
    """ReadError for a box that is not a convex quad or not inside the picture. ``partly_outside``
    (a pointer's box): a box reaching out of the picture is read when part of it is inside; the
    pointer reader flags the reading when the dial's pivot or scale arc is not (docs/interface.md,
    read_scale, "A box partly outside the picture")."""
    if not quad_is_convex(quad):
        raise ReadError("%s is not a convex TL,TR,BR,BL quad" % what)
    if quad_inside(quad, shape[1], shape[0]):
        return
    if partly_outside and quad_overlap(quad, shape[1], shape[0]) > 0.0:
        return
    raise ReadError("%s lies outside the %dx%d picture" % (what, shape[1], shape[0]))


def _to_u8(frame):
    lo, hi = float(np.nanmin(frame)), float(np.nanmax(frame))
    return np.clip((frame - lo) * 255.0 / max(hi - lo, 1e-3), 0, 255).astype(np.uint8)


def _annotate(image, quad, text, colour=(0, 255, 0)):
    pts = np.round(np.asarray(quad)).astype(np.int32)
    thickness = max(1, image.shape[1] // 400)
    cv2.polylines(image, [pts], True, colour, thickness, cv2.LINE_AA)
    x, y = int(pts[:, 0].min()), int(max(pts[:, 1].min() - 6, 12))
    cv2.putText(image, text, (x, y), cv2.FONT_HERSHEY_SIMPLEX, max(0.4, image.shape[1] / 2000.0), colour,
                thickness, cv2.LINE_AA)


def _save(image, folder, name):
    """Write a JPEG atomically under a name no earlier result uses (two reads of one preset in the
    same second get ``<stamp>_read_00.jpg`` and ``<stamp>_read_00_2.jpg``: no result is overwritten)."""
    path = os.path.join(folder, name)
    stem, ext = os.path.splitext(path)
    copy = 1
    while os.path.exists(path):
        copy += 1
        path = "%s_%d%s" % (stem, copy, ext)
    ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 90])
    if not ok:
        raise ReadError("cannot encode %s" % path)
    try:
        write_atomic(path, data.tobytes(), mode=PUBLIC_FILE_MODE)
    except FileError as err:
        raise ReadError(str(err))
    return path
