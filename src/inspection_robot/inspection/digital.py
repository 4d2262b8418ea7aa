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
from functools import lru_cache

import numpy as np

from inspection_robot.lazy import lazy_import
from inspection_robot.inspection.geometry import quad_size, rectify, sub_quad
from inspection_robot.inspection.readers import ReadFailed, Reading, clip_confidence

cv2 = lazy_import("cv2")

# segment order a b c d e f g (a top, then clockwise, g the middle bar)
SEGMENTS = "abcdefg"
PATTERNS = {"0": "abcdef", "1": "bc", "2": "abdeg", "3": "abcdg", "4": "bcfg", "5": "acdfg", "6": "acdefg",
            "7": "abc", "8": "abcdefg", "9": "abcdfg", "-": "g", " ": ""}
CODE = dict((ch, tuple(s in segs for s in SEGMENTS)) for ch, segs in PATTERNS.items())
# fonts differ in three digits: a 7 with its top-left bar (f), a 6 without its top (a), a 9 without
# its bottom (d); neither form is another digit, so both read, and calibration does not insist on it
VARIANTS = {"7": "f", "6": "a", "9": "d"}
DECODE = dict((code, ch) for ch, code in CODE.items())
DECODE.update((tuple(on != (s == VARIANTS[ch]) for s, on in zip(SEGMENTS, CODE[ch])), ch) for ch in VARIANTS)
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
MAX_STRAY_INK = 0.08          # share of a digit's strokes a learned model may leave unexplained
SHIFTS = (-0.08, -0.04, 0.0, 0.04, 0.08)   # how far the cells may begin or end from the box's sides (its share)

FULL_BOX = (0.0, 0.0, 1.0, 1.0)
# ``window``: where the digits' cells sit in the box drawn (left, top, right, bottom fractions of it),
# found at calibration: an operator's box is seldom tight
DisplayModel = namedtuple("DisplayModel", "digit_count polarity slant_deg fill decimals contrast window")


def display_model(params):
    """The DisplayModel of a digital target's checked calibration parameters."""
    return DisplayModel(int(params["digit_count"]), params["polarity"], float(params["slant"]), float(params["fill"]),
                        int(params["decimals"]), float(params["contrast"]),
                        tuple(params.get("window") or FULL_BOX))


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


def gray(image):
    return cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image


def _face(image, quad, digit_count, window=FULL_BOX):
    """The digits' window of the box rectified: CELL_HEIGHT tall, cells about 0.6 of it wide, as
    float grey levels."""
    width = max(8, int(round(CELL_HEIGHT * 0.62 * digit_count)))
    face = rectify(gray(image), sub_quad(quad, window), width, CELL_HEIGHT).astype(np.float32)
    return cv2.GaussianBlur(face, (3, 3), 0)


def _ink_box(image, quad, polarity):
    """(left, top, right, bottom) fractions of the box its digits' strokes span: the pixels on the
    ink side of Otsu's split, in pieces that do not touch the box's edge (a bezel, a frame, the
    next reading) and lie among the tallest ones, or None when nothing is left."""
    q = np.asarray(quad, dtype=float).reshape(4, 2)
    aspect = np.linalg.norm(q[1] - q[0]) / max(np.linalg.norm(q[3] - q[0]), 1e-6)
    height = 4 * CELL_HEIGHT
    width = max(16, int(round(height * aspect)))
    face = cv2.GaussianBlur(rectify(gray(image), q, width, height), (5, 5), 0)
    ink = face if polarity == "lit" else 255 - face
    _t, mask = cv2.threshold(ink, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    count, _labels, stats, _centres = cv2.connectedComponentsWithStats(mask)
    kept = [s for s in stats[1:] if s[0] > 0 and s[1] > 0 and s[0] + s[2] < width and s[1] + s[3] < height
            and s[4] >= 0.0005 * width * height]
    if not kept:
        return None
    # the digits are the tallest things in the box; a unit, a label or a scratch is smaller: the
    # strokes are the pieces at least half as tall as the tallest and what lies among them
    tall = [s for s in kept if s[3] >= 0.5 * max(k[3] for k in kept)]
    rows = (min(s[1] for s in tall), max(s[1] + s[3] for s in tall))
    columns = (min(s[0] for s in tall), max(s[0] + s[2] for s in tall))
    kept = [s for s in kept if s[1] >= rows[0] - 2 and s[1] + s[3] <= rows[1] + 2
            and columns[0] <= s[0] + s[2] / 2.0 <= columns[1]]
    x0, y0 = min(s[0] for s in kept), min(s[1] for s in kept)
    x1, y1 = max(s[0] + s[2] for s in kept), max(s[1] + s[3] for s in kept)
    return x0 / float(width), y0 / float(height), x1 / float(width), y1 / float(height)


def _window(ink, cells, fill):
    """The cells' window (box fractions) for strokes spanning ``ink`` when a digit's strokes take
    ``fill`` of its cell: blank leading cells left of the first stroke, a 1's strokes on its right."""
    left, top, right, bottom = ink
    first = next(k for k, ch in enumerate(cells) if ch != " ")
    start = {"1": 0.75, "-": 0.15}.get(cells[first], 0.0)    # where the first character's ink begins
    end = {"-": 0.85}.get(cells[-1], 1.0)                     # and where the last one's ends
    pitch = (right - left) / ((len(cells) - 1 - first) + fill * (end - start))
    cell_left = left - start * fill * pitch - first * pitch - (1.0 - fill) * pitch / 2.0
    return (cell_left, top, cell_left + len(cells) * pitch, bottom)


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


@lru_cache(maxsize=4096)
def _sample_index(digit_count, width, slant_deg, fill):
    """The sample points of _sample_points as (keys, flat pixel indices into a CELL_HEIGHT x width
    face, each key's first index, each key's count): one gather per model, not one per segment."""
    keys, flat, starts, counts = [], [], [], []
    for key, (xs, ys) in _sample_points(digit_count, width, slant_deg, fill).items():
        xi = np.clip(np.round(xs).astype(int), 0, width - 1)
        yi = np.clip(np.round(ys).astype(int), 0, CELL_HEIGHT - 1)
        keys.append(key)
        starts.append(len(flat))
        counts.append(len(xi))
        flat.extend((yi * width + xi).tolist())
    return tuple(keys), np.array(flat), np.array(starts), np.array(counts, dtype=float)


def _levels(face, model):
    """{(cell, segment): mean grey level along it}, segments brighter when on (dark displays inverted);
    also each cell's "dp" (its decimal point) and "hole" (the face inside its loops)."""
    face = face if model.polarity == "lit" else 255.0 - face
    keys, flat, starts, counts = _sample_index(model.digit_count, face.shape[1], model.slant_deg, model.fill)
    means = np.add.reduceat(face.ravel()[flat], starts) / counts
    return dict(zip(keys, means.tolist()))


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
    """The DisplayModel of a display box showing ``shown`` (the text the operator typed), one the
    picture reads back under as that text; ReadFailed when no window, polarity, slant and fill
    makes the picture show it."""
    cells, decimals, value = parse_shown(shown)
    count = len(cells)
    width, height = quad_size(quad)
    aspect = width / max(height, 1e-6) / count
    if not CELL_ASPECT[0] <= aspect <= CELL_ASPECT[1]:
        raise ReadFailed("a box %.0f x %.0f px holds %d digit(s) %.2f as wide as tall each: seven-segment digits are "
                         "%.1f to %.1f; type every digit shown (blank leading digits as spaces) and draw the box "
                         "tight around them" % (width, height, count, aspect, CELL_ASPECT[0], CELL_ASPECT[1]))
    want = dict(((k, s), on) for k, ch in enumerate(cells) for s, on in zip(SEGMENTS, CODE[ch])
                if s != VARIANTS.get(ch))

    def fit(windows, polarities, fills, slants, keep=4):
        """The ``keep`` best (score, gap, model) over the windows, polarities, fills and slants, best first."""
        found = []
        for window in windows:
            face = _face(image, quad, count, window)
            for polarity in polarities:
                for fill in fills:
                    for slant in slants:
                        model = DisplayModel(count, polarity, float(slant), fill, decimals, 0.0, window)
                        levels = _levels(face, model)
                        # each digit is split by itself when read (light falls unevenly): in every cell
                        # with a lit segment the worst pair must separate; among the models where they
                        # do, the centre lines that sit on the strokes (the largest mean contrast) win
                        gaps, contrasts = [], []
                        for k in range(count):
                            on = [levels[(k, s)] for s in SEGMENTS if want.get((k, s))]
                            off = [levels[(k, s)] for s in SEGMENTS if want.get((k, s)) is False] + \
                                [levels[(k, "hole")]]
                            if on:
                                gaps.append(min(on) - max(off))
                                contrasts.append(np.mean(on) - np.mean(off))
                        gap = min(gaps) if gaps else -np.inf
                        score = gap + (np.mean(contrasts) if contrasts else 0.0)
                        found.append((score, gap, model))
                    found = sorted(found, key=lambda f: -f[0])[:keep]
        return found

    # an operator's box is seldom tight or centred: the cells may start and end a little inside or
    # outside it, and the strokes found in it may place them (coarse slants first, then every one)
    windows = [(left, 0.0, right, 1.0) for left in SHIFTS for right in (1.0 + d for d in SHIFTS)]
    for polarity in POLARITIES:
        ink = _ink_box(image, quad, polarity) if cells.count(" ") < count else None
        if ink is not None:
            windows += [tuple(round(float(v), 4) for v in _window(ink, cells, fill)) for fill in FILLS]
    candidates = []
    for _score, _gap, coarse in fit(windows, POLARITIES, FILLS, SLANTS_DEG[::4], keep=3):
        left, top, right, bottom = coarse.window
        step = (SHIFTS[1] - SHIFTS[0]) / 2.0   # the sides to half the grid's step, then the top and bottom
        _s, _g, fine = fit([(left + dl, top, right + dr, bottom) for dl in (-step, 0, step) for dr in (-step, 0, step)],
                           (coarse.polarity,), FILLS, SLANTS_DEG[::2], keep=1)[0]
        left, top, right, bottom = fine.window
        candidates += fit([(left, top + dt, right, bottom + db) for dt in SHIFTS[1:-1] for db in SHIFTS[1:-1]],
                          (coarse.polarity,), FILLS, SLANTS_DEG)
    # the best model the picture reads back under as typed (a decimal point, a glare the score misses)
    best_gap, why = max(c[1] for c in candidates), ""
    for _score, gap, model in sorted(candidates, key=lambda c: -c[0]):
        if gap < MIN_CONTRAST:
            continue
        model = model._replace(contrast=round(float(gap), 1))
        try:
            back = read_display(image, quad, model)
        except ReadFailed as err:
            why = why or str(err)
            continue
        stray = _unexplained_ink(_face(image, quad, count, model.window), model, cells)
        if stray > MAX_STRAY_INK:
            why = why or "leaves %.0f %% of a digit's strokes unexplained" % (100.0 * stray)
            continue
        if not back.detail.get("reason") and abs(back.value - value) < 1e-9:
            return model
        doubt = ": " + back.detail["reason"] if back.detail.get("reason") else ""
        why = why or "reads '%s'%s" % (back.detail["text"], doubt)
    if best_gap < MIN_CONTRAST:
        raise ReadFailed("the picture does not show '%s' in the box as seven segments (best contrast between the "
                         "segments that must be lit and those that must be dark: %.0f grey levels, %.0f needed): draw "
                         "the box tight around the digits and type exactly what the display shows"
                         % (shown, best_gap, MIN_CONTRAST))
    raise ReadFailed("no model learned from the picture reads it back as '%s' (the best %s): draw the box tight "
                     "around the digits and type exactly what the display shows" % (shown, why))


def _unexplained_ink(face, model, cells):
    """The largest share, over the digits, of a digit cell's strokes (ink pixels: half-way between
    the model's lit and dark segments) that lie on no segment the typed text lights: a model
    contorted into reading an 8 as a 2 leaves the 8's other strokes over."""
    ink = face if model.polarity == "lit" else 255.0 - face
    levels = _levels(face, model)
    on = [levels[(k, s)] for k, ch in enumerate(cells) for s, lit in zip(SEGMENTS, CODE[ch]) if lit]
    off = [levels[(k, s)] for k, ch in enumerate(cells) for s, lit in zip(SEGMENTS, CODE[ch]) if not lit]
    if not on:
        return 0.0
    # ink: brighter than half-way between the model's lit and dark segments (a faint unlit segment is not)
    mask = (ink > (np.median(on) + np.median(off + [levels[(k, "hole")] for k in range(len(cells))])) / 2.0)
    mask = mask.astype(np.uint8) * 255
    count, labels, stats, _centres = cv2.connectedComponentsWithStats(mask)
    for label in range(1, count):   # a bezel or the next reading at the window's side is not a stroke
        if stats[label, 0] == 0 or stats[label, 0] + stats[label, 2] >= mask.shape[1]:
            mask[labels == label] = 0
    lit = np.zeros_like(mask)
    thick = max(2, int(round(0.22 * CELL_HEIGHT)))
    for (k, seg), (xs, ys) in _sample_points(model.digit_count, face.shape[1], model.slant_deg, model.fill).items():
        lights = seg == "dp" or (seg in SEGMENTS and (CODE[cells[k]][SEGMENTS.index(seg)]
                                                      or seg == VARIANTS.get(cells[k])))
        if lights and len(xs) > 1:   # the samples span 0.1..0.9 of a segment: its whole length and its corners
            ends = [(xs[0] - 0.15 * (xs[-1] - xs[0]), ys[0] - 0.15 * (ys[-1] - ys[0])),
                    (xs[-1] + 0.15 * (xs[-1] - xs[0]), ys[-1] + 0.15 * (ys[-1] - ys[0]))]
            cv2.line(lit, tuple(int(round(v)) for v in ends[0]), tuple(int(round(v)) for v in ends[1]), 255, thick)
        elif lights:
            cv2.circle(lit, (int(round(xs[0])), int(round(ys[0]))), thick // 2, 255, -1)
    strokes, stray = mask > 0, (mask > 0) & (lit == 0)
    pitch = face.shape[1] / float(model.digit_count)
    shares = []
    for k in range(model.digit_count):   # the worst digit: a wrong one leaves whole segments over
        cols = slice(int(round(k * pitch)), int(round((k + 1) * pitch)))
        ink_k = np.count_nonzero(strokes[:, cols])
        if ink_k >= 0.03 * strokes[:, cols].size:
            shares.append(np.count_nonzero(stray[:, cols]) / float(ink_k))
    return max(shares) if shares else 0.0


def read_display(image, quad, model):
    """Reading of a display box under its calibrated DisplayModel: value, confidence (the weakest
    digit's), detail {"text", "digits": [{"char", "confidence", "candidates"}], "reason" when
    uncertain}. Each cell is split on from off by itself (light falls unevenly on a display), a
    cell whose face is far brighter than the others' is glare, not a blank. ReadFailed when no
    segment is lit anywhere (display off, covered) or no digit can be read at all."""
    face = _face(image, quad, model.digit_count, model.window)
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
        if threshold is None:   # nothing lit in this cell: a blank, unless a segment stands half out
            code, margins = CODE[" "], [1.0] * len(SEGMENTS)
            brightest = int(np.argmax(values))
            if values[brightest] - faces[k] > floor / 2.0:   # a dim 1 must not vanish from a number's front
                doubts.append("digit %d: blank or lit (segment %s stands %.0f grey levels out)"
                              % (k + 1, SEGMENTS[brightest], values[brightest] - faces[k]))
                margins = [0.0] * len(SEGMENTS)
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
    detail = {"text": with_point(text, model.decimals), "digits": digits}
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


def with_point(text, decimals):
    """``text`` (digits, one per cell) with the point before its last ``decimals`` digits."""
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
