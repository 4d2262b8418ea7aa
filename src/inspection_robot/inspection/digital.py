"""Seven-segment displays (LED and LCD): read the digits of a calibrated display box.

The operator draws the box tight around the digits and types the value shown now. Calibration
(inspection.digital_learn) finds the display's model from that picture and that text: lit segments
brighter or darker than the face (LED / LCD), the slant of an italic font, the share of each digit
cell the digit's strokes fill, where the cells sit in the box, how lit segments are told from dark.
A reading (``read_display``) rectifies the box, moves the cells to where the digits are
(``_registered``), samples each segment along its centre line, splits each cell's segments on from
off (``_decode_cell``: at the widest gap between them, with the calibration's contrast as the floor
of a real gap, or at half that contrast above the face for a display lit unevenly), and maps each
cell to a digit, a minus or a blank. A pattern that is no digit, or a segment close to the split
(an 8 that might be a 0), makes the reading uncertain and names the candidates. The decimal places
come from the calibration (panel meters are fixed-point); a decimal point seen elsewhere in the
picture makes the reading uncertain.

Pure image logic (OpenCV, NumPy): the task and ROS sides see a Reading.
"""
import math
from collections import namedtuple
from functools import lru_cache

import numpy as np

from inspection_robot.lazy import lazy_import
from inspection_robot.inspection.geometry import grey, rectify, sub_quad
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
MIN_MARGIN = 0.5            # a segment within the middle half between its cell's dark and lit levels is doubtful
MAX_DIGITS = 12
MAX_CELL_SHIFT = 0.5        # cells a digit's cell may sit from even spacing (DisplayModel.shifts)
# a reading moves the cells' window by up to these shares of a cell's pitch (sideways) and of the
# digits' height (up and down), and scales it by up to these factors, to where the picture fits best
REGISTER_SHIFT = 0.6
REGISTER_LIFT = 0.2
REGISTER_SCALE = (0.7, 1.3)
REGISTER_COST = 0.02  # fit (correlation) a move must win per unit of shift to be taken
REGISTER_GAIN = 0.05  # and what it must win over the window as calibrated
REGISTER_KEEP = 4     # coarse moves searched finely about
REGISTER_STEPS = 11   # scales tried between REGISTER_SCALE's two (evenly on a log scale)
# the three bars' (a, g, d) level is the brightest of SLACK_LINES lines parallel to their centre
# line, up to this share of the digits' height above and below it: digits a pixel taller or lower
# than the window (registration keeps the calibrated window unless a move fits clearly better) put
# a lit bar's centre line on its edge. The upright segments are sampled on their centre line only:
# sideways slack made a 0 with its lower-left side dim a confident 7 with its top-left bar, and
# 0.04 of the height reaches past a blank cell's top into the bezel (chosen on the real set's
# tuning part: 45 readings right, 52 with this, 56 with every segment but one confident error)
SEGMENT_SLACK = 0.021
SLACK_LINES = 3
SLACK_SEGMENTS = "adg"
DIM_FLOOR = 0.5      # a display may show this share of its calibrated contrast and still read (see _floor)
STROKE = 0.16         # a segment's thickness, share of the digits' height, where a reading's strokes are drawn

FULL_BOX = (0.0, 0.0, 1.0, 1.0)
# ``window``: where the digits' cells sit in the box drawn (left, top, right, bottom fractions of it),
# found at calibration: an operator's box is seldom tight
# ``shifts``: each digit cell's shift from even spacing, in cells (a decimal point with a column of its
# own pushes the digits after it right), learned at calibration; () is even spacing
# ``split``: how a cell's segments are told lit from dark (_decode_cell): "gap" or "face", learned
DisplayModel = namedtuple("DisplayModel", "digit_count polarity slant_deg fill decimals contrast window shifts split")
DisplayModel.__new__.__defaults__ = ((), "gap")
SPLITS = ("gap", "face")


def display_model(params):
    """The DisplayModel of a digital target's checked calibration parameters."""
    return DisplayModel(int(params["digit_count"]), params["polarity"], float(params["slant"]), float(params["fill"]),
                        int(params["decimals"]), float(params["contrast"]),
                        tuple(params.get("window") or FULL_BOX), tuple(params.get("cell_shifts") or ()),
                        params.get("split") or "gap")


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


def _face(image, quad, digit_count, window=FULL_BOX):
    """The digits' window of the box rectified: CELL_HEIGHT tall, cells about 0.6 of it wide, as
    float grey levels."""
    width = max(8, int(round(CELL_HEIGHT * 0.62 * digit_count)))
    face = rectify(grey(image), sub_quad(quad, window), width, CELL_HEIGHT).astype(np.float32)
    return cv2.GaussianBlur(face, (3, 3), 0)


def _sample_points(digit_count, width, slant_deg, fill, shifts=()):
    """{(cell, segment): (xs, ys)} of the centre-line sample points, and the decimal point's per gap;
    cell k moved ``shifts[k]`` cells right of even spacing."""
    pitch = width / float(digit_count)
    shear = math.tan(math.radians(slant_deg)) * CELL_HEIGHT
    t = np.linspace(0.1, 0.9, SAMPLES)
    points = {}
    for k in range(digit_count):
        left = (k + (shifts[k] if shifts else 0.0)) * pitch + (1.0 - fill) * pitch / 2.0
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
def _sample_index(digit_count, width, slant_deg, fill, shifts=(), slack=0.0):
    """The sample points of _sample_points as (keys, flat pixel indices into a CELL_HEIGHT x width
    face, each line's first index, each line's count, each key's first line): one gather per model,
    not one per segment. The bars (SLACK_SEGMENTS) have SLACK_LINES lines, ``slack`` of the digits'
    height above and below their centre line (a bar's level is the brightest line's); every other
    key one."""
    keys, flat, starts, counts, groups = [], [], [], [], []
    offsets = np.linspace(-slack, slack, SLACK_LINES if slack else 1) * CELL_HEIGHT
    for key, (xs, ys) in _sample_points(digit_count, width, slant_deg, fill, shifts).items():
        keys.append(key)
        groups.append(len(starts))
        xi = np.clip(np.round(xs).astype(int), 0, width - 1)
        for offset in (offsets if key[1] in SLACK_SEGMENTS else [0.0]):
            yi = np.clip(np.round(ys + offset).astype(int), 0, CELL_HEIGHT - 1)
            starts.append(len(flat))
            counts.append(len(xi))
            flat.extend((yi * width + xi).tolist())
    return tuple(keys), np.array(flat), np.array(starts), np.array(counts, dtype=float), np.array(groups)


def _levels(face, model, slack=0.0):
    """{(cell, segment): mean grey level along it}, segments brighter when on (dark displays inverted);
    also each cell's "dp" (its decimal point) and "hole" (the face inside its loops). ``slack``: the
    bars' level is the brightest line within this share of the digits' height of their centre
    line (a reading: SEGMENT_SLACK); 0 for learning, which fits the centre lines."""
    face = face if model.polarity == "lit" else 255.0 - face
    keys, flat, starts, counts, groups = _sample_index(model.digit_count, face.shape[1], model.slant_deg, model.fill,
                                                       tuple(model.shifts), slack)
    lines = np.add.reduceat(face.ravel()[flat], starts) / counts
    return dict(zip(keys, np.maximum.reduceat(lines, groups).tolist()))


def _floor(levels, model):
    """Half the contrast that splits lit from dark segments in this picture: the calibrated
    contrast's half, or, on a display dimmer than at calibration (another exposure, a darker
    backlight), half the range its segments stand above their faces here, down to DIM_FLOOR of the
    calibrated contrast (a display off must not read its own noise)."""
    live = max(levels[(k, s)] - levels[(k, "hole")] for k in range(model.digit_count) for s in SEGMENTS)
    return 0.5 * min(model.contrast, max(live, DIM_FLOOR * model.contrast))


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


def _decode_cell(values, face_level, floor, split="gap"):
    """(code, margins, threshold, other) of one cell's segment levels ``values`` against the face
    inside its loops (``face_level``), split on from off by itself by two rules: at the widest gap
    ("gap": light falls unevenly on a display) and at ``floor`` (half the calibrated contrast) above
    the face ("face": the segments of one digit lit unevenly, an LCD's thin bars or an LED's dim
    corner, split inside the lit ones at the widest gap, a 7 with a faint bar reads as a 1). The
    calibrated rule (``split``) decides; when it gives no character and the other gives one, the
    other decides and a segment close to its split makes the cell doubtful (``other`` "?"); under
    "gap", ``other`` is the face rule's character when it is one and differs (the cell is then in
    doubt). A segment's margin: its distance from the split, 1 at either end of the cell's levels or
    half the floor from it (nothing lit: a blank, threshold None)."""
    gap_threshold, _gap = _split(values + [face_level], floor)
    if gap_threshold is None or not any(v > gap_threshold for v in values):
        return CODE[" "], [1.0] * len(SEGMENTS), None, None
    rules = {"gap": gap_threshold, "face": face_level + floor}
    codes = dict((rule, tuple(v > t for v in values)) for rule, t in rules.items())
    used = split
    if codes[split] not in DECODE or not any(codes[split]):
        alternative = "face" if split == "gap" else "gap"
        if codes[alternative] in DECODE and any(codes[alternative]):
            used = alternative
    code, threshold = codes[used], rules[used]
    if not any(code):
        return CODE[" "], [1.0] * len(SEGMENTS), None, None
    if used == "gap":
        margins = _margins(values, face_level, threshold)
    else:
        margins = [min(1.0, abs(v - threshold) / floor) for v in values]
    other = None
    if used != split:
        other = "?" if min(margins) < MIN_MARGIN else None
    elif split == "gap" and codes["face"] in DECODE and any(codes["face"]) and codes["face"] != code:
        other = DECODE[codes["face"]]
    return code, margins, threshold, other


def _margins(values, face_level, threshold):
    """Each segment's distance from the split, 0 at it and 1 at the median of its side."""
    on = [v for v in values if v > threshold]
    off = [v for v in values if v <= threshold] + [face_level]
    low, high = float(np.median(off)), float(np.median(on))
    return [min(1.0, abs((v - low) / (high - low) - 0.5) * 2.0) for v in values]


def _drawn(points, cells, codes, shape, stroke=STROKE):
    """A mask of ``shape`` (raveled, 0 or 1) with the lit segments of ``codes`` (one per cell) drawn
    along their centre lines (``points``, _sample_points) and a little past their ends, ``stroke``
    of the digits' height thick (a real segment's, by default)."""
    drawn = np.zeros(shape, np.uint8)
    thick = max(2, int(round(stroke * CELL_HEIGHT)))
    for k, code in zip(cells, codes):
        for s in (s for s, on in zip(SEGMENTS, code) if on):
            xs, ys = points[(k, s)]
            ends = [(xs[i] + 0.15 * (xs[i] - xs[j]), ys[i] + 0.15 * (ys[i] - ys[j])) for i, j in ((0, -1), (-1, 0))]
            cv2.line(drawn, tuple(int(round(v)) for v in ends[0]), tuple(int(round(v)) for v in ends[1]), 1, thick)
    return drawn.ravel().astype(np.float32)


def _registered(image, quad, model):
    """(face, levels) of the box with the cells' window moved and scaled to where the digits are: a
    box found in another picture (or on another unit of the same meter) sits off them, and a cell
    half on its neighbour's strokes reads a blank or no digit. A move is judged by the correlation
    of its window's picture with segments drawn: first every segment (an 8 in each cell: where the
    strokes can be, whatever they show) over a coarse grid of moves, then, about the best few and
    finer about the best of those, the segments the move's reading lights (a 7 read as a 1 leaves
    its bar unexplained, a pattern that is no digit explains nothing). The window as calibrated is
    kept unless a move wins clearly, and when nothing is lit in it (a display off is not searched
    for digits)."""
    grey_image = grey(image)
    left, top, right, bottom = model.window
    pitch, height = (right - left) / model.digit_count, bottom - top
    cells = range(model.digit_count)
    faces = {}

    def face_at(move):
        if move not in faces:
            dx, dy, scale = move
            centre_x, centre_y = (left + right) / 2.0 + dx * pitch, (top + bottom) / 2.0 + dy * height
            half_x, half_y = (right - left) * scale / 2.0, height * scale / 2.0
            window = (centre_x - half_x, centre_y - half_y, centre_x + half_x, centre_y + half_y)
            face = _face(grey_image, quad, model.digit_count, window)
            faces[move] = (face, (face if model.polarity == "lit" else 255.0 - face).ravel())
        return faces[move]

    face0 = face_at((0.0, 0.0, 1.0))[0]
    points = _sample_points(model.digit_count, face0.shape[1], model.slant_deg, model.fill, model.shifts)
    eights_face = _drawn(points, cells, [CODE["8"]] * model.digit_count, face0.shape).reshape(face0.shape)

    def cost(move):
        return REGISTER_COST * (abs(move[0]) + abs(move[1]) + abs(math.log(move[2])))

    def where(scale):
        """The best moves at one scale by the correlation of an 8 in every cell with the picture, at
        every shift at once (one picture with room around the window, matchTemplate): the best
        shift and the best one at least half a cell from it (the pattern repeats with the cells)."""
        reach_x, reach_y = REGISTER_SHIFT * pitch, REGISTER_LIFT * height
        half_x, half_y = (right - left) * scale / 2.0, height * scale / 2.0
        centre_x, centre_y = (left + right) / 2.0, (top + bottom) / 2.0
        px_x, px_y = face0.shape[1] / (2.0 * half_x), (CELL_HEIGHT - 1) / (2.0 * half_y)
        room = (centre_x - half_x - reach_x, centre_y - half_y - reach_y,
                centre_x + half_x + reach_x, centre_y + half_y + reach_y)
        size = (face0.shape[1] + 2 * int(round(reach_x * px_x)), CELL_HEIGHT + 2 * int(round(reach_y * px_y)))
        room_face = cv2.GaussianBlur(rectify(grey_image, sub_quad(quad, room), size[0], size[1]), (3, 3), 0)
        ink = (room_face if model.polarity == "lit" else 255 - room_face).astype(np.float32)
        scores = cv2.matchTemplate(ink, eights_face, cv2.TM_CCOEFF_NORMED)
        moves = []
        for _pick in range(2):
            row, col = np.unravel_index(int(np.argmax(scores)), scores.shape)
            if not np.isfinite(scores[row, col]) or scores[row, col] <= -1.0:
                break
            move = (round((col / px_x - reach_x) / pitch, 4), round((row / px_y - reach_y) / height, 4), scale)
            moves.append((float(scores[row, col]) - cost(move), move))
            scores[:, max(0, col - int(0.5 * pitch * px_x)):col + int(0.5 * pitch * px_x) + 1] = -2.0
        return moves

    def reads(move):
        """(correlation with what the move reads, None when nothing is lit; face; levels)."""
        face, ink = face_at(move)
        levels = _levels(face, model, SEGMENT_SLACK)
        floor = _floor(levels, model)
        codes = [_decode_cell([levels[(k, s)] for s in SEGMENTS], levels[(k, "hole")], floor, model.split)[0]
                 for k in cells]
        if not any(any(c) for c in codes):
            return None, face, levels
        drawn = _drawn(points, cells, [c if c in DECODE else CODE[" "] for c in codes], face.shape)
        fit = float(np.corrcoef(ink, drawn)[0, 1]) if drawn.any() else -1.0
        return fit - cost(move), face, levels

    def grid(centre, steps, counts):
        axes = [c + st * np.arange(-n, n + 1) for c, st, n in zip(centre, steps, counts)]
        return [(round(dx, 4), round(dy, 4), round(sc, 4)) for dx in axes[0] for dy in axes[1] for sc in axes[2]
                if abs(dx) <= REGISTER_SHIFT and abs(dy) <= REGISTER_LIFT
                and REGISTER_SCALE[0] <= sc <= REGISTER_SCALE[1]]

    def best(moves):
        return max((reads(move) + (move,) for move in moves), key=lambda r: -2.0 if r[0] is None else r[0])

    calibrated = reads((0.0, 0.0, 1.0))
    if calibrated[0] is None:   # nothing lit where the digits were: a display off or covered, not moved
        return calibrated[1], calibrated[2]
    scales = np.exp(np.linspace(math.log(REGISTER_SCALE[0]), math.log(REGISTER_SCALE[1]), REGISTER_STEPS))
    coarse = [move for _fit, move in sorted((m for scale in scales for m in where(round(float(scale), 4))),
                                            reverse=True)[:REGISTER_KEEP]]
    fine = best([move for centre in coarse for move in grid(centre, (0.04, 0.025, 0.025), (1, 1, 1))])
    fine = best(grid(fine[3], (0.015, 0.01, 0.01), (1, 1, 1)))
    if fine[0] is None or fine[0] < calibrated[0] + REGISTER_GAIN:   # the box is where calibration put it
        return calibrated[1], calibrated[2]
    return fine[1], fine[2]


def read_display(image, quad, model, register=True):
    """Reading of a display box under its calibrated DisplayModel: value, confidence (the weakest
    digit's), detail {"text", "digits": [{"char", "confidence", "candidates"}], "reason" when
    uncertain}. Each cell is split on from off by itself (light falls unevenly on a display), a
    cell whose face is far brighter than the others' is glare, not a blank. ReadFailed when no
    segment is lit anywhere (display off, covered) or no digit can be read at all. ``register``: move
    the cells to where the digits are (``_registered``); calibration reads its own fitted window."""
    if register:
        face, levels = _registered(image, quad, model)
    else:
        face = _face(image, quad, model.digit_count, model.window)
        levels = _levels(face, model, SEGMENT_SLACK)
    floor = _floor(levels, model)
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
        code, margins, threshold, other = _decode_cell(values, faces[k], floor, model.split)
        if threshold is None:   # nothing lit in this cell: a blank, unless a segment stands half out
            brightest = int(np.argmax(values))
            # a dim 1 must not vanish from a number's front; against the calibrated contrast, not the
            # dim picture's floor: an LCD's unlit segments show faintly, more so on a dim picture
            if values[brightest] - faces[k] > model.contrast / 4.0:
                doubts.append("digit %d: blank or lit (segment %s stands %.0f grey levels out)"
                              % (k + 1, SEGMENTS[brightest], values[brightest] - faces[k]))
                margins = [0.0] * len(SEGMENTS)
        else:
            lit_any = True
        char = DECODE.get(code)
        candidates = _candidates(code, margins)
        confidence = 100.0 * min(margins)
        if other is not None:   # split at the widest gap and above the face, the cell shows two digits
            candidates = [c for c in candidates if c != other][:1] + ([other] if other != "?" else [])
            margins = [0.0] * len(SEGMENTS)
        if char is None or other is not None or (len(candidates) > 1 and min(margins) < MIN_MARGIN):
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
    if "?" in stripped or "-" in stripped[1:] or not stripped.replace("-", ""):
        raise ReadFailed("display box unreadable: %s" % "; ".join(doubts))
    # a point seen elsewhere than calibrated (an auto-ranging meter, or a speck): the value as the
    # display shows it, and the reading uncertain above
    decimals = model.digit_count - 1 - dots[0] if len(dots) == 1 else model.decimals
    value = float(stripped.replace(" ", "0")) / 10 ** decimals
    confidence = min(d["confidence"] for d in digits)
    detail = {"text": with_point(text, decimals), "digits": digits}
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
