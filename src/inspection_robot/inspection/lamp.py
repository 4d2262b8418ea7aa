"""Indicator lamp reader: off, or the code of the lit colour."""
import math

import numpy as np

from inspection_robot.lazy import lazy_import
from inspection_robot.inspection.geometry import rectify
from inspection_robot.inspection.readers import Reading, clip_confidence

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load

LAMP_SIZE = 64
# a lamp's decision score runs from -1 (clearly dark) to 1 (clearly lit); within this of 0 (confidence
# under 50) the reading is uncertain. In 690 readings of simulated patrols every lamp scored 100.
LAMP_UNCLEAR = 0.2
# Lamp colours and their value codes in read_scale_ack.scale (0 = off).
LAMP_COLOURS = ("red", "green", "yellow", "blue", "white")
LAMP_CODES = dict((name, i + 1) for i, name in enumerate(LAMP_COLOURS))


def _lamp_colour(hue_deg, saturation):
    if saturation < 0.25:
        return "white"
    if hue_deg < 20 or hue_deg >= 330:
        return "red"
    if hue_deg < 70:
        return "yellow"
    if hue_deg < 170:
        return "green"
    if hue_deg < 270:
        return "blue"
    return "red"


def lamp_patch(image, quad):
    """Rectified colour patch of a lamp box, as stored for references."""
    return rectify(image, quad, LAMP_SIZE)


def _lamp_signature(patch, disc):
    """Disc colour relative to the brightest part of its surroundings (lighting gain cancels)."""
    patch = cv2.resize(np.asarray(patch), (LAMP_SIZE, LAMP_SIZE), interpolation=cv2.INTER_AREA)
    patch = patch.astype(np.float32) / 255.0
    yy, xx = np.mgrid[0:LAMP_SIZE, 0:LAMP_SIZE]
    rr = np.hypot(xx - (LAMP_SIZE - 1) / 2.0, yy - (LAMP_SIZE - 1) / 2.0) / LAMP_SIZE
    inner = rr < disc
    ring = (rr > disc + 0.06) & (rr < 0.5)
    value = patch.max(axis=2)
    surround = float(np.percentile(value[ring], 90)) + 0.02
    return np.median(patch[inner], axis=0) / surround, float(np.median(value[inner])), float(np.median(value[ring]))


def read_lamp(image, quad, colour=None, disc=0.35, references=None):
    """Indicator lamp: value 0 off, else the code of the lit colour (LAMP_CODES).

    With ``references`` (on patch, off patch: the same lamp lit and dark, from calibration) the
    lamp is lit when its disc colour, relative to the brightest part of its surroundings, is
    nearer the lit reference's; confidence from the margin. Without, it is lit when its disc is
    several times brighter than the housing ring around it and bright in absolute terms. The
    colour is the hue of the disc's brightest pixels; with the calibrated ``colour`` given, a lit
    lamp of another colour keeps its own code at lower confidence. Uncertain (``detail["reason"]``)
    when the decision is within LAMP_UNCLEAR of halfway (confidence under 50).
    """
    patch = rectify(image, quad, LAMP_SIZE).astype(np.float32) / 255.0
    yy, xx = np.mgrid[0:LAMP_SIZE, 0:LAMP_SIZE]
    rr = np.hypot(xx - (LAMP_SIZE - 1) / 2.0, yy - (LAMP_SIZE - 1) / 2.0) / LAMP_SIZE
    inner = rr < disc
    signature, disc_v, ring_v = _lamp_signature((patch * 255.0).astype(np.uint8), disc)
    detail = {"disc_v": disc_v, "ring_v": ring_v}
    if references is not None:
        d_on = float(np.linalg.norm(signature - _lamp_signature(references[0], disc)[0]))
        d_off = float(np.linalg.norm(signature - _lamp_signature(references[1], disc)[0]))
        detail.update({"d_on": d_on, "d_off": d_off})
        # +-1 at a clear decision (one distance 3x the other), 0 halfway between the references
        lit_score = min(max(math.log((d_off + 1e-3) / (d_on + 1e-3)) / math.log(3.0), -1.0), 1.0)
    else:
        # A lit lamp emits: its disc is several times brighter than its housing whatever the
        # ambient light, and bright in absolute terms.
        ratio = (disc_v + 0.02) / (ring_v + 0.02)
        lit_score = min(max(math.log(ratio / 3.0) / math.log(2.0), -1.0), 1.0)
        lit_score = min(lit_score, min(max((disc_v - 0.4) / 0.2, -1.0), 1.0))
    lit = lit_score > 0.0
    if abs(lit_score) < LAMP_UNCLEAR:
        detail["reason"] = "lamp unclear: %s" % ("halfway between its lit and its dark calibration picture"
                                                 if references is not None else
                                                 "its disc neither clearly lit nor clearly dark against its housing")
    if not lit:
        return Reading(0.0, clip_confidence(100.0 * min(1.0, -lit_score + 0.3)), detail)
    hsv = cv2.cvtColor((patch * 255).astype(np.uint8), cv2.COLOR_BGR2HSV_FULL).astype(np.float32)
    pix = hsv[inner]
    top = pix[pix[:, 2] >= np.percentile(pix[:, 2], 50)]
    # circular mean of hue (0..255 full circle)
    ang = top[:, 0] / 256.0 * 2 * math.pi
    weights = top[:, 1] + 1e-3
    hue = math.degrees(math.atan2((np.sin(ang) * weights).sum(), (np.cos(ang) * weights).sum())) % 360.0
    sat = float(np.median(top[:, 1]) / 255.0)
    found = _lamp_colour(hue, sat)
    detail.update({"hue": hue, "saturation": sat, "colour": found})
    confidence = 100.0 * min(1.0, lit_score + 0.3)
    if colour is not None and found != colour:
        confidence *= 0.5
    return Reading(float(LAMP_CODES[found]), clip_confidence(confidence), detail)
