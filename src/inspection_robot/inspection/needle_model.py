"""This meter's needle: its look learned at calibration, found again by matching at read time.

Why: the line fit (needle.NeedleFinder) takes the strongest line through the pivot and decides by
rules which line and which end is the pointer; on a meter with a counterweight tail, a drag pointer
or a printed line it can take the wrong one and be sure of it. At calibration the operator shows the
meter with its value, so the needle is known there. Its look in polar coordinates about the
calibrated pivot is the model: each sample's Lab difference from the local face colour, rows the
radii, columns the angles across the needle, along its length (to the scale) and on the opposite
side (its counterweight tail, or the face where it has none). Reading slides the model over the
search angles and takes the best cosine match: a second opinion that fails differently from the
line fit (it knows this needle's colour, width, length and tail; the line fit knows none of them).

Stored as a PNG beside the calibration (the target's ``needle_reference``): the difference halved
and offset by 128 per channel, one row per radius.
"""
from collections import namedtuple

import numpy as np

from inspection_robot.lazy import lazy_import

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load

TIP_RADII = np.linspace(0.15, 0.95, 33)   # dial radii along the needle, up to the scale marks
TAIL_RADII = np.linspace(0.1, 0.5, 9)     # dial radii opposite: a counterweight, or plain face
HALF_WIDTH_DEG = 5.0      # the model's angles either side of the needle
# Lab's lightness differences run about twice its colour ones: weighted so a red pointer does not
# match a black one (a drag pointer beside the needle)
CHANNEL_WEIGHTS = np.array([1.0, 3.0, 3.0], np.float32)
GREY_CHROMA = 3.0         # a face whose colour differences stay under this (Lab a, b) is grey: infrared night
# A match under MIN_MATCH (cosine) does not recognise the needle; a second peak over RIVAL_MATCH of
# the best is a pointer the model cannot tell from its own. Chosen on the real set's tuning part.
MIN_MATCH = 0.5
RIVAL_MATCH = 0.9
DECISIVE_BELOW = 0.8      # a match whose best rival stays under this share of it knows which pointer is the needle
TRIM = 0.25

# ``angle``: deg clockwise from up about the calibrated pivot (None when nothing matched); ``score``:
# its cosine match; ``rival``: the best match at least 2 model widths away (0 when none) and its angle
ModelMatch = namedtuple("ModelMatch", "angle score rival rival_angle")


class NeedleModel(object):
    """A needle's polar look: ``template`` (columns, radii, 3) float32, TIP_RADII rows then TAIL_RADII."""

    ROWS = len(TIP_RADII) + len(TAIL_RADII)

    def __init__(self, template):
        self.template = np.asarray(template, np.float32)

    def encode(self):
        """PNG bytes (rows = radii, columns = angles)."""
        image = np.clip(np.round(self.template.transpose(1, 0, 2) / 2.0 + 128.0), 0, 255).astype(np.uint8)
        ok, data = cv2.imencode(".png", image)
        if not ok:
            raise ValueError("cannot encode the needle model")
        return data.tobytes()

    @classmethod
    def decode(cls, data, step_deg):
        """The model of PNG bytes, or None when they are not a needle model of ``step_deg`` sampling."""
        if not data:
            return None
        image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
        if image is None or image.shape[:2] != (cls.ROWS, columns(step_deg)):
            return None
        return cls((image.astype(np.float32).transpose(1, 0, 2) - 128.0) * 2.0)


def columns(step_deg):
    return 2 * int(round(HALF_WIDTH_DEG / step_deg)) + 1


def polar(finder, face, angles):
    """(angles, rows, 3): every sample's Lab difference from the local face colour along each
    angle's ray (TIP_RADII) and opposite it (TAIL_RADII); ``angles`` evenly spaced."""
    angles = np.asarray(angles, float)
    _, tip, tip_face = finder.samples(face.lab, face.centre, face.rad, angles, TIP_RADII)
    _, tail, tail_face = finder.samples(face.lab, face.centre, face.rad, angles + 180.0, TAIL_RADII)
    return np.concatenate([tip - tip_face, tail - tail_face], axis=1) * CHANNEL_WEIGHTS


def learn(finder, face, angle):
    """The model of the needle at ``angle`` on ``face`` (a finder's Face)."""
    half = columns(finder.step_deg) // 2
    return NeedleModel(polar(finder, face, angle + finder.step_deg * np.arange(-half, half + 1)))


def decisive(found):
    """True when the match tells its needle from every other pointer (ModelMatch)."""
    return found.rival < DECISIVE_BELOW * found.score


def is_grey(face):
    """True for a picture without colour (a camera's infrared night mode): only lightness is compared."""
    chroma = face.lab[:, :, 1:].astype(np.float32) - 128.0
    return float(np.percentile(np.abs(chroma), 99)) < GREY_CHROMA


def match(finder, face, model, angles):
    """Where on ``face`` the model matches best over the evenly spaced search ``angles`` (ModelMatch).

    Cosine similarity of the model and the face's polar samples under it, at every search angle;
    the peak refined by a parabola through its neighbours. On a grey picture (infrared) only the
    lightness channel is compared, the model's colour could not be there."""
    step = float(angles[1] - angles[0])
    half = model.template.shape[0] // 2
    padded = np.concatenate([angles[0] - step * np.arange(half, 0, -1), angles,
                             angles[-1] + step * np.arange(1, half + 1)])
    found = polar(finder, face, padded)
    template = model.template
    if is_grey(face):
        found, template = found[:, :, :1], template[:, :, :1]
    n = len(angles)
    score = _row_scores(found, template, n)
    if score is None:
        return ModelMatch(None, 0.0, 0.0, None)
    best = int(np.argmax(score))
    offset = 0.0
    if 0 < best < n - 1:
        a, b, c = score[best - 1], score[best], score[best + 1]
        curve = a - 2.0 * b + c
        offset = 0.5 * (a - c) / curve if curve < 0 else 0.0
    # the best other peak (a local maximum) at least two model widths away
    peaks = np.r_[False, (score[1:-1] >= score[:-2]) & (score[1:-1] >= score[2:]), False] if n > 2 \
        else np.zeros(n, bool)
    peaks &= np.abs(np.arange(n) - best) > 2 * (2 * half + 1)
    rival = int(np.argmax(np.where(peaks, score, -np.inf))) if peaks.any() else None
    rival_score = max(0.0, float(score[rival])) if rival is not None else 0.0
    return ModelMatch(float(angles[best] + offset * step) % 360.0, float(score[best]), rival_score,
                      float(angles[rival]) % 360.0 if rival is not None else None)


def _row_scores(found, template, n):
    """The match at each of ``n`` positions: per radius (row) the cosine of the model's row and the
    face's under it, averaged with the model rows' energy as weights after leaving out each
    position's worst TRIM of rows (a numeral or tick the needle lies on spoils a few radii, not the
    match); None for an empty model."""
    width = template.shape[0]
    dots = np.zeros((n, template.shape[1]))
    for k in range(width):
        dots += (found[k:k + n] * template[k][None]).sum(axis=2)
    energy = np.concatenate([np.zeros((1, found.shape[1])), np.cumsum((found.astype(np.float64) ** 2).sum(axis=2),
                                                                      axis=0)])
    window = energy[width:width + n] - energy[:n]
    rows = np.sqrt((template.astype(np.float64) ** 2).sum(axis=(0, 2)))
    if rows.sum() <= 0.0:
        return None
    cosine = dots / np.maximum(rows[None] * np.sqrt(np.maximum(window, 0.0)), 1e-9)
    keep = np.argsort(np.argsort(cosine, axis=1), axis=1) >= int(TRIM * len(rows))
    return (cosine * rows[None] * keep).sum(axis=1) / np.maximum((rows[None] * keep).sum(axis=1), 1e-9)
