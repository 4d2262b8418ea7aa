"""Seven-segment displays: the calibration that learns a display's model (``learn_display``) from
one picture of its box and the text the operator typed.

It tries both polarities, every slant, stroke span and window (the cells seldom fill an operator's
box exactly) for the models under which every segment the typed text needs lit is brighter than
every one it needs dark, and keeps the best one the picture reads back under as typed with no
digit's strokes left unexplained: evenly spaced cells split at the widest gap first, then each
cell moved to its own digit (``cell_shifts``), then the segments split above the face (``split``
"face": a display lit unevenly). It refuses with the reason when none reads back. Reading is
inspection.digital's.
"""
import numpy as np

from inspection_robot.lazy import lazy_import
from inspection_robot.inspection.digital import CELL_HEIGHT, CODE, MAX_CELL_SHIFT, DisplayModel, POLARITIES, \
    SEGMENTS, VARIANTS, _drawn, _face, _levels, _sample_points, parse_shown, read_display
from inspection_robot.inspection.geometry import grey, quad_size, rectify
from inspection_robot.inspection.readers import ReadFailed

cv2 = lazy_import("cv2")

SLANTS_DEG = tuple(range(-14, 15, 1))
FILLS = (0.55, 0.6, 0.65, 0.7, 0.75, 0.8, 0.85, 0.9)   # share of a digit's cell (its pitch) its strokes span
CELL_ASPECT = (0.3, 1.3)    # width / height of one digit's cell (its pitch) on real displays, with margin
MIN_CONTRAST = 12.0         # grey levels between on and off segments: less is no display to read
CELL_SHIFTS = tuple(np.round(np.arange(-MAX_CELL_SHIFT, MAX_CELL_SHIFT + 0.01, 0.05), 2))   # a cell's moves tried
MIN_CELL_GAP = 0.6            # cells (their pitch) between one cell's start and the next's, at least
STRAY_STROKE = 0.22           # share of the digits' height a segment explains strokes across
MAX_STRAY_INK = 0.08          # share of a digit's strokes a learned model may leave unexplained
SHIFTS = (-0.08, -0.04, 0.0, 0.04, 0.08)   # how far the cells may begin or end from the box's sides (its share)


def _ink_box(image, quad, polarity):
    """(left, top, right, bottom) fractions of the box its digits' strokes span: the pixels on the
    ink side of Otsu's split, in pieces that do not touch the box's edge (a bezel, a frame, the
    next reading) and lie among the tallest ones, or None when nothing is left."""
    q = np.asarray(quad, dtype=float).reshape(4, 2)
    aspect = np.linalg.norm(q[1] - q[0]) / max(np.linalg.norm(q[3] - q[0]), 1e-6)
    height = 4 * CELL_HEIGHT
    width = max(16, int(round(height * aspect)))
    face = cv2.GaussianBlur(rectify(grey(image), q, width, height), (5, 5), 0)
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

    def cell_fits(levels):
        """{cell: (gap, contrast)} of the cells with a lit segment: each digit is split by itself when
        read (light falls unevenly), so in every such cell the worst pair must separate; among the
        models where they do, the centre lines that sit on the strokes (the largest contrast) win."""
        out = {}
        for k in range(count):
            on = [levels[(k, s)] for s in SEGMENTS if want.get((k, s))]
            off = [levels[(k, s)] for s in SEGMENTS if want.get((k, s)) is False] + [levels[(k, "hole")]]
            if on:
                out[k] = (min(on) - max(off), np.mean(on) - np.mean(off))
        return out

    def scored(model, face):
        """(score, gap, model): the worst cell's gap plus the mean contrast."""
        fits = cell_fits(_levels(face, model))
        gap = min(g for g, _c in fits.values()) if fits else -np.inf
        return gap + (np.mean([c for _g, c in fits.values()]) if fits else 0.0), gap, model

    def fit(windows, polarities, fills, slants, keep=4):
        """The ``keep`` best (score, gap, model) over the windows, polarities, fills and slants, best first."""
        found = []
        for window in windows:
            face = _face(image, quad, count, window)
            for polarity in polarities:
                for fill in fills:
                    found += [scored(DisplayModel(count, polarity, float(slant), fill, decimals, 0.0, window), face)
                              for slant in slants]
                    found = sorted(found, key=lambda f: -f[0])[:keep]
        return found

    def shifted(model):
        """(score, gap, model) with each digit cell moved where its own digit fits best, within
        CELL_SHIFTS of even spacing (a blank cell as the nearest digit after it), cells kept apart."""
        face = _face(image, quad, count, model.window)
        per_shift = [(d, cell_fits(_levels(face, model._replace(shifts=(d,) * count)))) for d in CELL_SHIFTS]
        best = {}
        for k in range(count):
            tried = [(sum(fits[k]), d) for d, fits in per_shift if k in fits]
            if tried:
                best[k] = max(tried)[1]
        if not best:
            return scored(model, face)
        shifts = [best.get(k, best[min((j for j in best if j > k), default=max(best))]) for k in range(count)]
        if any(shifts[k + 1] + 1.0 - shifts[k] < MIN_CELL_GAP for k in range(count - 1)):
            return scored(model, face)
        return scored(model._replace(shifts=tuple(round(float(d), 3) for d in shifts)), face)

    # an operator's box is seldom tight or centred: the cells may start and end a little inside or
    # outside it, and the strokes found in it may place them (coarse slants first, then every one)
    windows = [(left, 0.0, right, 1.0) for left in SHIFTS for right in (1.0 + d for d in SHIFTS)]
    for polarity in POLARITIES:
        ink = _ink_box(image, quad, polarity) if cells.count(" ") < count else None
        if ink is not None:
            windows += [tuple(round(float(v), 4) for v in _window(ink, cells, fill)) for fill in FILLS]

    def refined(seeds):
        """The seeds' models polished: the sides to half the window grid's step, then the top and
        bottom, every fill and slant (coarse slants first)."""
        out = []
        for coarse in seeds:
            left, top, right, bottom = coarse.window
            step = (SHIFTS[1] - SHIFTS[0]) / 2.0
            sides = [(left + dl, top, right + dr, bottom) for dl in (-step, 0, step) for dr in (-step, 0, step)]
            _s, _g, fine = fit(sides, (coarse.polarity,), FILLS, SLANTS_DEG[::2], keep=1)[0]
            left, top, right, bottom = fine.window
            out += fit([(left, top + dt, right, bottom + db) for dt in SHIFTS[1:-1] for db in SHIFTS[1:-1]],
                       (coarse.polarity,), FILLS, SLANTS_DEG)
        # evenly spaced cells first, then each model with its cells moved to their digits
        out = sorted(out, key=lambda c: -c[0])
        return out + sorted((shifted(c[2]) for c in out), key=lambda c: -c[0])

    why = []

    def accepted(candidates):
        """The best model the picture reads back under as typed (a decimal point, a glare the score
        misses), without doubt and with no digit's strokes left unexplained; None (``why`` says).
        Each digit's segments split at the widest gap first, then at half the contrast above the face
        (a display whose segments are lit unevenly)."""
        for _score, gap, model in candidates + [c[:2] + (c[2]._replace(split="face"),) for c in candidates]:
            if gap < MIN_CONTRAST:
                continue
            model = model._replace(contrast=round(float(gap), 1))
            try:
                back = read_display(image, quad, model, register=False)
            except ReadFailed as err:
                why.append(str(err))
                continue
            stray = _unexplained_ink(_face(image, quad, count, model.window), model, cells)
            if stray > MAX_STRAY_INK:
                why.append("leaves %.0f %% of a digit's strokes unexplained" % (100.0 * stray))
                continue
            if not back.detail.get("reason") and abs(back.value - value) < 1e-9:
                return model
            why.append("reads '%s'%s" % (back.detail["text"], ": " + back.detail["reason"]
                                         if back.detail.get("reason") else ""))
        return None

    candidates = refined([c[2] for c in fit(windows, POLARITIES, FILLS, SLANTS_DEG[::4], keep=3)])
    model = accepted(candidates)
    if model is not None:
        return model
    best_gap = max(c[1] for c in candidates)
    if best_gap < MIN_CONTRAST:
        raise ReadFailed("the picture does not show '%s' in the box as seven segments (best contrast between the "
                         "segments that must be lit and those that must be dark: %.0f grey levels, %.0f needed): draw "
                         "the box tight around the digits and type exactly what the display shows"
                         % (shown, best_gap, MIN_CONTRAST))
    raise ReadFailed("no model learned from the picture reads it back as '%s' (the best %s): draw the box tight "
                     "around the digits and type exactly what the display shows" % (shown, why[0]))


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
    # the segments the typed text lights (a font's other form of a 7, 6 or 9 too), drawn a little
    # thicker than a real segment, and every gap's decimal point
    codes = [tuple(on or s == VARIANTS.get(ch) for s, on in zip(SEGMENTS, CODE[ch])) for ch in cells]
    points = _sample_points(model.digit_count, face.shape[1], model.slant_deg, model.fill, model.shifts)
    lit = (_drawn(points, range(model.digit_count), codes, mask.shape, STRAY_STROKE).reshape(mask.shape) > 0)
    lit = lit.astype(np.uint8) * 255
    thick = max(2, int(round(STRAY_STROKE * CELL_HEIGHT)))
    for k in range(model.digit_count):
        xs, ys = points[(k, "dp")]
        cv2.circle(lit, (int(round(xs[0])), int(round(ys[0]))), thick // 2, 255, -1)
    strokes, stray = mask > 0, (mask > 0) & (lit == 0)
    pitch = face.shape[1] / float(model.digit_count)
    shares = []
    for k in range(model.digit_count):   # the worst digit: a wrong one leaves whole segments over
        start = (k + (model.shifts[k] if model.shifts else 0.0)) * pitch
        cols = slice(max(0, int(round(start))), max(0, int(round(start + pitch))))
        ink_k = np.count_nonzero(strokes[:, cols])
        if ink_k >= 0.03 * strokes[:, cols].size:
            shares.append(np.count_nonzero(stray[:, cols]) / float(ink_k))
    return max(shares) if shares else 0.0
