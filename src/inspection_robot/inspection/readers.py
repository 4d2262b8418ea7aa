"""Readers for one target box: pointer gauge, indicator lamp, switch position, thermal maximum.

Every reader takes the picture and the target's quad (TL, TR, BR, BL in picture pixels),
rectifies the quad to a frontal square and returns a Reading(value, confidence 0..100, detail).
Confidence comes from measurable evidence (contrast of the needle against the face, agreement
of two independent estimates, margin between references), never a constant.
"""
import math
from collections import namedtuple

import numpy as np

from inspection_robot.lazy import lazy_import
from inspection_robot.inspection.geometry import polygon_mask, rectify
from inspection_robot.inspection.gauge import GaugeScale, angle_diff, wrap360

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load

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


class ReadFailed(ValueError):
    """The picture cannot give a reading at all (blank, overexposed, not the gauge); the message says why."""


# Pointer colour classes a calibration may name (pointer_colour: the current pointer; ignore_colour:
# a drag / max pointer or set-point needle to leave alone). "dark"/"light" are relative to the face.
POINTER_COLOURS = ("dark", "light", "red", "black", "white")
UNCERTAIN_BELOW = 50.0    # confidence under which a reading is reported "uncertain" with its reason


DialFrame = namedtuple("DialFrame", "quad centre radius aspect scale detail")


def dial_from_marks(quad, centre, radius, aspect, marks, min_marks=6, min_span_deg=180.0, max_residual=0.03,
                    min_axis_ratio=0.3, max_axis_ratio=0.85):
    """The frontal dial from the calibration's scale marks, without a hand-fitted outline.

    ``marks``: [(value, u, v)] the marks' positions as fractions of the box (``quad``, whose
    physical width / height is ``aspect``). The marks lie on a circle about the pivot in the dial's
    plane, so in an oblique picture on an ellipse: fitted (cv2.fitEllipse), its centre is the
    pivot's projection (for an arc centred on the pivot) and stretching its minor axis to its
    major one undoes the view's foreshortening (an affine view: a PTZ's narrow field of view). The
    result is a new box (a square about the fitted pivot, the same picture region straightened),
    pivot, dial radius, aspect 1 and a scale whose marks' angles are measured in that frontal frame.

    Returns None (keep the calibrated frame) when the fit is ill-conditioned: fewer than
    ``min_marks`` marks (5 fit any ellipse exactly), an arc shorter than ``min_span_deg`` (a short
    arc's ellipse is mostly noise), a residual above ``max_residual`` of the radius, an implausible
    ellipse (size or centre far from the calibrated one, axes ratio under ``min_axis_ratio``), and
    for a view nearly frontal (axes ratio above ``max_axis_ratio``, about 32 deg off axis), where
    hand-placed marks' noise would distort more than the view does (measured on the real set).
    Otherwise a DialFrame; its detail says what was fitted.
    """
    if marks is None or len(marks) < min_marks:
        return None
    aspect = float(aspect)
    values = [float(m[0]) for m in marks]
    pts = np.array([[float(m[1]), float(m[2]) / aspect] for m in marks])     # physical frame, box width 1
    (cx, cy), (d1, d2), tilt = cv2.fitEllipse(pts.astype(np.float32).reshape(-1, 1, 2))
    major, minor = 0.5 * max(d1, d2), 0.5 * min(d1, d2)
    calibrated = np.array([centre[0], centre[1] / aspect])
    if not (minor > 0 and minor / major >= min_axis_ratio and 0.4 * radius <= major <= 2.0 * radius
            and math.hypot(cx - calibrated[0], cy - calibrated[1]) <= 0.8 * major):
        return None
    # the affine stretching the ellipse's minor axis to its major one (no rotation: up stays up)
    # (of the two axes the one that maps the marks onto a circle is the minor one: robust to the
    # angle conventions of OpenCV versions)
    c = np.array([cx, cy])
    best = None
    for t in (math.radians(tilt), math.radians(tilt + 90.0)):
        u = np.array([math.cos(t), math.sin(t)])
        stretch_t = np.eye(2) + (major / minor - 1.0) * np.outer(u, u)
        q_t = (pts - c).dot(stretch_t.T)
        residual_t = float(np.sqrt(np.mean((np.hypot(q_t[:, 0], q_t[:, 1]) / major - 1.0) ** 2)))
        if best is None or residual_t < best[0]:
            best = (residual_t, stretch_t, q_t)
    residual, stretch, q = best
    angles = [wrap360(math.degrees(math.atan2(x, -y))) for x, y in q]
    offsets = sorted(wrap360(a - angles[0]) for a in angles)
    gaps = np.diff(offsets + [offsets[0] + 360.0])
    span = 360.0 - float(gaps.max())
    detail = {"axis_ratio": round(minor / major, 4), "residual": round(residual, 4), "span_deg": round(span, 1),
              "pivot_shift": round(math.hypot(cx - calibrated[0], cy - calibrated[1]) / major, 4)}
    if span < min_span_deg or residual > max_residual or minor / major > max_axis_ratio:
        return None
    try:
        scale = GaugeScale(angles[0], angles[-1], values[0], values[-1], list(zip(values, angles)))
    except ValueError:
        return None
    dial = min(max(float(radius), 0.9 * major), 1.4 * major)
    half = 1.15 * dial
    square = c + np.array([[-half, -half], [half, -half], [half, half], [-half, half]]).dot(np.linalg.inv(stretch).T)
    unit = np.float32([[0, 0], [1, 0], [1, 1], [0, 1]])
    to_image = cv2.getPerspectiveTransform(unit, np.asarray(quad, np.float32))
    box = square * np.array([1.0, aspect])
    new_quad = cv2.perspectiveTransform(box.reshape(-1, 1, 2), to_image).reshape(4, 2)
    return DialFrame(new_quad, (0.5, 0.5), dial / (2 * half), 1.0, scale, detail)


Hub = namedtuple("Hub", "x y radius score")


def find_hub(gray, centre, dial, reach=0.45, sizes=(0.035, 0.16), directions=48, count=4, min_score=0.3,
             shortlist=64):
    """Where the needle's pivot may be in a frontal face: compact round blobs (hub cap, screw, boss).

    ``gray``: the face (one channel); ``centre``: the calibrated pivot (px); ``dial``: the dial
    radius (px). Candidate centres lie within ``reach`` dial radii of the calibrated centre (on a
    grid of dial/40 px); hub radii span ``sizes`` dial radii (the lower bound is above a needle's
    half-width, whose two parallel edges would otherwise look like a tiny circle). A hub's rim is
    an edge all around it with one polarity (a dark cap on a light face, a bright screw on a dark
    cap): at ``directions`` points of each candidate circle the image gradient's component along
    the radius is taken with the circle's majority sign, and the score is the 25th percentile of
    it (three quarters of the rim must show an edge: the needle crossing the rim, or a numeral's
    strokes, cannot make one) over the 95th percentile of the gradient magnitude on the dial; it is
    computed for the ``shortlist`` circles of each radius with the strongest mean radial edge.
    Returns up to ``count`` Hubs (px, score; distinct, best first) scoring at least ``min_score``:
    candidates, which the reader confirms by reading the needle about them (a needle's round tip,
    a numeral or a screw can score too).
    """
    gray = cv2.GaussianBlur(np.asarray(gray, np.float32), (3, 3), 0)
    gx = cv2.Sobel(gray, cv2.CV_32F, 1, 0)
    gy = cv2.Sobel(gray, cv2.CV_32F, 0, 1)
    yy, xx = np.mgrid[0:gray.shape[0], 0:gray.shape[1]]
    on_dial = np.hypot(xx - centre[0], yy - centre[1]) <= dial
    magnitude = np.hypot(gx, gy)
    norm = float(np.percentile(magnitude[on_dial], 95)) if on_dial.any() else 0.0
    if norm <= 1e-6:
        return []
    step = max(1.0, dial / 40.0)
    grid = np.arange(-reach * dial, reach * dial + step, step)
    ox, oy = np.meshgrid(grid, grid)
    keep = np.hypot(ox, oy) <= reach * dial
    spots = np.stack([centre[0] + ox[keep], centre[1] + oy[keep]], axis=1)
    radii = np.arange(max(3.0, sizes[0] * dial), max(4.0, sizes[1] * dial) + 0.5, max(1.0, dial / 60.0))
    theta = np.linspace(0.0, 2.0 * math.pi, directions, endpoint=False)
    cos, sin = np.cos(theta), np.sin(theta)

    def rims(spots, radii, shortlist):
        """Each spot's best rim score over ``radii`` and that radius."""
        scores = np.full(len(spots), -np.inf)
        sizes_px = np.zeros(len(spots))
        for r in radii:
            # one remap per hub radius: rows the candidate centres, columns the rim's directions
            map_x = (spots[:, 0:1] + r * cos[None]).astype(np.float32)
            map_y = (spots[:, 1:2] + r * sin[None]).astype(np.float32)
            rx = cv2.remap(gx, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
            ry = cv2.remap(gy, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
            radial = rx * cos[None] + ry * sin[None]
            mean = radial.mean(axis=1)
            # the rim's percentile only for the circles with the strongest mean radial edge (a
            # hub's is among them; the percentile over every candidate costs ten times as much)
            top = np.argsort(-np.abs(mean))[:shortlist]
            edge = radial[top] * np.where(mean[top] >= 0.0, 1.0, -1.0)[:, None]
            score = np.partition(edge, directions // 4, axis=1)[:, directions // 4] / norm
            better = score > scores[top]
            scores[top[better]], sizes_px[top[better]] = score[better], r
        return scores, sizes_px

    scores, sizes_px = rims(spots, radii, shortlist)
    hubs = []
    for j in np.argsort(-scores):
        if len(hubs) >= count or not np.isfinite(scores[j]) or scores[j] < min_score:
            break
        if all(math.hypot(spots[j, 0] - h.x, spots[j, 1] - h.y) > h.radius + sizes_px[j] for h in hubs):
            # refined on a half-pixel grid about the coarse spot
            fine = np.arange(-step, step + 0.25, 0.5)
            fx, fy = np.meshgrid(fine, fine)
            near = np.stack([spots[j, 0] + fx.ravel(), spots[j, 1] + fy.ravel()], axis=1)
            sizes_near = np.arange(max(3.0, sizes_px[j] - step), sizes_px[j] + step + 0.25, 0.5)
            fine_scores, fine_sizes = rims(near, sizes_near, len(near))
            k = int(np.argmax(fine_scores))
            hubs.append(Hub(float(near[k, 0]), float(near[k, 1]), float(fine_sizes[k]), float(fine_scores[k])))
    return hubs


def scale_about(scale, centre, pivot, ring, marks=None):
    """The calibrated scale re-measured about a pivot seen off the calibrated centre.

    The calibration measured its marks' angles about ``centre`` (px); the marks lie where those
    directions meet the scale's arc, an arc about the real ``pivot`` (px). Its radius is not in the
    calibration: the arc about the pivot through the calibrated scale circle (radius ``ring``
    about the centre) at the marks' directions, on average. Each mark's direction from the centre
    meets that arc at the mark; its angle about the pivot is the new scale's (a linear scale stays
    linear about its pivot, where the needle turns). Returns (GaugeScale, arc radius) or None when
    the geometry does not hold (the centre outside the arc, the marks out of order).

    With the marks' positions (``marks`` [(value, x, y)] px, the calibration's ``marks``) their
    own angles about the pivot make the scale and their distance its arc (no assumption needed).
    """
    if marks and len(marks) >= 2:
        angles = [wrap360(math.degrees(math.atan2(x - pivot[0], -(y - pivot[1])))) for _, x, y in marks]
        try:
            about = GaugeScale(angles[0], angles[-1], marks[0][0], marks[-1][0],
                               list(zip([m[0] for m in marks], angles)) if len(marks) > 2 else None)
            if abs(about.sweep - scale.sweep) <= 90.0:
                return about, float(np.median([math.hypot(x - pivot[0], y - pivot[1]) for _, x, y in marks]))
        except ValueError:
            pass
    entries = scale.entries()
    centre, pivot = np.asarray(centre, float), np.asarray(pivot, float)
    dirs = [np.array([math.sin(math.radians(a)), -math.cos(math.radians(a))]) for _, a in entries]
    arc = float(np.mean([np.linalg.norm(centre + ring * d - pivot) for d in dirs]))
    q = centre - pivot
    if float(np.dot(q, q)) >= arc * arc:
        return None
    table = []
    for (value, _), d in zip(entries, dirs):
        b = float(np.dot(q, d))
        t = -b + math.sqrt(b * b - (float(np.dot(q, q)) - arc * arc))
        x, y = q + t * d
        table.append((value, wrap360(math.degrees(math.atan2(x, -y)))))
    try:
        about = GaugeScale(table[0][1], table[-1][1], table[0][0], table[-1][0], table if len(table) > 2 else None)
    except ValueError:
        return None
    if abs(about.sweep - scale.sweep) > 90.0:     # the order of the marks flipped: not this pivot
        return None
    return about, arc


def _pivot_offset(pivot, centre, aspect):
    """Distance between two points given as fractions of the box, in box widths (the dial radius' unit)."""
    return math.hypot(pivot[0] - centre[0], (pivot[1] - centre[1]) / float(aspect))


# Where PointerReader searches a needle: rays from ``hub`` over ``angles`` with the dial radius ``rad``
# (px), read where the needle's line meets the circle ``read_radius`` about ``read_about`` on
# ``scale``; ``about_hub``: both about a hub seen off the calibrated centre.
_View = namedtuple("_View", "hub rad angles read_about read_radius scale about_hub")
# The radial profiles along a _View's rays (PointerReader._profile), their median over the radius
# (``full``, its median ``base``), the pointer candidates and each ray's distance from the dial's colour.
_NeedleProfile = namedtuple("_NeedleProfile",
                            "angles dist samples background reach_dist full base candidates off_dial")


class PointerReader(object):
    """Finds the needle on a rectified gauge face by a radial dissimilarity profile and a line fit.

    For every direction (0.5 deg steps) within the scale's sweep plus ``margin_deg`` the face is
    sampled along the radius between ``inner`` and ``outer`` (fractions of the dial radius) from
    the calibrated pivot; each sample's distance from the local face colour (mean over nearby
    directions, in Lab) measures "needle-ness". The median along the radius rejects numbers and
    ticks (which cover only part of the radius). Every local maximum is a pointer candidate; it
    is ranked by its strength, its coverage of the radius and its reach towards the scale (a
    pointer's tip reaches the ticks, its counterweight does not). With a colour hint from the
    calibration the hinted pointer wins; otherwise a second candidate nearly as strong makes the
    reading uncertain ("two pointers").

    The pivot is not trusted: the chosen pointer's centre line is fitted to the needle's own
    pixels (the angular centroid at each radius; for a coloured needle only samples of its hue, so
    a white number beside a red needle does not pull the line), so a pivot off the calibrated centre (a
    temperature indicator, a calibration that marked the dial's centre) still gives the needle's
    real line; the reading is where that line meets the scale circle (0.9 of the dial radius about
    the calibrated centre). Lines fitted to the inner and outer halves give the agreement that,
    with the needle's contrast, makes the confidence.

    A needle whose inner part is hidden (a plate or an inner arc over the hub, as on SF6 density
    meters) or whose pivot lies below the visible window (panel meters) shows only near the
    scale: when the reading in the inner band is uncertain, the same search runs again in the
    outer band ``outer_band`` (fractions of the dial radius), whose reading replaces it only when
    it is confident itself (detail["band"] says which band read).

    With the scale marks' positions from the calibration (``read(marks=...)``) an oblique dial is
    read in the frontal frame their fitted ellipse gives (dial_from_marks; detail["frame"]).

    A pivot off the calibrated centre (the operator clicked the dial's centre of a temperature
    indicator): when the needle's line misses the calibrated centre by more than ``hub_search``
    dial radii, the hub is looked for in the picture (find_hub) and, confirmed by the needle read
    about it (_about_hub), the needle is read on the scale re-measured about it (scale_about);
    without a confirmed hub, a line missing the centre by more than ``hub_unsure`` makes the
    reading uncertain ("pivot not found"). ``find_hubs`` False reads without it.
    """

    def __init__(self, size=GAUGE_SIZE, inner=0.22, outer=0.72, step_deg=ANGLE_STEP_DEG, background_deg=12.0,
                 margin_deg=8.0, reach=(0.72, 0.9), uncertain_below=UNCERTAIN_BELOW, outer_band=(0.6, 0.95),
                 hub_steps=2, hub_move=0.06, hub_axis=(0.1, 0.2, 0.3, 0.4),
                 hub_axis_confidence=75.0, find_hubs=True, hub_search=0.1, hub_unsure=0.12):
        self.size = size
        self.hub_search = hub_search
        self.hub_unsure = hub_unsure
        self.find_hubs = find_hubs
        self.hub_axis_confidence = hub_axis_confidence
        self.hub_axis = hub_axis
        self.hub_steps = hub_steps
        self.hub_move = hub_move
        self._outer_reader = None
        if outer_band:
            self._outer_reader = PointerReader(size, outer_band[0], outer_band[1], step_deg, background_deg,
                                               margin_deg, (outer_band[1] - 0.05, outer_band[1] + 0.05),
                                               uncertain_below, outer_band=None, hub_steps=0, find_hubs=False)
        self.background_deg = background_deg
        self.inner = inner
        self.outer = outer
        self.step_deg = step_deg
        self.margin_deg = margin_deg
        self.uncertain_below = uncertain_below
        self._radii = np.linspace(inner, outer, 48)
        self._reach_radii = np.linspace(reach[0], reach[1], 12)

    def _profile(self, face_lab, centre, radius, angles, radii):
        """Distance of every sample from the LOCAL face colour (mean over +-background_deg at the same
        radius): smooth glare, shading and tinted light cancel, a narrow needle stands out.
        Returns (dist angles x radii, samples, background); ``angles`` must be evenly spaced."""
        half = int(round(self.background_deg / self.step_deg))
        step = angles[1] - angles[0]
        padded = np.concatenate([angles[0] - step * np.arange(half, 0, -1), angles,
                                 angles[-1] + step * np.arange(1, half + 1)])
        theta = np.radians(padded)[:, None]
        r = (radii * radius)[None, :]
        # clockwise from 12 o'clock in image coordinates (y down)
        map_x = (centre[0] + r * np.sin(theta)).astype(np.float32)
        map_y = (centre[1] - r * np.cos(theta)).astype(np.float32)
        samples = cv2.remap(face_lab, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        samples = samples.astype(np.float32)
        csum = np.cumsum(np.concatenate([np.zeros((1,) + samples.shape[1:], np.float32), samples]), axis=0)
        n = len(angles)
        background = (csum[2 * half + 1:2 * half + 1 + n] - csum[:n]) / float(2 * half + 1)
        core = samples[half:half + n]
        return np.sqrt(((core - background) ** 2).sum(axis=2)), core, background

    def _search_angles(self, scale, centre=None, hub=None, ring=None):
        """Directions (deg clockwise from up) that cover the scale's sweep plus margin_deg, seen from
        ``hub``: the sweep's ends are the points of the ring (radius ``ring`` about the calibrated
        ``centre``) at the scale's end angles. All around without a scale."""
        if scale is None:
            return np.arange(0.0, 360.0, self.step_deg)
        start, sweep = scale.start_angle, scale.sweep
        if hub is not None and sweep < 300.0 and (hub[0] != centre[0] or hub[1] != centre[1]):
            ends = []
            for a in (scale.start_angle, scale.end_angle):
                x = centre[0] + ring * math.sin(math.radians(a)) - hub[0]
                y = centre[1] - ring * math.cos(math.radians(a)) - hub[1]
                ends.append(math.degrees(math.atan2(x, -y)))
            start, sweep = wrap360(ends[0]), wrap360(ends[1] - ends[0])
        span = min(360.0, sweep + 2 * self.margin_deg)
        start = start - (span - sweep) / 2.0
        return start + np.arange(0.0, span, self.step_deg)

    def _candidates(self, full, angles):
        """Local maxima of the profile, strongest first: [(index, height above the median)]."""
        base = float(np.median(full))
        sep = max(1, int(round(6.0 / self.step_deg)))
        order = np.argsort(-full)
        taken = []
        for i in order[:400]:
            if full[i] - base <= 0:
                break
            if all(abs(int(i) - j) > sep for j, _ in taken):
                taken.append((int(i), float(full[i] - base)))
            if len(taken) >= 4:
                break
        return taken, base

    def _line(self, dist, angles, i, centre, radius, lo, hi, like=None):
        """The needle's centre line near direction index ``i`` from the samples of radii ``lo:hi``:
        the angular centroid of the needle at each radius gives a point; a weighted least-squares
        line through them. ``like`` (angles x radii, 0..1): how much each sample has the needle's
        own colour; it scales the weights, so a number or tick of another colour beside the needle
        does not pull the centroid. Returns (point on the line, unit direction outwards) or None."""
        half = max(2, int(round(6.0 / self.step_deg)))
        idx = np.arange(max(0, i - half), min(len(angles), i + half + 1))
        points, weights = [], []
        for k in range(lo, hi):
            column = dist[idx, k] if like is None else dist[idx, k] * like[idx, k]
            w = np.clip(column - 0.5 * (column.max() + np.median(dist[:, k])), 0.0, None)
            if w.sum() <= 0:
                continue
            theta = math.radians(float((w * angles[idx]).sum() / w.sum()))
            r = self._radii[k] * radius
            points.append((centre[0] + r * math.sin(theta), centre[1] - r * math.cos(theta)))
            weights.append(float(w.sum()))
        if len(points) < 4:
            return None
        pts, w = np.array(points), np.array(weights)
        mean = (pts * w[:, None]).sum(axis=0) / w.sum()
        d = pts - mean
        cov = (d * w[:, None]).T.dot(d)
        _, vectors = np.linalg.eigh(cov)
        u = vectors[:, -1]
        if np.dot(u, pts[-1] - pts[0]) < 0:
            u = -u
        return mean, u

    @staticmethod
    def _needle_likeness(dist, samples, background, full, base, i, min_chroma=15.0):
        """How much every sample has the hue of a coloured needle at direction index ``i`` (angles
        x radii, 0..1), or None for a needle of the face's own hue (black on white: the numbers
        and ticks share its ink, colour cannot tell them apart). Only the chroma (Lab a, b) counts,
        so glare or shade along the needle do not matter: 1 at the needle's median chroma, falling
        linearly to 0 at the face's. A half-covered pixel at the needle's edge scores about its
        coverage on both edges alike (no bias); a white number beside a red needle scores near 0."""
        strong = dist[i] > 0.5 * (full[i] + base)
        if not strong.any():
            return None
        needle = np.median(samples[i][strong][:, 1:], axis=0)
        chroma = float(np.sqrt(((needle - np.median(background[i][:, 1:], axis=0)) ** 2).sum()))
        if chroma < min_chroma:
            return None
        apart = np.sqrt(((samples[:, :, 1:] - needle[None, None]) ** 2).sum(axis=2))
        return np.clip(1.0 - apart / chroma, 0.0, 1.0)

    @staticmethod
    def _meets_circle(line, centre, r):
        """Angle (deg clockwise from up, about ``centre``) where the line leaves the circle of radius r."""
        p, u = line
        q = p - np.asarray(centre)
        b = float(np.dot(q, u))
        disc = b * b - (float(np.dot(q, q)) - r * r)
        t = -b + math.sqrt(max(disc, 0.0))
        x, y = q + t * u
        return wrap360(math.degrees(math.atan2(x, -y)))

    @staticmethod
    def _colour_class(needle_lab, face_lab):
        """red | dark | light for a candidate's median colour against the local face colour."""
        if needle_lab[1] - 128.0 > 20.0 and needle_lab[1] - face_lab[1] > 15.0:
            return "red"
        return "dark" if needle_lab[0] < face_lab[0] else "light"

    @staticmethod
    def _matches(colour, hint):
        hint = {"black": "dark", "white": "light"}.get(hint, hint)
        return colour == hint

    @staticmethod
    def check_face(face):
        """Raise ReadFailed for a picture that cannot hold a reading: blank, over- or underexposed."""
        gray = face if face.ndim == 2 else cv2.cvtColor(face, cv2.COLOR_BGR2GRAY)
        if float((gray >= 250).mean()) > 0.95:   # a saturated dial with a visible needle still reads
            raise ReadFailed("overexposed picture in the box")
        if float((gray <= 5).mean()) > 0.95:
            raise ReadFailed("underexposed picture in the box")
        if float(gray.std()) < 4.0:
            raise ReadFailed("blank picture in the box (no contrast)")

    def _face_geometry(self, centre, radius, aspect):
        """The rectified face's size (px), the dial radius (px) and the calibrated centre (px)."""
        aspect = float(aspect)
        width = self.size if aspect >= 1.0 else max(16, int(round(self.size * aspect)))
        height = max(16, int(round(width / aspect)))
        rad = radius * (width - 1)
        return width, height, rad, (centre[0] * (width - 1), centre[1] * (height - 1))

    def needle_angle(self, image, quad, centre=(0.5, 0.5), radius=0.45, aspect=1.0, scale=None,
                     pointer_colour="", ignore_colour="", hub=None, look_for_hub=False, about_hub=False,
                     marks=None):
        """Needle angle (deg clockwise from up, about the calibrated centre) in the face's frontal
        view, a confidence and a detail dict (``reason``: why the confidence is low, "" when it is not).

        From the calibration: ``centre`` (pivot as fractions of the box width, height), ``radius``
        (dial radius as a fraction of the box width), ``aspect`` (physical width / height of the
        box, so the frontal view is not stretched), ``scale`` (the search covers its sweep plus
        margin_deg; None: all around), colour hints. ``hub`` (face fractions): search along rays
        from it instead of the centre; with ``about_hub`` the angle is about the hub, measured on
        the scale re-measured about it (scale_about, from ``marks`` when given), which the detail
        carries (``scale_about_hub``). ``look_for_hub``: when the line misses the centre by more
        than ``hub_search``, detail["hub_candidates"] are find_hub's candidates.
        """
        width, height, rad, c = self._face_geometry(centre, radius, aspect)
        face, lab = self._face_lab(image, quad, width, height)
        view = self._view(c, rad, width, height, scale, hub, about_hub, marks)
        if view is None:
            return None, 0.0, {"reason": "the calibrated scale does not fit an arc about the hub seen",
                               "angle": None}
        prof = self._needle_profile(lab, view)
        detail = {"candidates": len(prof.candidates)}
        if not prof.candidates:
            detail.update(reason="needle not found", angle=None)
            return None, 0.0, detail
        described = self._describe(prof)
        pool = self._ranked(described, pointer_colour, ignore_colour)
        chosen = pool[0]
        i = self._needle_index(prof, chosen["index"])
        lines = self._needle_lines(prof, view, i)
        if lines is None:
            detail.update(reason="needle not found (no continuous needle along the radius)", angle=None)
            return None, 0.0, detail
        # where the needle's line meets the scale circle: near the tip, so the line's direction
        # error (a tapered or shadowed needle) hardly matters, and a pivot off the calibrated
        # centre moves the reading only by the parallax at the scale, not by a ray's full error
        angle, inner_angle, outer_angle = (self._meets_circle(line, view.read_about, view.read_radius)
                                           for line in lines)
        foot = self._pivot_detail(detail, lab, c, view, lines, look_for_hub)
        contrast, disagreement, confidence = self._confidence(prof, i, inner_angle, outer_angle)
        reason = self._rival_reason(prof, described, pool, i, bool(pointer_colour or ignore_colour))
        if reason:
            confidence = min(confidence, self.uncertain_below * 0.8)
        detail["pointers"] = [(round(float(prof.angles[d["index"]]) % 360.0, 1), round(d["score"], 1), d["reach"],
                               d["colour"]) for d in described]
        detail["needle_width"] = self._needle_width(prof, i, view.rad) / view.rad
        detail.update({"angle": angle, "inner_angle": inner_angle, "outer_angle": outer_angle,
                       "contrast": float(prof.full[i] - prof.base), "contrast_ratio": float(contrast),
                       "disagreement": disagreement, "colour": chosen["colour"], "reach": chosen["reach"],
                       "pivot": (float(foot[0]) / (width - 1), float(foot[1]) / (height - 1))})
        if confidence < self.uncertain_below and not reason:
            reason = self._weak_reason(face, contrast, disagreement)
        detail["reason"] = reason
        return angle, _clip_confidence(confidence), detail

    def _face_lab(self, image, quad, width, height):
        """The rectified face (BGR, slightly blurred) and its Lab image; ReadFailed for a blank one."""
        face = rectify(image, quad, width, height)
        if face.ndim == 2:
            face = cv2.cvtColor(face, cv2.COLOR_GRAY2BGR)
        self.check_face(face)
        face = cv2.GaussianBlur(face, (3, 3), 0)
        return face, cv2.cvtColor(face, cv2.COLOR_BGR2LAB)

    def _view(self, c, rad, width, height, scale, hub, about_hub, marks):
        """Where the needle is searched and read (_View), or None when the scale does not fit an arc
        about the hub. The needle is searched along rays from ``hub`` (the calibrated centre unless
        given) and read where its line meets the scale circle about the calibrated centre."""
        ring = rad * self._reach_radii[-1]
        hub = c if hub is None else (hub[0] * (width - 1), hub[1] * (height - 1))
        if not (about_hub and scale is not None and hub != c):
            return _View(hub, rad, self._search_angles(scale, c, hub, ring), c, ring, scale, False)
        # a hub seen in the picture: the scale's arc is about it (scale_about), the needle
        # turns about it, so the search and the reading are both about the hub
        found = scale_about(scale, c, hub, ring, None if not marks else
                            [(m[0], m[1] * (width - 1), m[2] * (height - 1)) for m in marks])
        if found is None:
            return None
        scale, read_radius = found
        # the needle's sampling band in proportion to the scale's arc about the hub
        return _View(hub, read_radius / self._reach_radii[-1], self._search_angles(scale), hub, read_radius,
                     scale, True)

    def _needle_profile(self, lab, view):
        """The radial profiles along ``view``'s rays and their pointer candidates (_NeedleProfile)."""
        dist, samples, background = self._profile(lab, view.hub, view.rad, view.angles, self._radii)
        reach_dist = self._profile(lab, view.hub, view.rad, view.angles, self._reach_radii)[0]
        full = np.median(dist, axis=1)
        candidates, base = self._candidates(full, view.angles)
        # distance from the dial's own colour (median over the sweep at each radius): a pointer
        # differs from the dial, the bright or dark fringe that the local mean leaves beside a
        # strong needle does not
        dial = np.median(samples, axis=0)
        off_dial = np.median(np.sqrt(((samples - dial[None]) ** 2).sum(axis=2)), axis=1)
        return _NeedleProfile(view.angles, dist, samples, background, reach_dist, full, base, candidates, off_dial)

    def _describe(self, prof):
        """Each candidate's index, strength, colour class, reach towards the scale and score."""
        described = []
        for i, strength in prof.candidates:
            level = 0.5 * (prof.full[i] + prof.base)
            strong = prof.dist[i] > level
            colour = self._colour_class(np.median(prof.samples[i][strong], axis=0) if strong.any()
                                        else prof.samples[i].mean(0), prof.background[i].mean(axis=0))
            lo, hi = max(0, i - 2), i + 3
            reach = float((prof.reach_dist[lo:hi].max(axis=0) > level).mean())
            described.append({"index": i, "strength": strength, "colour": colour, "reach": reach,
                              "score": strength * (0.5 + float(strong.mean())) * (0.3 + reach)
                              * float(prof.off_dial[i])})
        return described

    def _ranked(self, described, pointer_colour, ignore_colour):
        """The candidates the colour hints allow (all when none fits), best score first."""
        pool = described
        if pointer_colour:
            pool = [d for d in described if self._matches(d["colour"], pointer_colour)] or described
        if ignore_colour:
            pool = [d for d in pool if not self._matches(d["colour"], ignore_colour)] or pool
        return sorted(pool, key=lambda d: -d["score"])

    def _needle_index(self, prof, index):
        """Centre on the needle itself: of the peaks within +-8 deg of ``index``, the one farthest
        from the dial's colour (a fringe beside the needle can win the profile)."""
        near = np.arange(max(0, index - int(8.0 / self.step_deg)),
                         min(len(prof.angles), index + int(8.0 / self.step_deg) + 1))
        return int(near[np.argmax(prof.off_dial[near] * (prof.full[near] > prof.base))])

    def _needle_width(self, prof, i, rad):
        """The needle's width (px): its angular extent above half its height at each radius."""
        window = np.arange(max(0, i - int(6.0 / self.step_deg)),
                           min(len(prof.angles), i + int(6.0 / self.step_deg) + 1))
        over = prof.dist[window] > 0.5 * (prof.dist[i][None] + np.median(prof.dist, axis=0)[None])
        return float(np.median(over.sum(axis=0) * math.radians(self.step_deg) * self._radii * rad))

    def _needle_lines(self, prof, view, i):
        """The needle's whole, inner-half and outer-half centre lines, or None. Fitted to the samples
        of the needle's own colour; to all of them where that leaves too few (a needle hardly apart
        from the face)."""
        k = len(self._radii) // 2
        bands = ((0, len(self._radii)), (0, k), (k, len(self._radii)))
        for like in (self._needle_likeness(prof.dist, prof.samples, prof.background, prof.full, prof.base, i),
                     None):
            lines = [self._line(prof.dist, prof.angles, i, view.hub, view.rad, lo, hi, like) for lo, hi in bands]
            if all(line is not None for line in lines):
                return lines
        return None

    def _pivot_detail(self, detail, lab, c, view, lines, look_for_hub):
        """Adds how far the needle's line passes from the calibrated centre (and the hub) to ``detail``;
        returns the foot of the line nearest the centre: the pivot seen in the picture."""
        line, _, outer_line = lines
        # distances to the outer half's line alone: the inner samples, taken along rays from the hub
        # (or from a centre far off the pivot), pull the whole line through it, the outer ones hardly
        normal = np.array([-outer_line[1][1], outer_line[1][0]])
        if view.about_hub:
            detail["scale_about_hub"] = view.scale
            detail["hub_off_line"] = float(abs(np.dot(np.asarray(view.hub) - outer_line[0], normal))) / view.rad
            detail["hub_radius_unit"] = view.rad     # px per unit of hub_off_line and needle_width
        foot = line[0] + np.dot(np.asarray(c) - line[0], line[1]) * line[1]
        detail["outer_line_miss"] = float(abs(np.dot(np.asarray(c) - outer_line[0], normal))) / view.rad
        if look_for_hub and max(math.hypot(foot[0] - c[0], foot[1] - c[1]) / view.rad,
                                detail["outer_line_miss"]) > self.hub_search:
            # the needle's line misses the calibrated centre: the pivot may be elsewhere
            detail["hub_candidates"] = find_hub(lab[:, :, 0], c, view.rad)
        return foot

    @staticmethod
    def _confidence(prof, i, inner_angle, outer_angle):
        """(contrast ratio, inner/outer disagreement in deg, confidence) of the needle at index ``i``."""
        spread = float(np.percentile(prof.full, 90) - prof.base) + 1.0
        contrast = (prof.full[i] - prof.base) / max(spread, 1.0)
        disagreement = abs(angle_diff(inner_angle, outer_angle))
        return contrast, disagreement, 100.0 * min(1.0, contrast / 2.5) * math.exp(-disagreement / 10.0)

    def _rival_reason(self, prof, described, pool, i, hinted):
        """The "two pointers" reason when another pointer nearly as strong as the chosen one is seen
        and colour hints do not tell them apart; "" otherwise. A rival is another pointer: not the
        same needle's other edge, nor its counterweight (opposite, falling short of the scale)."""
        chosen, angles = pool[0], prof.angles
        rivals = [d for d in pool[1:] if d["score"] > 0.6 * chosen["score"]
                  and abs(d["index"] - i) * self.step_deg > 2.0 * self.background_deg
                  and not (abs(abs(angle_diff(angles[d["index"]], angles[i])) - 180.0) < 15.0
                           and d["reach"] < 0.5 * chosen["reach"])]
        hinted = hinted and any(d["colour"] != chosen["colour"] for d in described)
        if not rivals or hinted:
            return ""
        gap = abs(angle_diff(angles[rivals[0]["index"]], angles[i]))
        return "two pointers %.0f deg apart (set pointer_colour / ignore_colour in the calibration)" % gap

    @staticmethod
    def _weak_reason(face, contrast, disagreement):
        """Why a confidence is low when no rival pointer explains it."""
        glare = float((cv2.cvtColor(face, cv2.COLOR_BGR2GRAY) >= 245).mean())
        if glare > 0.05:
            return "glare over %.0f %% of the dial" % (100.0 * glare)
        if contrast < 1.5:
            return "needle not found (no clear needle against the face)"
        return "inner and outer needle halves disagree by %.1f deg" % disagreement

    def read(self, image, quad, scale, centre=(0.5, 0.5), radius=0.45, aspect=1.0, pointer_colour="",
             ignore_colour="", marks=None):
        """Reading of a pointer gauge; detail["reason"] is non-empty when the reading is uncertain
        (confidence below ``uncertain_below``). Raises ReadFailed when no reading is possible.
        ``marks`` [(value, u, v)] (the scale marks' positions as fractions of the box): when they
        fit an ellipse well, the dial is read in the frontal frame they give (dial_from_marks)."""
        frame = dial_from_marks(quad, centre, radius, aspect, marks) if marks else None
        if frame is not None:
            reading = self._read_frame(image, frame.quad, frame.scale, frame.centre, frame.radius, frame.aspect,
                                       pointer_colour, ignore_colour)
            reading.detail["frame"] = dict(frame.detail, source="marks")
            return reading
        reading = self._read_frame(image, quad, scale, centre, radius, aspect, pointer_colour, ignore_colour, marks)
        if marks:
            reading.detail["frame"] = {"source": "calibration"}
        return reading

    def _read_frame(self, image, quad, scale, centre, radius, aspect, pointer_colour, ignore_colour, marks=None):
        reading = self._read_retried(image, quad, scale, centre, radius, aspect, pointer_colour, ignore_colour, marks)
        unsure = reading.detail.pop("pivot_unsure", "")
        if unsure and reading.confidence >= self.uncertain_below:
            reading = Reading(reading.value, self.uncertain_below * 0.9, reading.detail)
            reading.detail["reason"] = unsure
        return reading

    def _read_retried(self, image, quad, scale, centre, radius, aspect, pointer_colour, ignore_colour, marks):
        reading = self._read_band(image, quad, scale, centre, radius, aspect, pointer_colour, ignore_colour,
                                  marks=marks)
        reading.detail["band"] = "inner"
        if reading.confidence < self.uncertain_below and self._outer_reader is not None:
            outer = self._outer_reader._read_band(image, quad, scale, centre, radius, aspect, pointer_colour,
                                                  ignore_colour, marks=marks)
            if outer.confidence >= self.uncertain_below:
                outer.detail["band"] = "outer"
                return outer
        if reading.confidence < self.uncertain_below and self.hub_axis and scale is not None and scale.sweep < 300.0:
            # still uncertain: the pivot may lie nearer the scale than calibrated (a panel meter seen
            # from below its window, whose marks' circle is flattened): search along the scale's
            # symmetry axis for the hub from which the needle reads most confidently
            mid = math.radians(scale.start_angle + scale.sweep / 2.0)
            best = None
            for d in self.hub_axis:
                hub = (centre[0] + d * radius * math.sin(mid), centre[1] - d * radius * math.cos(mid) * float(aspect))
                found = self._read_band(image, quad, scale, centre, radius, aspect, pointer_colour, ignore_colour,
                                        hub=hub)
                if best is None or found.confidence > best.confidence:
                    best = found
            if best.confidence >= self.hub_axis_confidence:
                best.detail["band"] = "axis"
                return best
        return reading

    def _about_hub(self, hubs, image, quad, scale, centre, radius, aspect, pointer_colour, ignore_colour, first,
                   marks=None):
        """The reading about a hub seen in the picture (find_hub's candidates, face px) instead of the
        calibrated centre, called when the needle's line misses that centre. A candidate within
        ``hub_move`` dial radii of the calibrated centre confirms the calibration (nothing changes).
        One farther off is confirmed when the needle, searched along rays from it and read on the
        scale's arc about it (scale_about), is confident and inside the sweep, the line of its
        outer half passes through the candidate (within the hub's radius, at least 4 % of the dial
        radius) and the candidate is at least twice as wide as the needle: a needle's round tip or
        end, a numeral or a screw on the bezel fail that. Of several confirmed (a hub cap, the
        counterweight's end, a widening of the needle on the same line) the widest is the pivot.
        Returns (angle, confidence, detail, scale the angle is measured on); the detail lists the
        candidates refused and why (``hub_tried``)."""
        angle, confidence, detail, _ = first
        width, height, rad, c = self._face_geometry(centre, radius, aspect)

        def seen(h, off):
            return {"x": round(h.x / (width - 1), 4), "y": round(h.y / (height - 1), 4),
                    "radius": round(h.radius / rad, 3), "score": round(h.score, 2), "offset": round(off, 3)}
        offsets = [math.hypot(h.x - c[0], h.y - c[1]) / rad for h in hubs]
        for h, off in zip(hubs, offsets):
            if off <= self.hub_move:
                detail["hub_seen"] = dict(seen(h, off), used=False)
                return angle, confidence, detail, scale
        tried, confirmed = [], []
        for h, off in zip(hubs, offsets):
            again = self.needle_angle(image, quad, centre, radius, aspect, scale, pointer_colour, ignore_colour,
                                      hub=(h.x / (width - 1), h.y / (height - 1)), about_hub=True, marks=marks)
            if again[0] is None or "scale_about_hub" not in again[2]:
                tried.append(dict(seen(h, off), why="no needle about it"))
                continue
            about = again[2].pop("scale_about_hub")
            why = []
            unit = again[2].pop("hub_radius_unit")
            if again[2]["hub_off_line"] * unit > max(h.radius, 0.04 * rad):
                why.append("the needle's line passes %.0f %% of the dial radius from it"
                           % (100 * again[2]["hub_off_line"] * unit / rad))
            needle_px = again[2]["needle_width"] * unit
            if h.radius < needle_px:
                # a hub cap is at least twice as wide as its needle; a needle's round end is not
                why.append("narrower than twice the needle (%.1f px against %.1f)" % (2 * h.radius, needle_px))
            if not about.in_sweep(again[0], margin_deg=max(1.5, 0.01 * about.sweep)):
                why.append("the needle about it is outside the scale's sweep")
            # the needle's line misses the calibrated centre (find_hub runs only then), which
            # contradicts the calibration: a hub on the line needs only a confident needle
            if again[1] < self.uncertain_below:
                why.append("the needle about it is uncertain (confidence %.0f)" % again[1])
            if why:
                tried.append(dict(seen(h, off), why="; ".join(why)))
                continue
            confirmed.append((h, off, again, about))
        if not confirmed:
            detail["hub_tried"] = tried
            return angle, confidence, detail, scale
        # several on the needle's line (the hub cap, the counterweight's end, a widening of the
        # needle): the pivot is the widest, the cap
        h, off, again, about = max(confirmed, key=lambda k: k[0].radius)
        again[2]["hub_seen"] = dict(seen(h, off), used=True)
        again[2]["hub"] = (h.x / (width - 1), h.y / (height - 1))
        again[2]["hub_tried"] = tried + [dict(seen(k[0], k[1]), why="on the needle's line, narrower than the hub")
                                         for k in confirmed if k[0] is not h]
        return again[0], again[1], again[2], about

    def _read_band(self, image, quad, scale, centre, radius, aspect, pointer_colour, ignore_colour, hub=None,
                   marks=None):
        angle, confidence, detail = self.needle_angle(image, quad, centre, radius, aspect, scale,
                                                      pointer_colour, ignore_colour, hub=hub,
                                                      look_for_hub=hub is None and self.find_hubs)
        hubs = detail.pop("hub_candidates", None)
        if hubs == []:
            detail["hub_tried"] = []
        if angle is not None and hubs:
            angle, confidence, detail, scale = self._about_hub(hubs, image, quad, scale, centre, radius, aspect,
                                                               pointer_colour, ignore_colour,
                                                               (angle, confidence, detail, scale), marks)
        first = detail
        for _ in range(self.hub_steps if hub is None and "hub" not in detail else 0):
            # the hub lies on the needle's line: when a confidently found line passes well away
            # from the calibrated centre, search again along rays from its point nearest the centre
            if angle is None or confidence < self.uncertain_below:
                break
            off = _pivot_offset(detail["pivot"], centre, aspect)
            if off < self.hub_move * radius:
                break
            again = self.needle_angle(image, quad, centre, radius, aspect, scale, pointer_colour, ignore_colour,
                                      hub=detail["pivot"])
            if again[0] is None or again[1] < 0.8 * confidence:
                break
            angle, confidence, detail = again
            detail["hub"] = detail["pivot"]
        if angle is not None and "hub_tried" in first and "hub_seen" not in first:
            # the needle's line misses the calibrated centre and no hub seen in the picture confirms
            # another pivot (the search from the line's point nearest the centre guesses one): the
            # reading's geometry is a guess
            off = max(_pivot_offset(first["pivot"], centre, aspect), first["outer_line_miss"] * radius)
            if off > self.hub_unsure * radius:
                # applied by _read_frame to the reading it returns, so the retries it makes for an
                # uncertain reading (outer band, axis) do not replace an honest flag with a guess
                detail["hub_tried"] = first["hub_tried"]
                detail["pivot_unsure"] = ("pivot not found: the needle's line passes %.0f %% of the dial radius from "
                                          "the calibrated centre and no hub on it was confirmed (%d candidate(s) tried)"
                                          % (100.0 * off / radius, len(first["hub_tried"])))
        if angle is None:
            return Reading(float("nan"), 0.0, detail)
        if not scale.in_sweep(angle, margin_deg=max(1.5, 0.01 * scale.sweep)):
            # beyond an end (inside the search margin): reported, not hidden in the end value
            over = scale.offset(angle) - scale.sweep
            under = 360.0 - scale.offset(angle)
            confidence = min(confidence, self.uncertain_below * 0.6)
            detail["reason"] = "needle outside the scale's sweep (%.1f deg beyond the %s)" % (
                min(over, under), "end" if over < under else "start")
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


def face_similarity(image, quad, reference, reference_quad, size=96):
    """Correlation (-1..1) of the edge structure of two boxes rectified to ``size`` px: a gauge's
    ticks, numbers and rim outweigh its needle, so the same gauge at another value stays high."""
    def signature(img, q):
        patch = rectify(img, q, size)
        return _edge_signature(patch if patch.ndim == 2 else cv2.cvtColor(patch, cv2.COLOR_BGR2GRAY))
    return float((signature(image, quad) * signature(reference, reference_quad)).sum())


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
