"""Benchmark: meter finding and reading accuracy over rendered cases with known truth.

Synthetic part (>= 300 cases): a gauge of a random style on a textured wall, recorded from one
head position, then seen again after a head move (shift, zoom change, roll, slight perspective)
with a new random value, lighting gain/offset, glare, blur, noise and partial occlusion.
find = feature localisation of the box against the reference; read = pointer reading in the
located box. World part: the camera team's renderer and ground-truth projection of the
simulated yard's gauges: record a preset, calibrate it from ground truth, come back off by up to
0.3 m / 5 deg, find with the full finder (heading correction, coarse-to-fine, re-centring), read.

Real part (when the photos are present, see scripts/real_gauges.py): real photographs labelled by
eye (bench/data/real_gauges.json), split by source into a tuning and a test part (bench/real_set.py:
the rule, fixed before tuning; only the test part counts), read through read_scale's core
(ScaleReader). No oracle: a dial with several photos is calibrated on one and each other photo is
found (feature matching from the calibration picture) and read ("cross"); a dial's only photo is
read on its own picture ("same_picture", reported apart). Per part: accuracy, the share flagged
uncertain, gross errors (> 10 % FS) not flagged, the share of good readings (<= 2 % FS) flagged,
the figures per category (needle at the scale's start or end, drag pointers, off-centre pivots,
reversed or non-linear scales, obliques), a reliability curve (accuracy per confidence band), and
pictures that are not a gauge, which must fail. BENCH_REAL_DIAL_AXES=1 uses the hand-fitted dial
ellipses (an oracle, off by default), BENCH_REAL_BOX=label places cross boxes from the labels (a
perfect finder), BENCH_REAL_CENTRE_OFF=f calibrates the centre f tick radii off the labelled pivot
(a dial's centre clicked as the pivot), BENCH_REAL_VERBOSE=1 prints every photo's result.

Field part (when ``<data_root>/corrections/`` holds files, BENCH_CORRECTIONS_DIR overrides the
folder): every uncertain patrol reading an operator confirmed or corrected (task_manager's
``review``, docs/interface.md "Uncertain readings and their review") is read again from its picture
and box with its preset's calibration and scored against the operator's true value: the field set
grows with every review. Only pointer targets with a known picture and box are scored.

Prints one JSON line per figure: mean abs error (% of full scale), share within 1 % and 1.5 %
FS, find success rate, mean ROI IoU, time per find and per read.
"""
import json
import math
import os
import shutil
import sys
import tempfile
import time

import cv2
import numpy as np

from inspection_robot_testing import fixtures as S
from inspection_robot.inspection.geometry import quad_iou, transform_quad
from inspection_robot.inspection.locate import LocateError, Locator
from inspection_robot.inspection.pointer import PointerReader
from inspection_robot.inspection.readers import ReadFailed

import real_set   # bench/real_set.py: the real set's split and protocol

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
W, H = 640, 360
CASES = int(os.environ.get("BENCH_INSPECTION_CASES", "320"))   # 0: no synthetic part
# 1: use the hand-fitted dial ellipses (``dial_axes``) of oblique photos; off by default: a field
# calibration has no such ellipse (an oracle)
USE_DIAL_AXES = os.environ.get("BENCH_REAL_DIAL_AXES", "0") == "1"
# 0: calibrate without the marks' positions (no ellipse fit: the reader's calibrated frame only)
USE_MARKS = os.environ.get("BENCH_REAL_MARKS", "1") != "0"
# > 0: the calibration clicks the centre this many tick radii off the labelled pivot, towards the
# scale's middle (where a dial's centre lies from a pivot below it), the marks' angles measured
# about that centre, as a calibration of an off-centre-pivot gauge made at the dial's centre is
CENTRE_OFF = float(os.environ.get("BENCH_REAL_CENTRE_OFF", "0"))
# "find": a cross-protocol photo's box is located by feature matching (the robot's path); "label": moved
# onto its labelled pivot and radius (a finder that is never wrong, to tell finder from reader errors)
BOX_SOURCE = os.environ.get("BENCH_REAL_BOX", "find")
FIND_DETECTOR = os.environ.get("BENCH_REAL_DETECTOR", "orb")    # config/find_scale.yaml's default
# the needle model learned at calibration from the calibration photo's labelled value, as an operator
# types the value the meter shows (calibration.SelfCheck); 0: the line fit alone (calibrations before #40)
NEEDLE_MODEL = os.environ.get("BENCH_REAL_NEEDLE_MODEL", "1") != "0"


def synthetic_case(rng, locator, reader):
    style = list(S.GAUGE_STYLES)[int(rng.integers(0, len(S.GAUGE_STYLES)))]
    low = float(rng.choice([0.0, -0.1, 0.0, -20.0]))
    high = low + float(rng.choice([1.0, 1.6, 2.5, 160.0]))
    scale = S.style_scale(style, low, high)
    wall = S.textured_background(1400, 900, rng)
    side = float(rng.uniform(90, 170))
    quad_wall = S.perspective_quad((700 + rng.uniform(-60, 60), 450 + rng.uniform(-40, 40)), side,
                                   rng.uniform(-35, 35), rng.uniform(-25, 25), rng.uniform(-8, 8))
    ref_matrix = np.array([[1.0, 0, W / 2.0 - 700], [0, 1.0, H / 2.0 - 450], [0, 0, 1]])
    ref = cv2.warpPerspective(wall, ref_matrix, (W, H), flags=cv2.INTER_AREA)
    ref_quad = transform_quad(ref_matrix, quad_wall)
    S.paste(ref, S.draw_gauge_face(scale, rng.uniform(low, high), 400, style), ref_quad)
    # the head comes back a little off: shift, zoom, roll, a touch of perspective
    z = float(rng.uniform(0.8, 1.3))
    a = math.radians(rng.uniform(-3, 3))
    move = np.array([[z * math.cos(a), -z * math.sin(a), 0], [z * math.sin(a), z * math.cos(a), 0],
                     [rng.uniform(-4e-5, 4e-5), rng.uniform(-4e-5, 4e-5), 1.0]])
    centre = np.array([[1, 0, -W / 2.0], [0, 1, -H / 2.0], [0, 0, 1]])
    move = np.linalg.inv(centre).dot(move).dot(centre)
    move[:2, 2] += rng.uniform(-50, 50, 2)
    new_matrix = move.dot(ref_matrix)
    value = float(rng.uniform(low, high))
    new = cv2.warpPerspective(wall, new_matrix, (W, H), flags=cv2.INTER_AREA)
    true_quad = transform_quad(new_matrix, quad_wall)
    S.paste(new, S.draw_gauge_face(scale, value, 400, style), true_quad)
    c = true_quad.mean(axis=0)
    size = np.ptp(true_quad[:, 0])
    glare = (c[0] + rng.uniform(-0.3, 0.3) * size, c[1] + rng.uniform(-0.3, 0.3) * size, size * 0.08) \
        if rng.random() < 0.3 else None
    occlusion = None
    if rng.random() < 0.2:  # a cable or branch across a corner of the box
        corner = true_quad[int(rng.integers(0, 4))]
        d = (c - corner) * 0.35
        occlusion = [corner - [4, 0], corner + [4, 0], corner + d + [4, 0], corner + d - [4, 0]]
    new = S.degrade(new, rng, noise=float(rng.uniform(1, 5)), blur=float(rng.uniform(0, 1.2)),
                    gain=float(rng.uniform(0.55, 1.35)), offset=float(rng.uniform(-15, 15)), glare=glare,
                    occlusion=occlusion)
    ref_features = locator.features(ref)
    t0 = time.perf_counter()
    try:
        located = locator.locate(ref_features, new, [ref_quad])
    except LocateError:
        return None, time.perf_counter() - t0, None, 0.0
    t_find = time.perf_counter() - t0
    iou = quad_iou(located.quads[0], true_quad)
    t0 = time.perf_counter()
    try:
        reading = reader.read(new, located.quads[0], scale)
    except ReadFailed:
        return float("nan"), t_find, time.perf_counter() - t0, iou   # refused: no number
    t_read = time.perf_counter() - t0
    return scale.error_percent_fs(reading.value, value), t_find, t_read, iou


def world_cases(rng, locator, reader, count, tmp):
    """The simulated yard's gauges through the real renderer and the full finder: record a preset,
    calibrate it from ground truth, change the value, come back off by up to 0.3 m / 5 deg, find
    (heading correction, coarse-to-fine, re-centring), read."""
    import yaml
    from inspection_robot.camera.optics import ZoomOptics
    from inspection_robot.inspection.calibration import calibrate
    from inspection_robot.inspection.finder import Finder, FindError
    from inspection_robot.inspection.geometry import quads_from_flat
    from inspection_robot.inspection.preset import load_preset
    from inspection_robot.inspection.recorder import record_preset
    from inspection_robot.sim.inspection_sim import RenderedHead, world_specs
    from inspection_robot.sim.render import Renderer, ground_truth
    from inspection_robot.sim.world import World
    world = World.load(os.path.join(ROOT, "config", "sim_world.yaml"))
    table = yaml.safe_load(open(os.path.join(ROOT, "config", "camera_optics.yaml")))["camera_optics"]
    width, height = 800, 450
    optics = ZoomOptics(table["zoom_hfov_deg"], width, height)
    renderer = Renderer(world, seed=1)
    gauges = [f for f in world.faces.values() if f.type == "gauge"]
    out = []
    for i in range(count):
        face = gauges[i % len(gauges)]
        normal = face.quad.normal
        dist = float(rng.uniform(2.5, 4.0))
        spot = face.quad.centre + normal * dist
        pose = (spot[0], spot[1], math.atan2(-normal[1], -normal[0]))
        tilt = math.degrees(math.atan2(world.sensor_height - face.quad.centre[2], dist))
        zoom = max(1.0, min(30.0, 0.3 * width * dist / (optics.focal_px(1.0, width) * face.quad.width)))
        head = RenderedHead(renderer, optics, pose, world.sensor_height, width, height)
        head.set_angles(0.0, tilt)
        head.set_zoom(zoom)
        low, high = face.range
        face.set_value(float(rng.uniform(low, high)))
        state = {"pan_deg": 0.0, "tilt_deg": tilt, "zoom": zoom, "pose": pose}
        path = record_preset(head, tmp, "case%03d" % i, "20260101_000000", state, min_zoom=optics.min_zoom)
        specs = [s for s in world_specs(world, head) if s["name"] == face.id]
        if not specs:
            out.append((None, 0.0, None, 0.0))
            continue
        calibrate(path, specs, optics)
        preset = load_preset(path)
        value = float(rng.uniform(low, high))
        face.set_value(value)
        dx, dy = rng.uniform(-0.3, 0.3, 2)
        back = (pose[0] + dx, pose[1] + dy, pose[2] + math.radians(rng.uniform(-5, 5)))
        head.pose = back
        finder = Finder(head, optics, locator, os.path.join(tmp, "pictures"), max_moves=3)
        t0 = time.perf_counter()
        try:
            found = finder.find(preset, "find_scale", math.degrees(pose[2] - back[2]), "20260102_000000",
                                cv2.imread)
        except FindError:
            out.append((None, time.perf_counter() - t0, None, 0.0))
            continue
        t_find = time.perf_counter() - t0
        quad = quads_from_flat(found.roi_vertex)[0]
        truth = ground_truth(world, head.camera())["faces"][face.id]
        image = cv2.imread(found.filename)
        p = preset.targets[0].params
        t0 = time.perf_counter()
        reading = reader.read(image, quad, preset.targets[0].scale, p["centre"], p["radius"], p["aspect"])
        t_read = time.perf_counter() - t0
        out.append((preset.targets[0].scale.error_percent_fs(reading.value, value), t_find, t_read,
                    quad_iou(quad, np.array(truth["corners"]))))
    return out


def mark_angles(label, px, py, sx=1.0, sy=1.0):
    """The labelled marks' angles (deg clockwise from up) about (``px``, ``py``) in the dial's frontal
    frame (an ellipse ``sx`` x ``sy`` dial radii seen as a circle)."""
    return [math.degrees(math.atan2((x - px) / sx, -(y - py) / sy)) % 360.0 for _, x, y in label["marks"]]


def label_spec(label, width, height):
    """A calibration target spec (calibration.build_targets' format) from a photo's labels: a box
    1.15 tick radii around the pivot grown to hold every mark (clipped to the picture), the marks'
    angles as the scale.
    ``dial_axes`` [sx, sy] (an oblique view: the round dial seen as an ellipse sx·R wide, sy·R
    high) makes the box that ellipse's bounding box with the physical aspect of a square, so the
    reader's rectification (the same one that undoes the finder's homography) sees a round dial;
    the marks' angles are taken in that frontal frame."""
    px, py = label["pivot"]
    sx, sy = label.get("dial_axes", (1.0, 1.0)) if USE_DIAL_AXES else (1.0, 1.0)
    r = float(label["radius"])
    if CENTRE_OFF > 0.0:
        marks = np.array([(x, y) for _, x, y in label["marks"]], float)
        ends = (marks[0] + marks[-1]) / 2.0 - (px, py)
        middle = marks[len(marks) // 2] - (px, py)
        towards = middle if np.hypot(*ends) < 0.3 * r else ends     # a near-full circle: its middle mark
        px, py = np.array([px, py]) + CENTRE_OFF * r * towards / np.hypot(*towards)
    mx, my = [float(x) for _, x, _ in label["marks"]], [float(y) for _, _, y in label["marks"]]
    pad = 0.05 * r     # the box holds every mark, as an operator draws it round the whole scale
    x0, y0 = max(0.0, min(px - 1.15 * r * sx, min(mx) - pad)), max(0.0, min(py - 1.15 * r * sy, min(my) - pad))
    x1 = min(width - 1.0, max(px + 1.15 * r * sx, max(mx) + pad))
    y1 = min(height - 1.0, max(py + 1.15 * r * sy, max(my) + pad))
    angles = mark_angles(label, px, py, sx, sy)
    values = [float(v) for v, _, _ in label["marks"]]
    spec = {"kind": "pointer", "name": label["id"], "box": [x0, y0, x1, y0, x1, y1, x0, y1],
            "centre": ((px - x0) / (x1 - x0), (py - y0) / (y1 - y0)), "radius": r * sx / (x1 - x0),
            "aspect": ((x1 - x0) / sx) / ((y1 - y0) / sy), "start_angle": angles[0], "end_angle": angles[-1],
            "start_value": values[0], "end_value": values[-1], "unit": label.get("unit", "")}
    if len(values) > 2:
        spec["scale_table"] = list(zip(values, angles))
    if USE_MARKS:
        spec["marks"] = [(float(v), (x - x0) / (x1 - x0), (y - y0) / (y1 - y0)) for v, x, y in label["marks"]]
    for key in ("pointer_colour", "ignore_colour"):
        if label.get(key):
            spec[key] = label[key]
    return spec


def real_photo_preset(root, label, picture, optics_for, shown=None):
    """A one-picture preset of ``picture`` calibrated from ``label``; returns its directory. ``shown``:
    the value the picture shows, typed at calibration (the needle model is learned from it); None:
    learned from the reader's own confident reading, as without a typed value."""
    from inspection_robot.files import write_atomic
    from inspection_robot.inspection.calibration import SelfCheck, calibrate
    from inspection_robot.inspection.preset import PresetDirWriter, PresetInfo
    image = cv2.imread(picture)
    height, width = image.shape[:2]
    with PresetDirWriter(root, label["id"].replace(".", "_"), "20260101_000000") as writer:
        cv2.imwrite(writer.file("zoom0.jpg"), image, [cv2.IMWRITE_JPEG_QUALITY, 97])
        info = PresetInfo(label["id"], "visible", False, "20260101_000000", 0.0, 0.0, 1.0, 0x4000,
                          (0.0, 0.0, 0.0), [1.0], width, height)
        write_atomic(writer.file("preset.ini"), info.to_ini())
        check = SelfCheck([shown], force=True) if NEEDLE_MODEL else None
        calibrate(writer.path, [label_spec(label, width, height)], optics_for(width, height), check=check)
        return writer.commit()


def _label_box(calibration, live, box):
    """The calibration box moved onto ``live``'s labelled pivot and scaled by the labelled radii: a
    finder that is never wrong (BENCH_REAL_BOX=label), to tell finder errors from reader errors."""
    scale = float(live["radius"]) / float(calibration["radius"])
    return (np.asarray(box, float) - calibration["pivot"]) * scale + live["pivot"]


def occluded_copy(label, picture, path, cover=0.35):
    """``picture`` with a bird's nest (sim.faces.paint_foreign) over its needle's outer half (centred
    at 0.6 of the labelled radius along the labelled value's angle, ``cover`` radii each side),
    written to ``path``: a synthetic occluder on a real photo (reported apart from the real figures)."""
    from inspection_robot.inspection.gauge import GaugeScale
    from inspection_robot_testing.world_views import cover_with_nest
    image = cv2.imread(picture)
    (px, py), r = label["pivot"], float(label["radius"])
    table = list(zip([float(v) for v, _, _ in label["marks"]], mark_angles(label, px, py)))
    scale = GaugeScale(table[0][1], table[-1][1], table[0][0], table[-1][0], table)
    a = math.radians(scale.angle(label["truth"]))
    cover_with_nest(image, px + 0.6 * r * math.sin(a), py - 0.6 * r * math.cos(a), max(2, int(cover * r)),
                    len(label["id"]))
    cv2.imwrite(path, image)
    return path


def real_cases(photo_dir, tmp, occlude=False):
    """Score every scored photo present in ``photo_dir`` by its protocol (real_set.plan); returns the
    result dicts. "cross": the dial's calibration photo makes the preset, the box is located in this
    photo by feature matching (the finder's Locator), then read; "same": the photo is both.
    ``occlude``: every photo read (not the calibration) gets a nest over its needle (occluded_copy)."""
    from inspection_robot.inspection.geometry import flat_from_quads
    from inspection_robot.inspection.preset import load_preset
    from inspection_robot.inspection.reading import ReadError, ScaleReader
    doc = real_set.load()
    roles = real_set.plan(doc)
    seen = dict((s["repo"], s.get("seen_by_reader", False)) for s in doc["sources"])
    by_id = dict((p["id"], p) for p in doc["photos"])
    found = dict((os.path.splitext(n)[0], os.path.join(photo_dir, n)) for n in os.listdir(photo_dir))
    reader = ScaleReader([tmp], [tmp, photo_dir], os.path.join(tmp, "results"),
                         pointer=PointerReader())
    locator = Locator(FIND_DETECTOR)
    out = []
    for label in doc["photos"] + doc["negatives"]:
        negative = "calibration_of" in label
        role = "negative" if negative else roles.get(label["id"])
        picture = found.get(label["id"])
        if role in (None, "calibration") or picture is None:
            continue
        calibration = by_id[label["calibration_of"]] if negative else real_set.calibration_photo(doc, label)
        if calibration["id"] not in found:
            continue
        if occlude:
            if negative or "truth" not in label:
                continue
            picture = occluded_copy(label, picture, os.path.join(tmp, "occluded_%s.png" % label["id"]))
        row = {"id": label["id"], "negative": negative, "role": role, "failed": "", "find_failed": "",
               "part": real_set.part_of(doc, label), "repo": label["repo"], "seen": seen[label["repo"]],
               "dial": real_set.dial_of(label), "categories": real_set.categories_of(label)}
        # the value shown is typed for a calibration photo that is not the one read (on the same
        # photo, the model would know the answer: the reader's own reading teaches it there)
        preset_dir = real_photo_preset(tmp, dict(calibration, id=label["id"]), found[calibration["id"]],
                                       S.linear_optics, calibration.get("truth") if role == "cross" else None)
        preset = load_preset(preset_dir)
        quad = preset.targets[0].boxes[0]
        t0 = time.perf_counter()
        if role == "cross" and BOX_SOURCE == "label":
            quad = _label_box(calibration, label, quad)
        elif role == "cross":
            try:
                quad = locator.locate(cv2.imread(found[calibration["id"]]), cv2.imread(picture), [quad]).quads[0]
            except LocateError as err:
                out.append(dict(row, find_failed=str(err), t=time.perf_counter() - t0))
                continue
        try:
            outcome = reader.read(preset_dir, 0, [picture], [], flat_from_quads([quad]), [], "20260102_000000")
        except ReadError as err:
            out.append(dict(row, failed=str(err), t=time.perf_counter() - t0))
            continue
        scale = preset.targets[0].scale
        error = scale.error_percent_fs(outcome.scale[0], label["truth"]) if "truth" in label else None
        out.append(dict(row, error=error, value=outcome.scale[0], truth=label.get("truth"),
                        confidence=outcome.possibility[0], uncertain=outcome.uncertain[0],
                        label_uncertainty_pct_fs=100.0 * label.get("uncertainty", 0.0) / scale.full_scale,
                        t=time.perf_counter() - t0))
    return doc, out


def correction_cases(folder):
    """Read every correction file's picture again (its box, its preset's calibration); the result
    dicts with the error against the operator's true value (% FS)."""
    from inspection_robot.inspection.preset import PresetError, load_preset
    from inspection_robot.inspection.reading import ScaleReader
    reader = ScaleReader([], [], folder, pointer=PointerReader())
    out = []
    for name in sorted(n for n in os.listdir(folder) if n.endswith(".json")):
        with open(os.path.join(folder, name)) as f:
            case = json.load(f)
        if case.get("kind") != "pointer" or not case.get("picture") or len(case.get("roi") or []) != 8:
            continue
        image = cv2.imread(case["picture"], cv2.IMREAD_COLOR)
        try:
            preset = load_preset(case["preset"])
            target = preset.targets[case["target"]]
        except (PresetError, IndexError) as err:
            out.append({"id": name, "failed": "preset: %s" % err})
            continue
        if image is None:
            out.append({"id": name, "failed": "picture missing: %s" % case["picture"]})
            continue
        t0 = time.perf_counter()
        try:
            reading = reader.read_target(preset, target, image, np.array(case["roi"], float).reshape(4, 2))
        except ReadFailed as err:
            out.append({"id": name, "failed": str(err), "t": time.perf_counter() - t0})
            continue
        out.append({"id": name, "failed": "", "value": reading.value, "truth": case["true_value"],
                    "error": target.scale.error_percent_fs(reading.value, case["true_value"]),
                    "uncertain": bool(reading.detail.get("reason")), "t": time.perf_counter() - t0})
    return out


def report_corrections(rows):
    print(json.dumps(dict(_accuracy("inspection_field_corrections", rows), files=len(rows),
                          failed=sum(1 for r in rows if r["failed"]),
                          still_uncertain=sum(1 for r in rows if r.get("uncertain")))))


GOOD_PCT_FS = 2.0     # a reading this close to the truth is good: flagging it uncertain costs an operator a look
GROSS_PCT_FS = 10.0   # farther than this is a gross error: acceptable only when flagged uncertain


def _accuracy(name, rows, **extra):
    """Accuracy figures of the rows that gave a number, and how the reader's flag sorted them."""
    read = [r for r in rows if r.get("error") is not None]
    figures = {"bench": name, "n": len(rows), "read": len(read), "failed": len([r for r in rows if r["failed"]]),
               "find_failed": len([r for r in rows if r.get("find_failed")])}
    figures.update(extra)
    if not read:
        return figures
    errors = np.array([r["error"] for r in read])
    good = [r for r in read if r["error"] <= GOOD_PCT_FS]
    figures.update({"mean_abs_error_pct_fs": round(float(errors.mean()), 3),
                    "median_pct_fs": round(float(np.median(errors)), 3),
                    "within_1pct_fs": round(float((errors <= 1.0).mean()), 4),
                    "within_2pct_fs": round(float((errors <= GOOD_PCT_FS).mean()), 4),
                    "within_5pct_fs": round(float((errors <= 5.0).mean()), 4),
                    "uncertain": len([r for r in read if r.get("uncertain")]),
                    "gross_unflagged": len([r for r in read if r["error"] > GROSS_PCT_FS and not r.get("uncertain")]),
                    "good_flagged_share": round(len([r for r in good if r.get("uncertain")]) / float(len(good)), 4)
                    if good else None})
    return figures


def report_real(doc, rows):
    if os.environ.get("BENCH_REAL_VERBOSE"):
        for r in rows:
            print(json.dumps(dict((k, v) for k, v in r.items() if k not in ("t",))))
    print(json.dumps(dict(real_set.summary(doc), bench="inspection_real_set", box=BOX_SOURCE,
                          dial_axes=USE_DIAL_AXES)))
    photos = [r for r in rows if not r["negative"]]
    for part in real_set.PARTS:
        mine = [r for r in photos if r["part"] == part]
        prefix = "inspection_real_%s" % part
        counts = "(the figure that counts)" if part == "test" else "(tune on this part only)"
        print(json.dumps(_accuracy(prefix, mine, sources=len(set(r["repo"] for r in mine)), note=counts)))
        print(json.dumps(_accuracy(prefix + "_cross", [r for r in mine if r["role"] == "cross"])))
        print(json.dumps(_accuracy(prefix + "_same_picture", [r for r in mine if r["role"] == "same"])))
        if part == "test":
            unseen = [r for r in mine if not r["seen"]]
            print(json.dumps(_accuracy(prefix + "_unseen_sources", unseen,
                                       sources=len(set(r["repo"] for r in unseen)))))
        for category in real_set.CATEGORIES:
            print(json.dumps(_accuracy(prefix + "_" + category, [r for r in mine if category in r["categories"]])))
        read = [r for r in mine if r.get("error") is not None]
        for low, high in ((0, 25), (25, 50), (50, 75), (75, 90), (90, 101)):
            band = [r for r in read if low <= r["confidence"] < high]
            print(json.dumps(_accuracy(prefix + "_reliability", band, confidence="%d-%d" % (low, min(high, 100)))))
    negatives = [r for r in rows if r["negative"]]
    print(json.dumps({"bench": "inspection_real_not_a_gauge", "n": len(negatives),
                      "failed": len([r for r in negatives if r["failed"]]),
                      "reasons": sorted(set(r["failed"].split(": ", 1)[-1][:60] for r in negatives if r["failed"]))}))
    print(json.dumps({"bench": "inspection_real_read", "n": len(rows),
                      "p50_ms": round(1000 * float(np.median([r["t"] for r in rows])), 1)}))


def report(name, results):
    refused = len([r for r in results if r[0] is not None and math.isnan(r[0])])
    errors = np.array([r[0] for r in results if r[0] is not None and not math.isnan(r[0])])
    finds = [r for r in results if r[0] is not None]
    figures = {"bench": name + "_accuracy", "n": len(results), "read_refused": refused,
               "mean_abs_error_pct_fs": round(float(errors.mean()), 3) if len(errors) else None,
               "within_1pct_fs": round(float((errors <= 1.0).mean()), 4) if len(errors) else None,
               "within_1_5pct_fs": round(float((errors <= 1.5).mean()), 4) if len(errors) else None,
               "p99_error_pct_fs": round(float(np.percentile(errors, 99)), 3) if len(errors) else None}
    print(json.dumps(figures))
    print(json.dumps({"bench": name + "_find", "n": len(results),
                      "success_rate": round(len(finds) / float(len(results)), 4),
                      "mean_roi_iou": round(float(np.mean([r[3] for r in finds])), 4) if finds else None,
                      "p50_ms": round(1000 * float(np.median([r[1] for r in results])), 1)}))
    if finds:
        print(json.dumps({"bench": name + "_read", "n": len(finds),
                          "p50_ms": round(1000 * float(np.median([r[2] for r in finds])), 1),
                          "p99_ms": round(1000 * float(np.percentile([r[2] for r in finds], 99)), 1)}))


def main():
    cv2.setNumThreads(1)
    rng = np.random.default_rng(2024)
    locator = Locator("orb", max_side=960)
    reader = PointerReader()
    if CASES > 0:
        report("inspection_synthetic", [synthetic_case(rng, locator, reader) for _ in range(CASES)])
    photo_dir = os.environ.get("REAL_GAUGES_DIR") or os.path.expanduser("~/.cache/inspection_robot/real_gauges")
    if os.path.isdir(photo_dir):
        tmp = tempfile.mkdtemp(prefix="bench_inspection_real_")
        try:
            report_real(*real_cases(photo_dir, tmp))
            if os.environ.get("BENCH_REAL_OCCLUDED", "1") != "0":
                rows = real_cases(photo_dir, tempfile.mkdtemp(dir=tmp), occlude=True)[1]   # presets of its own
                for part in real_set.PARTS:
                    print(json.dumps(_accuracy("inspection_real_%s_synthetic_occluder" % part,
                                               [r for r in rows if r["part"] == part])))
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    else:
        print(json.dumps({"bench": "inspection_real", "skipped": "no photos in %s (run scripts/real_gauges.py)"
                          % photo_dir}))
    corrections = os.environ.get("BENCH_CORRECTIONS_DIR") or os.path.join(
        os.environ.get("ROS_HOME", os.path.expanduser("~/.ros")), "inspection_robot", "corrections")
    if os.path.isdir(corrections):
        report_corrections(correction_cases(corrections))
    else:
        print(json.dumps({"bench": "inspection_field_corrections", "skipped": "no folder %s" % corrections}))
    world_count = int(os.environ.get("BENCH_INSPECTION_WORLD_CASES", "40"))
    if world_count > 0:
        tmp = tempfile.mkdtemp(prefix="bench_inspection_")
        try:
            report("inspection_world", world_cases(rng, locator, reader, world_count, tmp))
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
