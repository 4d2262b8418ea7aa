"""Mechanical drum counters (an arrester's discharge counter, a tap changer's or breaker's operation
counter, a water meter's register): printed digits on wheels that roll up as the count rises.

Each wheel is seen through its window as a slice of a vertical strip "... 9 0 1 2 ... 9 0 ...": the
next digit comes up from below. Calibration (``learn_drum``) finds, from the picture and the value
the operator typed, the printed font (among stroke fonts drawn with OpenCV, several weights), the
digits' height in the box, and whether they are light on dark wheels
(``lit``) or dark on light ones. A reading (``read_drum``) slides each window over that strip
(normalised cross-correlation, OpenCV's matchTemplate) and takes the wheel's position: a wheel
between two digits is read as the lower one and the reading says so (the counter's own
convention), three quarters of the way the next digit is read; within DOUBT of that point the
reading is uncertain with both digits named, as it is when two positions match near-equally; a
wheel half-way while the wheel below it is not passing 9 to 0 cannot be, and is doubted too.

A stroke font is only like a meter's print: a water meter's 4 reads as the font's 2. So a reading
also takes the counter's own digits (``own_digits``), cut from its calibration picture where the
operator's value names them: a window near-identical to one of them, and clearly less like the
print of the digit the font reads, is that digit; one much like a printed digit but read as another
is doubted.

Pure image logic (OpenCV, NumPy); digital.py holds what drums share with seven-segment displays
(the typed value's parser, the point in the text).
"""
import math
from collections import namedtuple
from functools import lru_cache

import numpy as np

from inspection_robot.lazy import lazy_import
from inspection_robot.inspection.digital import with_point
from inspection_robot.inspection.geometry import grey, quad_size, rectify
from inspection_robot.inspection.readers import ReadFailed, Reading, clip_confidence

cv2 = lazy_import("cv2")

# (name, OpenCV stroke font, stroke weight as a share of the glyph height)
FONTS = tuple((name + weight_name, font, weight)
              for name, font in (("simplex", 0), ("duplex", 2), ("complex", 3), ("triplex", 4), ("plain", 1))
              for weight_name, weight in (("", 0.09), ("_bold", 0.15)))
FONT_NAMES = tuple(f[0] for f in FONTS)
GLYPH_PX = 32                # a digit's height in the strip and in a rectified window
GLYPHS = (0.4, 0.5, 0.6, 0.7, 0.8, 0.9)   # the digits' height as a share of the box's height
PITCHES = (1.2, 1.35, 1.5, 1.7, 2.0)       # digit to digit on a wheel, in digit heights
MIN_MATCH = 0.35             # a window matching no position better is no digit (covered, glare, blank)
MIN_LEAD = 0.06              # the best position must lead the best other digit by this much, else uncertain
ROLLED = 0.25                # a wheel more than this far past a digit, or short of the next, is between two
DOUBT = 0.1                  # within this of the point where the next digit is read, the wheel is doubtful
OWN_READ = 0.9               # a window this like one digit the counter showed at calibration, and OWN_LEAD
OWN_LEAD = 0.05              # less like the font's digit's print, seen too: the printed digit is read
OWN_DOUBT = 0.85             # this like a digit printed at calibration while the font reads another: uncertain

DrumModel = namedtuple("DrumModel", "digit_count polarity font glyph decimals contrast")


def drum_model(params):
    """The DrumModel of a drum counter's checked calibration parameters."""
    return DrumModel(int(params["digit_count"]), params["polarity"], params["font"], float(params["glyph"]),
                     int(params["decimals"]), float(params["contrast"]))


def _glyphs(font_name):
    """The ten digits of a font as float ink images, GLYPH_PX tall, one common width, centred."""
    _name, font, weight = FONTS[FONT_NAMES.index(font_name)]
    scale = GLYPH_PX / 22.0 * 1.6
    thick = max(1, int(round(weight * GLYPH_PX * 1.6)))
    canvases = []
    for digit in "0123456789":
        canvas = np.zeros((3 * GLYPH_PX, 3 * GLYPH_PX), np.uint8)
        cv2.putText(canvas, digit, (GLYPH_PX // 2, 2 * GLYPH_PX + GLYPH_PX // 2), font, scale, 255, thick,
                    cv2.LINE_AA)
        canvases.append(canvas)
    rows = np.where(np.max(canvases, axis=0).max(axis=1) > 0)[0]
    cols = [np.where(c.max(axis=0) > 0)[0] for c in canvases]
    width = max(c[-1] - c[0] + 1 for c in cols)
    out = []
    for canvas, c in zip(canvases, cols):
        glyph = np.zeros((rows[-1] - rows[0] + 1, width), np.float32)
        left = (width - (c[-1] - c[0] + 1)) // 2
        glyph[:, left:left + c[-1] - c[0] + 1] = canvas[rows[0]:rows[-1] + 1, c[0]:c[-1] + 1] / 255.0
        out.append(cv2.resize(glyph, (max(2, int(round(width * GLYPH_PX / glyph.shape[0]))), GLYPH_PX),
                              interpolation=cv2.INTER_AREA))
    return out


@lru_cache(maxsize=512)   # a node reads each preset's wheels at one width: bounded, not one per picture ever seen
def _strip(font_name, pitch, width):
    """The wheel's strip: digits 9, 0, 1, ..., 9, 0, 1 top to bottom, ``pitch`` digit heights apart,
    centred in ``width`` px; digit k's centre is at (k + 1.5) * pitch * GLYPH_PX (read-only: shared)."""
    glyphs = _glyphs(font_name)
    step = pitch * GLYPH_PX
    strip = np.zeros((int(math.ceil(13 * step)), width), np.float32)
    for k, digit in enumerate([9] + list(range(10)) + [0, 1]):
        glyph = glyphs[digit][:, :width]
        top = int(round((k + 0.5) * step - GLYPH_PX / 2.0))
        left = (width - glyph.shape[1]) // 2
        strip[top:top + GLYPH_PX, left:left + glyph.shape[1]] = glyph
    strip.setflags(write=False)
    return strip


def _windows(image, quad, digit_count, glyph):
    """Each wheel's window rectified so that a digit is GLYPH_PX tall: float grey levels."""
    height = int(round(GLYPH_PX / glyph))
    box_w, box_h = quad_size(quad)
    cell = max(4, int(round(height * box_w / max(box_h, 1e-6) / digit_count)))
    face = rectify(grey(image), quad, cell * digit_count, height).astype(np.float32)
    return [face[:, k * cell:(k + 1) * cell] for k in range(digit_count)]


def _bright(window, polarity):
    """The window with its digit's ink bright."""
    return window if polarity == "lit" else 255.0 - window


def _ink(window, polarity):
    """The window's digit as bright ink, with a margin left out either side (a digit need not sit
    in its window's middle): (ink, margin)."""
    ink = _bright(window, polarity)
    margin = max(2, ink.shape[1] // 6)
    return (ink[:, margin:-margin] if ink.shape[1] > 2 * margin + 4 else ink), margin


def _profile(ink, margin, font, pitch):
    """The ink's match along its wheel, digits ``pitch`` digit heights apart: (scores per position
    in digits, the positions, the best column per row, the strip)."""
    strip = _strip(font, pitch, ink.shape[1] + 2 * margin)
    if ink.shape[0] >= strip.shape[0] or float(ink.std()) < 1e-3:
        return np.full(1, -1.0), np.zeros(1), np.zeros(1, int), strip
    result = cv2.matchTemplate(strip, ink.astype(np.float32), cv2.TM_CCOEFF_NORMED)
    positions = (np.arange(result.shape[0]) + ink.shape[0] / 2.0) / (pitch * GLYPH_PX) - 1.5
    return result.max(axis=1), positions, result.argmax(axis=1), strip


def _wheel(window, model, pitches=PITCHES):
    """(position in 0..10, its match, the best other digit, its lead in match, its lead in what
    tells the two apart) of one wheel, over every pitch (at rest a window seldom shows its
    neighbours: the pitch is not learned; half-way it does).

    What tells them apart: the window's correlation with the difference of the two digits' strip
    slices at the best fit's offset (a 6 and an 8 match a window almost alike; only the stroke one
    has and the other lacks decides)."""
    ink, margin = _ink(window, model.polarity)
    best, fits = None, []
    for pitch in pitches:
        scores, positions, columns, strip = _profile(ink, margin, model.font, pitch)
        fits.append((scores, positions))
        k = int(np.argmax(scores))
        if best is None or scores[k] > best[0]:
            best = (float(scores[k]), float(positions[k]), int(k), int(columns[k]), pitch, strip)
    score, position, row, column, pitch, strip = best
    other, other_score = int(round(position)) % 10, -2.0
    for scores, positions in fits:
        apart = np.abs((positions - position + 5.0) % 10.0 - 5.0) > 0.6
        if apart.any():
            k = int(np.argmax(np.where(apart, scores, -2.0)))
            if scores[k] > other_score:
                other, other_score = int(round(float(positions[k]))) % 10, float(scores[k])
    lead = told = score - other_score
    shift = ((other - position + 5.0) % 10.0 - 5.0) * pitch * GLYPH_PX   # the runner-up's slice, same offset
    rows = int(round(row + shift))
    height, width = ink.shape
    if 0 <= rows <= strip.shape[0] - height:
        own, rival = strip[row:row + height, column:column + width], strip[rows:rows + height, column:column + width]
        difference, seen = (own - rival).ravel(), (ink - ink.mean()).ravel()
        norm = float(np.linalg.norm(difference) * np.linalg.norm(seen))
        if norm > 1e-6:
            told = max(lead, float(np.dot(difference, seen)) / norm)
    return position % 10.0, score, other, lead, told


def learn_drum(image, quad, cells, decimals):
    """The DrumModel under which the box shows the digits ``cells`` (digit_count characters, the
    text the operator typed, parsed by digital.parse_shown) and the picture reads back as them
    without doubt; ReadFailed when no font and digit size makes every wheel's best position the
    digit typed, or the reading back doubts or differs."""
    if any(not c.isdigit() for c in cells):
        raise ReadFailed("a drum counter shows a digit on every wheel: type them all (no blanks, no minus)")

    def fit(glyph, polarities, fonts, pitches=PITCHES):
        """The best (score, model) at one digit height; score -inf when none reads ``cells``."""
        found = (-np.inf, None)
        windows = _windows(image, quad, len(cells), glyph)
        for polarity in polarities:
            for font in fonts:
                model = DrumModel(len(cells), polarity, font, glyph, decimals, 0.0)
                wheels = [_wheel(w, model, pitches) for w in windows]
                if all(int(round(p)) % 10 == int(c) and abs(p - round(p)) < ROLLED
                       for (p, _s, _o, _l, _t), c in zip(wheels, cells)):
                    # every wheel's lead over its runner-up, and its own match
                    score = float(np.mean([w[3] for w in wheels]) + np.mean([w[1] for w in wheels]))
                    found = max(found, (score, model), key=lambda f: f[0])
        return found

    # at rest a wheel's neighbours seldom show: one pitch finds the size, polarity and font candidates
    coarse = sorted((fit(g, ("lit", "dark"), FONT_NAMES, (1.5,)) for g in GLYPHS), key=lambda f: -f[0])
    best_score, best = max((fit(m.glyph, (m.polarity,), (m.font,)) for _s, m in coarse[:2] if m is not None),
                           key=lambda f: f[0], default=(-np.inf, None))
    if best is not None:   # the digit height to a quarter of the coarse step, every font again
        for step in (0.05, 0.025):
            best_score, best = max([(best_score, best)] + [fit(best.glyph + d, (best.polarity,), FONT_NAMES)
                                                           for d in (-step, step)], key=lambda f: f[0])
    if best is None:
        raise ReadFailed("the picture does not show '%s' on drum wheels in the box (no printed font, digit size "
                         "reads every wheel as typed): draw the box tight around the windows and "
                         "type every wheel's digit" % "".join(cells))
    windows = _windows(image, quad, len(cells), best.glyph)
    contrast = float(np.median([np.percentile(w, 95) - np.percentile(w, 5) for w in windows]))
    best = best._replace(glyph=round(best.glyph, 3), contrast=round(contrast, 1))
    back = read_drum(image, quad, best)   # every wheel at its digit is not yet a reading without doubt
    typed = with_point("".join(cells), decimals)
    if back.detail["text"] != typed:
        raise ReadFailed("the learned counter reads '%s' on the calibration picture, not '%s'%s"
                         % (back.detail["text"], typed,
                            ": " + back.detail["reason"] if back.detail.get("reason") else ""))
    if back.detail.get("reason"):
        raise ReadFailed("the learned counter reads '%s' on the calibration picture only in doubt (%s): draw "
                         "the box tight around the windows, with every wheel's digit centred in them"
                         % (typed, back.detail["reason"]))
    return best


def _own_template(window, polarity):
    """A wheel's digit as the calibration picture shows it: its ink with a sixth of the height and a
    fifth of the width left out each side, so that it slides a little over a window read later."""
    ink = _bright(window, polarity)
    height, width = ink.shape
    return np.ascontiguousarray(ink[height // 6:height - height // 6, width // 5:width - width // 5], np.float32)


def own_digits(picture, quad, model):
    """The counter's own print: {digit: [templates]} cut from its calibration ``picture`` (its box
    ``quad``), each wheel's window at rest under the digit the picture reads under ``model``;
    calibration keeps only a model it reads back under as typed, without doubt, so these are the
    operator's digits. None when the picture reads in doubt or not at all (replaced since): the font
    alone reads then."""
    try:
        back = read_drum(picture, quad, model)
    except ReadFailed:
        return None
    if back.detail.get("reason"):
        return None
    own = {}
    for shown, window in zip(back.detail["digits"], _windows(picture, quad, model.digit_count, model.glyph)):
        if abs(shown["position"] - round(shown["position"])) < ROLLED:   # a wheel between two digits is no print
            own.setdefault(shown["char"], []).append(_own_template(window, model.polarity))
    return own


def _likeness(window, polarity, own):
    """{digit: how like its own print the window is (best normalised cross-correlation)}."""
    ink = _bright(window, polarity).astype(np.float32)
    likes = {}
    for digit, templates in own.items():
        scores = [float(cv2.matchTemplate(ink, t, cv2.TM_CCOEFF_NORMED).max()) for t in templates
                  if t.shape[0] <= ink.shape[0] and t.shape[1] <= ink.shape[1] and float(t.std()) > 1e-3]
        if scores:
            likes[digit] = max(scores)
    return likes


def _own_verdict(window, model, own, digit, font_rival):
    """What the counter's own print says of a wheel the font reads ``digit`` (``font_rival``: the
    font's near-equal runner-up, or None), as (verdict, digit, match):

    - "printed": another digit, the window being near-identical to its print and clearly less like the
      print of ``digit`` (two prints of one meter compared: a fair contest);
    - "doubt": much like another digit's print, ``digit``'s print unseen or not clearly better (two
      digits of one print can be 0.9 alike: an unseen digit is never overruled, only doubted);
    - "settled": near-identical to ``digit``'s print and clearly less like its rival's;
    - "": nothing to add."""
    likes = _likeness(window, model.polarity, own)
    if not likes:
        return "", digit, 0.0
    mine = max(likes, key=likes.get)
    if mine == str(digit):
        settles = (font_rival is not None and likes[mine] >= OWN_READ
                   and likes[mine] - likes.get(str(font_rival), -1.0) >= OWN_LEAD)
        return ("settled" if settles else ""), digit, likes[mine]
    if likes[mine] - likes.get(str(digit), -1.0) < OWN_LEAD:
        return "", digit, likes[mine]
    if str(digit) in likes and likes[mine] >= OWN_READ:
        return "printed", int(mine), likes[mine]
    if likes[mine] >= OWN_DOUBT:
        return "doubt", int(mine), likes[mine]
    return "", digit, likes[mine]


def read_drum(image, quad, model, own=None):
    """Reading of a drum counter's box: value, confidence (the weakest wheel's), detail {"text",
    "digits": [{"char", "position", "confidence", "candidates"}], "rolled" (the wheels between two
    digits, read as the lower), "own" (wheels the counter's own print read, ``own`` from own_digits),
    "reason" when uncertain}. ReadFailed when no wheel shows a digit."""
    windows = _windows(image, quad, model.digit_count, model.glyph)
    wheels = [_wheel(w, model) for w in windows]
    if all(w[1] < MIN_MATCH for w in wheels):
        raise ReadFailed("no drum wheel shows a digit in the box (best match %.2f, %.2f needed): counter covered, "
                         "dirty or the box off its windows" % (max(w[1] for w in wheels), MIN_MATCH))
    digits, doubts, rolled, notes = [], [], [], []
    for k, (position, score, other, _lead, lead) in enumerate(wheels):
        lower = int(math.floor(position + ROLLED)) % 10   # 3.9 shows 4; 3.5 is between 3 and 4: read 3
        between = abs(position - round(position)) >= ROLLED
        candidates = [str(lower)]
        confidence = 100.0 * min(1.0, max(0.0, lead / (2 * MIN_LEAD)))
        rival = other if score >= MIN_MATCH and lead < MIN_LEAD and other != lower else None
        verdict = ""
        if own and score >= MIN_MATCH and not between:
            verdict, printed, match = _own_verdict(windows[k], model, own, lower, rival)
            if verdict == "printed":
                notes.append("wheel %d read %d, as printed at calibration (match %.2f; the font read %d)"
                             % (k + 1, printed, match, lower))
                candidates, lower, rival, confidence = [str(printed), str(lower)], printed, None, 100.0
            elif verdict == "settled":
                rival, confidence = None, 100.0
            elif verdict == "doubt":
                candidates.append(str(printed))
                doubts.append("wheel %d: %d|%d (like the %d printed at calibration, match %.2f)"
                              % (k + 1, lower, printed, printed, match))
        if score < MIN_MATCH:
            doubts.append("wheel %d: no digit (match %.2f)" % (k + 1, score))
            confidence = 0.0
        elif rival is not None:
            candidates.append(str(rival))
            doubts.append("wheel %d: %s" % (k + 1, "|".join(candidates)))
        if between:
            rolled.append("wheel %d between %d and %d, read %d" % (k + 1, lower, (lower + 1) % 10, lower))
        past = (position + ROLLED) % 1.0   # 0 where the next digit is read from
        if min(past, 1.0 - past) < DOUBT and score >= MIN_MATCH and verdict != "printed":   # the font's position
            near = (lower + (1 if past > 0.5 else -1)) % 10
            candidates.append(str(near))
            doubts.append("wheel %d at %.2f: %d|%d" % (k + 1, position, lower, near))
        digits.append({"char": str(lower), "position": round(position, 2), "confidence": round(confidence, 1),
                       "candidates": candidates})
    for k in range(model.digit_count - 1):   # a wheel only turns while the one below passes 9 -> 0
        below = wheels[k + 1][0]
        if abs(wheels[k][0] - round(wheels[k][0])) >= ROLLED and not (below >= 8.5 or below < 0.5):
            doubts.append("wheel %d half-way while wheel %d shows %s" % (k + 1, k + 2, digits[k + 1]["char"]))
    text = "".join(d["char"] for d in digits)
    value = float(text) / 10 ** model.decimals
    confidence = min(d["confidence"] for d in digits)
    detail = {"text": with_point(text, model.decimals), "digits": digits}
    if rolled:
        detail["rolled"] = "; ".join(rolled)
    if notes:
        detail["own"] = "; ".join(notes)
    if doubts:
        detail["reason"] = "; ".join(doubts)
        confidence = min(confidence, 40.0)
    return Reading(value, clip_confidence(confidence), detail)


def render_drum(positions, width, height, font="duplex", polarity="lit", pitch=1.5, glyph=0.6,
                face=(25, 25, 25), ink=(235, 235, 235), frame=(90, 90, 90)):
    """A drum counter's windows showing wheel ``positions`` (3.5: half-way from 3 to 4), BGR
    ``width`` x ``height``: the simulated yard and tests draw their counters with it."""
    count = len(positions)
    cell = width // count
    window_h = int(round(GLYPH_PX / glyph))
    out = np.zeros((height, width, 3), np.uint8)
    out[:] = frame
    for k, position in enumerate(positions):
        strip = _strip(font, pitch, GLYPH_PX)
        centre = (position % 10.0 + 1.5) * pitch * GLYPH_PX
        top = int(round(centre - window_h / 2.0))
        ink_map = strip[top:top + window_h]
        colour = np.array(face, np.float32) + ink_map[..., None] * (np.array(ink, np.float32) - np.array(face))
        tile = cv2.resize(colour, (max(2, cell - 2 * max(1, cell // 10)), height - 2 * max(1, height // 10)),
                          interpolation=cv2.INTER_AREA)
        y0, x0 = (height - tile.shape[0]) // 2, k * cell + (cell - tile.shape[1]) // 2
        out[y0:y0 + tile.shape[0], x0:x0 + tile.shape[1]] = np.clip(tile, 0, 255).astype(np.uint8)
    return out if polarity == "lit" else 255 - out
