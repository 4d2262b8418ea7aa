"""Seven-segment displays (LED and LCD): read the digits of a calibrated display box.

The operator draws the box tight around the digits and types the value shown now. Calibration
(``learn_display``) finds the display's geometry from that picture and that text: lit segments
brighter or darker than the face (LED / LCD), the slant of an italic font, the share of each digit
cell the digit's strokes fill; it keeps the model under which every segment that must be on is
clearly brighter than every segment that must be off, and refuses when none separates them. A
reading (``read_display``) rectifies the box, samples each segment along its centre line, splits on
from off by the widest gap between the samples (with the calibration's contrast as the floor of a
real gap), and maps each cell to a digit, a minus or a blank. A pattern that is no digit, or a
segment close to the split (an 8 that might be a 0), makes the reading uncertain and names the
candidates. The decimal places come from the calibration (panel meters are fixed-point); a
decimal point seen elsewhere in the picture makes the reading uncertain.

Pure image logic (OpenCV, NumPy): the task and ROS sides see a Reading.
"""
import math
from collections import namedtuple

import numpy as np

from inspection_robot.lazy import lazy_import
from inspection_robot.inspection.geometry import rectify
from inspection_robot.inspection.readers import ReadFailed, Reading, clip_confidence

cv2 = lazy_import("cv2")

# segment order a b c d e f g (a top, then clockwise, g the middle bar)
SEGMENTS = "abcdefg"
PATTERNS = {"0": "abcdef", "1": "bc", "2": "abdeg", "3": "abcdg", "4": "bcfg", "5": "acdfg", "6": "acdefg",
            "7": "abc", "8": "abcdefg", "9": "abcdfg", "-": "g", " ": ""}
CODE = dict((ch, tuple(s in segs for s in SEGMENTS)) for ch, segs in PATTERNS.items())
DECODE = dict((code, ch) for ch, code in CODE.items())
# centre lines of the segments in a digit's frame (u right, v down, both 0..1), as (u0, v0, u1, v1)
LINES = {"a": (0.22, 0.07, 0.78, 0.07), "b": (0.88, 0.17, 0.88, 0.41), "c": (0.88, 0.59, 0.88, 0.83),
         "d": (0.22, 0.93, 0.78, 0.93), "e": (0.12, 0.59, 0.12, 0.83), "f": (0.12, 0.17, 0.12, 0.41),
         "g": (0.22, 0.50, 0.78, 0.50)}
CELL_HEIGHT = 48            # px of a digit's height once rectified
SAMPLES = 7                 # points along each segment's centre line
POLARITIES = ("lit", "dark")   # lit: segments brighter than the face (LED, backlit LCD); dark: plain LCD
SLANTS_DEG = tuple(range(-14, 15, 1))
FILLS = (0.55, 0.6, 0.65, 0.7, 0.75, 0.8, 0.85, 0.9)   # share of a digit's cell (its pitch) its strokes span
CELL_ASPECT = (0.3, 1.3)    # width / height of one digit's cell (its pitch) on real displays, with margin
MIN_CONTRAST = 12.0         # grey levels between on and off segments: less is no display to read
MIN_MARGIN = 0.5            # a segment within the middle half between its cell's dark and lit levels is doubtful
MAX_DIGITS = 12

DisplayModel = namedtuple("DisplayModel", "digit_count polarity slant_deg fill decimals contrast")


def display_model(params):
    """The DisplayModel of a digital target's checked calibration parameters."""
    return DisplayModel(int(params["digit_count"]), params["polarity"], float(params["slant"]), float(params["fill"]),
                        int(params["decimals"]), float(params["contrast"]))


def parse_shown(text):
    """(characters per cell, decimal places, value) of the text typed at calibration: digits, one
    leading minus, one decimal point, leading blanks as spaces ("  42" on a 4-digit display)."""
    if not isinstance(text, str) or not text.strip():
        raise ValueError("the value shown must be the display's text, e.g. '23.5', '-0.12', '  42'")
    body = text.rstrip()
    decimals = 0
    if "." in body:
        if body.count(".") > 1 or body.endswith("."):
            raise ValueError("'%s': one decimal point, followed by digits" % text)
        decimals = len(body) - body.index(".") - 1
        body = body.replace(".", "")
    stripped = body.lstrip(" ")
    if stripped.startswith("-"):
        stripped = stripped[1:]
    if not stripped or not stripped.isdigit():
        raise ValueError("'%s' is not what a seven-segment display shows (digits, a leading minus, "
                         "a decimal point, leading blanks)" % text)
    if len(body) > MAX_DIGITS:
        raise ValueError("'%s' has more than %d digits" % (text, MAX_DIGITS))
    return list(body), decimals, float(body.replace(" ", "")) / 10 ** decimals


def _gray(image):
    return cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image


def _face(image, quad, digit_count):
    """The box rectified: CELL_HEIGHT tall, cells about 0.6 of it wide, as float grey levels."""
    width = max(8, int(round(CELL_HEIGHT * 0.62 * digit_count)))
    face = rectify(_gray(image), quad, width, CELL_HEIGHT).astype(np.float32)
    return cv2.GaussianBlur(face, (3, 3), 0)


def _sample_points(digit_count, width, slant_deg, fill):
    """{(cell, segment): (xs, ys)} of the centre-line sample points, and the decimal point's per gap."""
    pitch = width / float(digit_count)
    shear = math.tan(math.radians(slant_deg)) * CELL_HEIGHT
    t = np.linspace(0.1, 0.9, SAMPLES)
    points = {}
    for k in range(digit_count):
        left = k * pitch + (1.0 - fill) * pitch / 2.0
        for seg, (u0, v0, u1, v1) in LINES.items():
            u, v = u0 + (u1 - u0) * t, v0 + (v1 - v0) * t
            points[(k, seg)] = (left + u * fill * pitch + (0.5 - v) * shear, v * (CELL_HEIGHT - 1))
        # the decimal point: low, in the gap after the digit
        u, v = np.array([1.0 + (1.0 - fill) / (2.0 * fill)]), np.array([0.93])
        points[(k, "dp")] = (left + u * fill * pitch + (0.5 - v) * shear, v * (CELL_HEIGHT - 1))
        # the face inside the digit's two loops: never lit, the dark end of every split (an all-8 display)
        u, v = np.array([0.5, 0.5]), np.array([0.28, 0.72])
        points[(k, "hole")] = (left + u * fill * pitch + (0.5 - v) * shear, v * (CELL_HEIGHT - 1))
    return points


def _levels(face, model):
    """{(cell, segment): mean grey level along it}, segments brighter when on (dark displays inverted);
    also each cell's "dp" (its decimal point) and "hole" (the face inside its loops)."""
    face = face if model.polarity == "lit" else 255.0 - face
    height, width = face.shape
    out = {}
    for key, (xs, ys) in _sample_points(model.digit_count, width, model.slant_deg, model.fill).items():
        xi = np.clip(np.round(xs).astype(int), 0, width - 1)
        yi = np.clip(np.round(ys).astype(int), 0, height - 1)
        out[key] = float(np.mean(face[yi, xi]))
    return out


def _split(values, floor):
    """(threshold, gap) of the widest gap in the sorted ``values`` not narrower than ``floor``; a
    display all on or all off has no such gap: (None, 0)."""
    ordered = np.sort(np.asarray(values, dtype=float))
    gaps = np.diff(ordered)
    if not len(gaps):
        return None, 0.0
    k = int(np.argmax(gaps))
    if gaps[k] < floor:
        return None, float(gaps[k])
    return float(ordered[k] + gaps[k] / 2.0), float(gaps[k])


def learn_display(image, quad, shown):
    """The DisplayModel of a display box showing ``shown`` (the text the operator typed); ReadFailed
    when no polarity, slant and fill makes the picture show that text."""
    cells, decimals, _value = parse_shown(shown)
    count = len(cells)
    q = np.asarray(quad, dtype=float).reshape(4, 2)
    width = (np.linalg.norm(q[1] - q[0]) + np.linalg.norm(q[2] - q[3])) / 2.0
    height = (np.linalg.norm(q[3] - q[0]) + np.linalg.norm(q[2] - q[1])) / 2.0
    aspect = width / max(height, 1e-6) / count
    if not CELL_ASPECT[0] <= aspect <= CELL_ASPECT[1]:
        raise ReadFailed("a box %.0f x %.0f px holds %d digit(s) %.2f as wide as tall each: seven-segment digits are "
                         "%.1f to %.1f; type every digit shown (blank leading digits as spaces) and draw the box "
                         "tight around them" % (width, height, count, aspect, CELL_ASPECT[0], CELL_ASPECT[1]))
    face = _face(image, quad, count)
    want = dict(((k, s), on) for k, ch in enumerate(cells) for s, on in zip(SEGMENTS, CODE[ch]))
    best, best_gap, best_score = None, -np.inf, -np.inf
    for polarity in POLARITIES:
        for slant in SLANTS_DEG:
            for fill in FILLS:
                model = DisplayModel(count, polarity, float(slant), fill, decimals, 0.0)
                levels = _levels(face, model)
                on = [levels[key] for key, lit in want.items() if lit]
                off = [levels[key] for key, lit in want.items() if not lit] + \
                    [levels[(k, "hole")] for k in range(count)]
                gap = (min(on) if on else 255.0) - max(off)
                # the worst pair must separate; among those that do, the centre lines that sit on the
                # strokes (the largest mean contrast) win
                score = gap + (np.mean(on) - np.mean(off) if on else 0.0)
                if score > best_score:
                    best, best_gap, best_score = model, gap, score
    if best_gap < MIN_CONTRAST:
        raise ReadFailed("the picture does not show '%s' in the box as seven segments (best contrast between the "
                         "segments that must be lit and those that must be dark: %.0f grey levels, %.0f needed): draw "
                         "the box tight around the digits and type exactly what the display shows"
                         % (shown, best_gap, MIN_CONTRAST))
    return best._replace(contrast=round(float(best_gap), 1))


def read_display(image, quad, model):
    """Reading of a display box under its calibrated DisplayModel: value, confidence (the weakest
    digit's), detail {"text", "digits": [{"char", "confidence", "candidates"}], "reason" when
    uncertain}. Each cell is split on from off by itself (light falls unevenly on a display), a
    cell whose face is far brighter than the others' is glare, not a blank. ReadFailed when no
    segment is lit anywhere (display off, covered) or no digit can be read at all."""
    face = _face(image, quad, model.digit_count)
    levels = _levels(face, model)
    floor = 0.5 * model.contrast
    faces = [levels[(k, "hole")] for k in range(model.digit_count)]
    face_level = float(np.median(faces))
    chars, digits, doubts, lit_any = [], [], [], False
    for k in range(model.digit_count):
        values = [levels[(k, s)] for s in SEGMENTS]
        if faces[k] > face_level + floor:
            doubts.append("digit %d: its face is %.0f grey levels brighter than the others' (glare?)"
                          % (k + 1, faces[k] - face_level))
            chars.append("?")
            digits.append({"char": "?", "confidence": 0.0, "candidates": []})
            continue
        threshold, _gap = _split(values + [faces[k]], floor)
        if threshold is None:   # nothing lit in this cell: a blank
            code, margins = CODE[" "], [1.0] * len(SEGMENTS)
        else:
            lit_any = True
            on = [v for v in values if v > threshold]
            off = [v for v in values if v <= threshold] + [faces[k]]
            low, high = float(np.median(off)), float(np.median(on))
            code = tuple(v > threshold for v in values)
            margins = [min(1.0, abs((v - low) / (high - low) - 0.5) * 2.0) for v in values]
        char = DECODE.get(code)
        candidates = _candidates(code, margins)
        confidence = 100.0 * min(margins)
        if char is None or (len(candidates) > 1 and min(margins) < MIN_MARGIN):
            doubts.append("digit %d: %s" % (k + 1, "|".join(candidates) if candidates else "no digit"))
            confidence = min(confidence, 40.0)
        chars.append(char if char is not None else (candidates[0] if candidates else "?"))
        digits.append({"char": chars[-1], "confidence": round(confidence, 1), "candidates": candidates,
                       "threshold": None if threshold is None else round(threshold, 1)})
    if not lit_any and not doubts:
        raise ReadFailed("no lit segment stands out in the display box (the calibration saw %.0f grey levels "
                         "between lit and dark segments): display off, covered or overexposed" % model.contrast)
    text = "".join(chars)
    stripped = text.lstrip(" ")
    if not stripped or " " in stripped or "-" in stripped[1:] or stripped == "-":
        doubts.append("'%s' is not a number" % text)
    thresholds = [d.get("threshold") for d in digits]
    dots = [k for k in range(model.digit_count - 1)
            if thresholds[k] is not None and levels[(k, "dp")] > thresholds[k] + floor / 2.0]
    calibrated_dot = model.digit_count - 1 - model.decimals if model.decimals else None
    if dots and dots != [calibrated_dot]:
        where = "after digit %d" % (calibrated_dot + 1) if calibrated_dot is not None else "without one"
        doubts.append("decimal point after digit %s, calibrated %s" % (",".join(str(k + 1) for k in dots), where))
    if "?" in stripped or not stripped.replace("-", ""):
        raise ReadFailed("display box unreadable: %s" % "; ".join(doubts))
    value = float(stripped.replace(" ", "0")) / 10 ** model.decimals
    confidence = min(d["confidence"] for d in digits)
    detail = {"text": _with_point(text, model.decimals), "digits": digits}
    if doubts:
        detail["reason"] = "; ".join(doubts)
        confidence = min(confidence, 40.0)
    return Reading(value, clip_confidence(confidence), detail)


def _candidates(code, margins):
    """The characters this cell could show: its own pattern's, then those that flipping its doubtful
    segments (margin under MIN_MARGIN, or the nearest one) would give, nearest first."""
    doubtful = [i for i, m in enumerate(margins) if m < MIN_MARGIN] or [int(np.argmin(margins))]
    out = [DECODE[code]] if code in DECODE else []
    for i in sorted(doubtful, key=lambda j: margins[j]):
        flipped = tuple(not c if j == i else c for j, c in enumerate(code))
        ch = DECODE.get(flipped)
        if ch is not None and ch not in out:
            out.append(ch)
    return out


def _with_point(text, decimals):
    return text if not decimals else text[:len(text) - decimals] + "." + text[len(text) - decimals:]


def render_display(text, width, height, polarity="lit", slant_deg=0.0, fill=0.75, stroke=0.12,
                   on=(60, 60, 235), off=(30, 30, 45), face=(20, 20, 20)):
    """A seven-segment display showing ``text`` (as parse_shown reads it), BGR ``width`` x ``height``:
    tests and the simulated yard draw their displays with it. ``off`` is the faint unlit segment of a
    real display; ``stroke`` the segments' thickness as a share of the height."""
    cells, decimals, _value = parse_shown(text)
    image = np.zeros((height, width, 3), np.uint8)
    image[:] = face
    pitch = width / float(len(cells))
    shear = math.tan(math.radians(slant_deg)) * height
    thick = max(1, int(round(stroke * height)))
    dot_cell = len(cells) - 1 - decimals if decimals else None
    for k, ch in enumerate(cells):
        left = k * pitch + (1.0 - fill) * pitch / 2.0
        for seg, (u0, v0, u1, v1) in LINES.items():
            lit = CODE[ch][SEGMENTS.index(seg)]
            p0 = (left + u0 * fill * pitch + (0.5 - v0) * shear, v0 * (height - 1))
            p1 = (left + u1 * fill * pitch + (0.5 - v1) * shear, v1 * (height - 1))
            # strokes reach a little past the sampled centre line, as a real segment does
            cv2.line(image, tuple(int(round(c)) for c in p0), tuple(int(round(c)) for c in p1),
                     on if lit else off, thick, cv2.LINE_AA)
        u, v = 1.0 + (1.0 - fill) / (2.0 * fill), 0.93
        centre = (int(round(left + u * fill * pitch + (0.5 - v) * shear)), int(round(v * (height - 1))))
        cv2.circle(image, centre, max(1, thick // 2 + 1), on if k == dot_cell else off, -1, cv2.LINE_AA)
    if polarity == "dark":
        image = 255 - image
    return image
