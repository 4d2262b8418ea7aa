"""Readers for one target box: pointer gauge, indicator lamp, switch position, thermal maximum.

Every reader takes the picture and the target's quad (TL, TR, BR, BL in picture pixels),
rectifies the quad to a frontal square and returns a Reading(value, confidence 0..100, detail).
Confidence comes from measurable evidence (contrast of the needle against the face, agreement
of two independent estimates, margin between references), never a constant.
"""
import math
from collections import namedtuple

import cv2
import numpy as np

from inspection_robot.inspection.geometry import polygon_mask, rectify
from inspection_robot.inspection.gauge import angle_diff, wrap360

Reading = namedtuple("Reading", "value confidence detail")

GAUGE_SIZE = 256          # px side of the rectified gauge face
ANGLE_STEP_DEG = 0.5      # angular sampling of the polar profile
LAMP_SIZE = 64
SWITCH_SIZE = 64

# Lamp colours and their value codes in read_scale_ack.scale (0 = off).
LAMP_COLOURS = ("red", "green", "yellow", "blue", "white")
LAMP_CODES = dict((name, i + 1) for i, name in enumerate(LAMP_COLOURS))


def _clip_confidence(value):
    return float(min(max(value, 0.0), 100.0))


class PointerReader(object):
    """Finds the needle angle on a rectified gauge face by a radial dissimilarity profile.

    For every direction (0.5 deg steps) the face is sampled along the radius between
    ``inner`` and ``outer`` (fractions of the dial radius); each sample's distance from the
    local face colour (mean over nearby directions, in Lab) measures "needle-ness". The median along the
    radius rejects numbers and ticks (which cover only part of the radius); the peak's
    weighted centroid gives a sub-step angle. Inner and outer halves give two estimates whose
    agreement, together with the peak contrast, makes the confidence.
    """

    def __init__(self, size=GAUGE_SIZE, inner=0.22, outer=0.72, step_deg=ANGLE_STEP_DEG, background_deg=12.0):
        self.size = size
        self.background_deg = background_deg
        self.inner = inner
        self.outer = outer
        self.step_deg = step_deg
        self._angles = np.arange(0.0, 360.0, step_deg)
        self._radii = np.linspace(inner, outer, 48)

    def _profile(self, face_lab, centre, radius):
        theta = np.radians(self._angles)[:, None]
        r = (self._radii * radius)[None, :]
        # clockwise from 12 o'clock in image coordinates (y down)
        map_x = (centre[0] + r * np.sin(theta)).astype(np.float32)
        map_y = (centre[1] - r * np.cos(theta)).astype(np.float32)
        samples = cv2.remap(face_lab, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        samples = samples.astype(np.float32)
        # Deviation from the LOCAL face colour (circular mean over +-background_deg at the same
        # radius): smooth glare, shading and tinted light cancel, a narrow needle stands out.
        half = int(round(self.background_deg / self.step_deg))
        padded = np.concatenate([samples[-half:], samples, samples[:half]], axis=0)
        csum = np.cumsum(np.concatenate([np.zeros((1,) + samples.shape[1:], np.float32), padded]), axis=0)
        n = samples.shape[0]
        background = (csum[2 * half + 1:2 * half + 1 + n] - csum[:n]) / float(2 * half + 1)
        dist = np.sqrt(((samples - background) ** 2).sum(axis=2))  # angles x radii
        return dist

    def _peak(self, profile):
        n = len(profile)
        i = int(np.argmax(profile))
        half = max(2, int(round(4.0 / self.step_deg)))
        idx = np.arange(i - half, i + half + 1) % n
        window = profile[idx]
        base = float(np.median(profile))
        weights = np.clip(window - 0.5 * (base + profile[i]), 0.0, None)
        if weights.sum() <= 0:
            return self._angles[i], float(profile[i]), base
        offsets = (np.arange(-half, half + 1) * self.step_deg)
        centroid = float((weights * offsets).sum() / weights.sum())
        return wrap360(self._angles[i] + centroid), float(profile[i]), base

    def needle_angle(self, image, quad, centre=(0.5, 0.5), radius=0.45, aspect=1.0):
        """Needle angle (deg clockwise from up) in the face's frontal view, and a confidence.

        From the calibration: ``centre`` (pivot as fractions of the box width, height),
        ``radius`` (dial radius as a fraction of the box width) and ``aspect`` (physical
        width / height of the box, so the frontal view is not stretched).
        """
        aspect = float(aspect)
        width = self.size if aspect >= 1.0 else max(16, int(round(self.size * aspect)))
        height = max(16, int(round(width / aspect)))
        face = rectify(image, quad, width, height)
        if face.ndim == 2:
            face = cv2.cvtColor(face, cv2.COLOR_GRAY2BGR)
        face = cv2.GaussianBlur(face, (3, 3), 0)
        lab = cv2.cvtColor(face, cv2.COLOR_BGR2LAB)
        c = (centre[0] * (width - 1), centre[1] * (height - 1))
        rad = radius * (width - 1)
        dist = self._profile(lab, c, rad)
        k = dist.shape[1] // 2
        full = np.median(dist, axis=1)
        angle, peak, base = self._peak(full)
        inner_angle, _, _ = self._peak(np.median(dist[:, :k], axis=1))
        outer_angle, _, _ = self._peak(np.median(dist[:, k:], axis=1))
        spread = float(np.percentile(full, 90) - base) + 1.0
        contrast = (peak - base) / max(spread, 1.0)
        disagreement = abs(angle_diff(inner_angle, outer_angle))
        confidence = _clip_confidence(100.0 * min(1.0, contrast / 4.0) * math.exp(-disagreement / 3.0))
        detail = {"angle": angle, "inner_angle": inner_angle, "outer_angle": outer_angle,
                  "contrast": float(peak - base)}
        return angle, confidence, detail

    def read(self, image, quad, scale, centre=(0.5, 0.5), radius=0.45, aspect=1.0):
        angle, confidence, detail = self.needle_angle(image, quad, centre, radius, aspect)
        if not scale.in_sweep(angle, margin_deg=5.0):
            confidence *= 0.3  # the needle points into the dead zone: probably not the needle
        return Reading(scale.value(angle), _clip_confidence(confidence), detail)


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
    lamp of another colour keeps its own code at lower confidence.
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
    if not lit:
        return Reading(0.0, _clip_confidence(100.0 * min(1.0, -lit_score + 0.3)), detail)
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
    return Reading(float(LAMP_CODES[found]), _clip_confidence(confidence), detail)


def _edge_signature(gray):
    gray = cv2.GaussianBlur(gray, (3, 3), 0).astype(np.float32)
    gx = cv2.Sobel(gray, cv2.CV_32F, 1, 0)
    gy = cv2.Sobel(gray, cv2.CV_32F, 0, 1)
    mag = cv2.GaussianBlur(np.hypot(gx, gy), (5, 5), 0)
    mag -= mag.mean()
    norm = np.linalg.norm(mag)
    return mag / norm if norm > 0 else mag


def switch_patch(image, quad):
    """Rectified grey patch of a switch box, as stored for references."""
    patch = rectify(image, quad, SWITCH_SIZE)
    if patch.ndim == 3:
        patch = cv2.cvtColor(patch, cv2.COLOR_BGR2GRAY)
    return patch


def read_switch(image, quad, open_ref, closed_ref):
    """Switch position: value 1 closed, 0 open, by edge correlation with the two reference patches."""
    sig = _edge_signature(switch_patch(image, quad))
    score_open = float((sig * _edge_signature(_as_gray(open_ref))).sum())
    score_closed = float((sig * _edge_signature(_as_gray(closed_ref))).sum())
    margin = abs(score_closed - score_open)
    best = max(score_open, score_closed)
    confidence = 100.0 * min(1.0, margin / 0.3) * min(1.0, max(best, 0.0) / 0.5)
    value = 1.0 if score_closed > score_open else 0.0
    return Reading(value, _clip_confidence(confidence), {"open": score_open, "closed": score_closed})


def _as_gray(patch):
    patch = cv2.resize(np.asarray(patch), (SWITCH_SIZE, SWITCH_SIZE), interpolation=cv2.INTER_AREA)
    if patch.ndim == 3:
        patch = cv2.cvtColor(patch, cv2.COLOR_BGR2GRAY)
    return patch


def read_thermal_max(frame, quad):
    """Maximum temperature (deg C) of a radiometric frame inside the quad.

    Confidence falls with the share of the quad outside the frame and with non-finite pixels.
    """
    frame = np.asarray(frame, dtype=np.float32)
    mask = polygon_mask(frame.shape, quad) > 0
    if not mask.any():
        raise ValueError("thermal box covers no pixel of the frame")
    values = frame[mask]
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        raise ValueError("thermal box holds no valid temperature")
    area = abs(cv2.contourArea(np.asarray(quad, dtype=np.float32))) + 1.0
    inside = min(1.0, mask.sum() / area)
    confidence = 100.0 * inside * finite.size / float(values.size)
    return Reading(float(finite.max()), _clip_confidence(confidence), {"pixels": int(finite.size)})
