#!/usr/bin/env python3
"""Benchmark: seven-segment displays and drum counters on real photographs (issue #42), beside
ssocr (the seven-segment OCR program, a Debian package) on the same crops.

The set: bench/data/real_displays.json (photos fetched by ``scripts/real_gauges.py --set
displays`` into ~/.cache/inspection_robot/real_displays, or $REAL_DISPLAYS_DIR; skipped when
absent). Split by source (bench/real_set.py); only the test part's figures count.

Protocol, per device (photos of one physical display): the operator calibrates on its first photo,
typing what it shows, in his box (``calibration_box``, else the labelled box or the whole crop),
retrying a tenth larger or without the leading blanks when refused. Every other photo of the device
is then read with that model in the box the robot finds there (the finder's Locator, ORB features
from the calibration photo; $BENCH_DISPLAYS_BOX=label: carried by the labelled boxes instead)
(``cross``). A device with one photo is not scored (read on its own
picture it would only check its calibration). $BENCH_DISPLAYS_PART: the parts scored (default
both). ssocr reads the same rectified crop, told the polarity the calibration learned (its -f/-b),
iterative threshold, digits found by itself.

Per part and kind: readings, exactly right (the value and not uncertain), right but flagged, wrong
flagged, wrong not flagged (the figure that must be 0), failed (refused with a reason), devices
whose calibration was refused; ssocr's exactly right on the same crops; read time per display.
"""
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import real_set  # noqa: E402
from benchlib import percentile, report  # noqa: E402

from inspection_robot.inspection.digital import parse_shown, read_display  # noqa: E402
from inspection_robot.inspection.digital_learn import learn_display  # noqa: E402
from inspection_robot.inspection.drum import learn_drum, own_digits, read_drum  # noqa: E402
from inspection_robot.inspection.geometry import rectify, sub_quad  # noqa: E402
from inspection_robot.inspection.locate import LocateError, Locator  # noqa: E402
from inspection_robot.inspection.readers import ReadFailed  # noqa: E402
from inspection_robot.lazy import lazy_import  # noqa: E402

cv2 = lazy_import("cv2")
PHOTOS = os.environ.get("REAL_DISPLAYS_DIR") or os.path.join(os.path.expanduser("~"), ".cache", "inspection_robot",
                                                             "real_displays")
PARTS = os.environ.get("BENCH_DISPLAYS_PART", "tuning,test").split(",")
BOX_SOURCE = os.environ.get("BENCH_DISPLAYS_BOX", "find")   # or "label": carried by the labelled boxes
LOCATOR = Locator("orb")
SSOCR_HEIGHT = 80                                   # px of the crop ssocr gets (its segment pixel counts assume it)


def box_quad(photo, image, key="box"):
    """The photo's labelled box (``key``: "box", or "calibration_box", the operator's) as a quad TL,
    TR, BR, BL in the digits' own orientation."""
    height, width = image.shape[:2]
    x, y, w, h = photo.get(key) or photo.get("box") or (0, 0, width, height)
    corners = [[x, y], [x + w, y], [x + w, y + h], [x, y + h]]
    turns = int(round(photo.get("rotation_ccw_deg", 0) / 90.0)) % 4   # the digits' top-left corner first
    return np.array(corners[turns:] + corners[:turns], dtype=float)


def learn(photo, image, quad):
    """(model, the operator's box) for the calibration photo, or (None, reason). The operator draws
    the labelled box, or one a tenth larger each side when that is refused, and types what it
    shows, or without its leading blanks when his box leaves the blank digits out."""
    decimals = parse_shown(photo["shown"])[1]
    why = ""
    for box in (quad, sub_quad(quad, (-0.1, -0.1, 1.1, 1.1))):
        for text in sorted(set([photo["shown"], photo["shown"].lstrip()]), key=len, reverse=True):
            try:   # each learns only a model the picture reads back under as typed (as calibration)
                if photo["kind"] == "drum":
                    return learn_drum(image, box, parse_shown(text)[0], decimals), box
                return learn_display(image, box, text), box
            except ReadFailed as err:
                why = why or str(err)
    return None, why


def carried(box, calibration_quad, live_quad):
    """The operator's box moved and scaled as the labelled box moved from the calibration photo to
    this one (the same display: its digits sit where they sat in it)."""
    src = np.asarray(calibration_quad, dtype=np.float32)[:3]
    dst = np.asarray(live_quad, dtype=np.float32)[:3]
    affine = cv2.getAffineTransform(src, dst)
    return np.hstack([np.asarray(box), np.ones((4, 1))]).dot(affine.T)


def ssocr(image, quad, polarity, tmp):
    """ssocr's reading of the rectified box (None when it prints no number)."""
    q = np.asarray(quad, dtype=float)
    width = np.linalg.norm(q[1] - q[0]) / max(np.linalg.norm(q[3] - q[0]), 1e-6) * SSOCR_HEIGHT
    crop = rectify(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), q, max(8, int(round(width))), SSOCR_HEIGHT)
    path = os.path.join(tmp, "crop.png")
    cv2.imwrite(path, crop)
    colours = ["-f", "white", "-b", "black"] if polarity == "lit" else ["-f", "black", "-b", "white"]
    try:
        out = subprocess.run(["ssocr", "-T", "-d", "-1"] + colours + ["remove_isolated", path],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=10)
    except (OSError, subprocess.TimeoutExpired):
        return None
    try:
        return float(out.stdout.decode(errors="replace").strip())
    except ValueError:
        return None


def score(doc, tmp):
    """One result dict per photo read with another photo's calibration (role cross)."""
    roles = real_set.plan(doc, real_set.device_of)
    found = dict((os.path.splitext(n)[0], os.path.join(PHOTOS, n)) for n in os.listdir(PHOTOS))
    by_device = {}
    out = []
    for photo in doc["photos"]:
        role = roles.get(photo["id"])
        if role in (None, "same") or real_set.part_of(doc, photo) not in PARTS:
            continue
        image = cv2.imread(found[photo["id"]], cv2.IMREAD_COLOR) if photo["id"] in found else None
        if image is None:
            continue
        calibration = real_set.calibration_photo(doc, photo, real_set.device_of)
        device = photo["device"]
        if device not in by_device:
            cal_image = cv2.imread(found[calibration["id"]], cv2.IMREAD_COLOR)
            model, box = learn(calibration, cal_image, box_quad(calibration, cal_image, "calibration_box"))
            by_device[device] = (model, box, box_quad(calibration, cal_image), cal_image)
        model, box, cal_quad, cal_image = by_device[device]
        if role == "calibration":
            continue
        row = {"id": photo["id"], "role": role, "kind": photo["kind"], "device": device,
               "part": real_set.part_of(doc, photo), "truth": parse_shown(photo["shown"])[2]}
        if model is None:
            out.append(dict(row, refused=box))
            continue
        t0 = time.perf_counter()
        if BOX_SOURCE == "label":
            quad = carried(box, cal_quad, box_quad(photo, image))
        else:   # the robot's way: the calibration's box found in this picture by feature matching
            try:
                quad = LOCATOR.locate(cal_image, image, [box]).quads[0]
            except LocateError as err:
                out.append(dict(row, find_failed=str(err)))
                continue
        t1 = time.perf_counter()
        try:
            if photo["kind"] == "drum":   # as read_scale: with the counter's own print from its calibration picture
                reading = read_drum(image, quad, model, own_digits(cal_image, box, model))
            else:
                reading = read_display(image, quad, model)
            row.update(value=reading.value, uncertain=bool(reading.detail.get("reason")),
                       reason=reading.detail.get("reason", ""))
        except ReadFailed as err:
            row.update(failed=str(err))
        row["t_find"], row["t"] = t1 - t0, time.perf_counter() - t1
        if photo["kind"] != "drum":
            row["ssocr"] = ssocr(image, quad, model.polarity, tmp)
        out.append(row)
    return out


def figures(rows):
    """The counts of one group of result rows."""
    read = [r for r in rows if "refused" not in r and "find_failed" not in r]
    right = [r for r in read if "value" in r and abs(r["value"] - r["truth"]) < 1e-9]
    wrong = [r for r in read if "value" in r and abs(r["value"] - r["truth"]) >= 1e-9]
    with_ssocr = [r for r in read if "ssocr" in r]
    out = {"readings": len(rows), "exactly_right": len([r for r in right if not r["uncertain"]]),
           "right_flagged": len([r for r in right if r["uncertain"]]),
           "wrong_flagged": len([r for r in wrong if r["uncertain"]]),
           "wrong_unflagged": len([r for r in wrong if not r["uncertain"]]),
           "failed": len([r for r in read if "failed" in r]),
           "calibration_refused": len([r for r in rows if "refused" in r]),
           "not_found": len([r for r in rows if "find_failed" in r]),
           "devices_refused": len(set(r["device"] for r in rows if "refused" in r))}
    out["exactly_right_pct"] = round(100.0 * out["exactly_right"] / max(1, len(rows)), 1)
    if with_ssocr:
        ssocr_right = [r for r in with_ssocr if r["ssocr"] is not None and abs(r["ssocr"] - r["truth"]) < 1e-9]
        out["ssocr_exactly_right"] = len(ssocr_right)
        out["ssocr_exactly_right_pct"] = round(100.0 * len(ssocr_right) / max(1, len(rows)), 1)
        out["ssocr_no_number"] = len([r for r in with_ssocr if r["ssocr"] is None])
    for key, name in (("t", "read_ms"), ("t_find", "find_ms")):   # the reader alone; finding its box
        times = [r[key] for r in read if key in r]
        if times:
            out[name + "_p50"] = round(1000.0 * percentile(times, 0.5), 1)
            out[name + "_max"] = round(1000.0 * max(times), 1)
    return out


def main():
    if not os.path.isdir(PHOTOS) or not os.listdir(PHOTOS):
        report(bench="displays_real", skipped="no photos in %s: run scripts/real_gauges.py --set displays" % PHOTOS)
        return 0
    doc = real_set.load_displays()
    with tempfile.TemporaryDirectory() as tmp:
        rows = score(doc, tmp)
    for part in real_set.PARTS:
        for role in ("cross",):
            for kinds, name in ((("lit", "dark"), "seven_segment"), (("drum",), "drum")):
                group = [r for r in rows if r["part"] == part and r["role"] == role and r["kind"] in kinds]
                if group:
                    report(bench="displays_real", part=part, protocol=role, kind=name, **figures(group))
    wrong = [r for r in rows if r["part"] == "test" and "value" in r and abs(r["value"] - r["truth"]) >= 1e-9]
    for r in wrong:
        report(bench="displays_real_wrong", **dict((k, v) for k, v in r.items() if k not in ("t", "t_find")))
    if os.environ.get("BENCH_DISPLAYS_ROWS"):
        with open(os.environ["BENCH_DISPLAYS_ROWS"], "w") as f:
            json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
