"""The needle of a pointer gauge found on its rectified face: candidates and the needle's line.

One job: from the picture, the box and the calibrated dial (pivot, radius, aspect, scale) to the
pointer candidates and the chosen needle's centre lines (whole, inner half, outer half). How much
to trust what is found (confidence, rivals, agreement) is needle_confidence's; turning an angle
into a value, and which band or frame to read in, is pointer's.
"""
import math
from collections import namedtuple

import numpy as np

from inspection_robot.lazy import lazy_import
from inspection_robot.inspection.geometry import grey, quad_size, rectify
from inspection_robot.inspection.gauge import wrap360
from inspection_robot.inspection.readers import ReadFailed

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load

GAUGE_SIZE = 256          # px side of the rectified gauge face
ANGLE_STEP_DEG = 0.5      # angular sampling of the polar profile
# Pointer colour classes a calibration may name (pointer_colour: the current pointer; ignore_colour:
# a drag / max pointer or set-point needle to leave alone). "dark"/"light" are relative to the face.
POINTER_COLOURS = ("dark", "light", "red", "black", "white")
# A needle's run of samples wider than its own width (a straight line of width against radius) by
# this share and this many px, its centre JOINED_PX off the needle's line: a numeral or tick is
# joined to it there and pulls it (NeedleFinder._joined). Chosen on bench_needle_numeral's tuning part.
WIDENED_SHARE = 0.3
WIDENED_PX = 0.5
JOINED_PX = 0.5
# A radius shows the needle when the face SIDE_GAP (of the dial radius) beyond its edges, each side, is no farther from
# the dial's colour than SIDE_RATIO of the needle itself, and the needle at least MIN_NEEDLE_DIST (Lab)
# from it (NeedleFinder.visible_share). Chosen on the real set's tuning part (bench/real_set.py).
SIDE_GAP = 0.08     # of the dial radius: beyond a needle's shadow, within an object that hides it
SIDE_RATIO = 0.5
MIN_NEEDLE_DIST = 8.0
MIN_FOCUS_RATIO = 0.5   # a box less sharp than this share of its calibration picture is out of focus (focus_ratio)

# The radial profiles along the rays from the calibrated pivot (NeedleFinder.profile), their median
# over the radius (``full``, its median ``base``), the pointer candidates and each ray's distance
# from the dial's colour.
NeedleProfile = namedtuple("NeedleProfile", "angles dist samples background reach_dist full base candidates off_dial")
# The face as read: its BGR and Lab images, the dial radius (px), the calibrated pivot (px), the
# scale circle's radius (px) and the share of the face that lies inside the picture.
Face = namedtuple("Face", "bgr lab rad centre ring inside")


def check_face(face):
    """Raise ReadFailed for a picture that cannot hold a reading: blank, over- or underexposed."""
    gray = grey(face)
    if float((gray >= 250).mean()) > 0.95:   # a saturated dial with a visible needle still reads
        raise ReadFailed("overexposed picture in the box")
    if float((gray <= 5).mean()) > 0.95:
        raise ReadFailed("underexposed picture in the box")
    if float(gray.std()) < 4.0:
        raise ReadFailed("blank picture in the box (no contrast)")


def sharpness(image, quad, size):
    """Fine detail of the box rectified to ``size`` px: the mean absolute Laplacian over the grey
    levels' spread (a darker or flatter picture is not a blurred one)."""
    face = rectify(image, quad, size)
    grey_face = grey(face).astype(np.float32)
    return float(np.mean(np.abs(cv2.Laplacian(grey_face, cv2.CV_32F, ksize=3))) / (float(grey_face.std()) + 1.0))


def focus_ratio(image, quad, reference, reference_quad):
    """The box's sharpness against the calibration picture's at the coarser of the two resolutions
    (a gauge seen from farther is not out of focus for that): about 1 for the same focus, under
    MIN_FOCUS_RATIO for a picture out of focus or shaken (chosen on the real set's tuning part: a
    blur of 1.5 % of the dial radius gives 0.1-0.6, sharp cross photos 0.7-1.3)."""
    size = int(min((GAUGE_SIZE,) + quad_size(quad) + quad_size(reference_quad)))
    if size < 16:
        return 1.0
    return sharpness(image, quad, size) / max(sharpness(reference, reference_quad, size), 1e-6)


def meets_circle(line, centre, r):
    """Angle (deg clockwise from up, about ``centre``) where the line leaves the circle of radius r."""
    p, u = line
    q = p - np.asarray(centre)
    b = float(np.dot(q, u))
    disc = b * b - (float(np.dot(q, q)) - r * r)
    t = -b + math.sqrt(max(disc, 0.0))
    x, y = q + t * u
    return wrap360(math.degrees(math.atan2(x, -y)))


def colour_class(needle_lab, face_lab):
    """red | dark | light for a candidate's median colour against the local face colour."""
    if needle_lab[1] - 128.0 > 20.0 and needle_lab[1] - face_lab[1] > 15.0:
        return "red"
    return "dark" if needle_lab[0] < face_lab[0] else "light"


def matches_colour(colour, hint):
    hint = {"black": "dark", "white": "light"}.get(hint, hint)
    return colour == hint


def rectify_face(image, quad, width, height):
    """The box rectified to ``width`` x ``height``, the part outside the picture filled with the
    face's median colour (a flat fill shows no needle; replicated border pixels would draw
    streaks), and the share of the face inside the picture."""
    face = rectify(image, quad, width, height)
    if face.ndim == 2:
        face = cv2.cvtColor(face, cv2.COLOR_GRAY2BGR)
    dst = np.float32([[0, 0], [width - 1, 0], [width - 1, height - 1], [0, height - 1]])
    matrix = cv2.getPerspectiveTransform(np.asarray(quad, np.float32), dst)
    seen = cv2.warpPerspective(np.full(image.shape[:2], 255, np.uint8), matrix, (width, height),
                               flags=cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT, borderValue=0) > 0
    inside = float(seen.mean())
    if 0.0 < inside < 1.0:
        face = face.copy()
        face[~seen] = np.median(face[seen], axis=0).astype(face.dtype)
    return face, inside


class NeedleFinder(object):
    """Finds the needle on a rectified gauge face by a radial dissimilarity profile and a line fit.

    For every direction (``step_deg`` steps) within the scale's sweep plus ``margin_deg`` the face
    is sampled along the radius between ``inner`` and ``outer`` (fractions of the dial radius)
    from the calibrated pivot; each sample's distance from the local face colour (mean over
    +-``background_deg``, in Lab) measures "needle-ness". The median along the radius rejects
    numbers and ticks (which cover only part of the radius). Every local maximum is a pointer
    candidate, ranked by its strength, its coverage of the radius and its reach towards the scale
    (radii ``reach``: a pointer's tip reaches the ticks, its counterweight does not). Colour hints
    from the calibration choose among them.

    The chosen pointer's centre line is fitted to the needle's own pixels (the angular centroid at
    each radius; for a coloured needle only samples of its hue), so a pivot a little off the
    calibrated centre still gives the needle's real line; it is read where it meets the scale
    circle (``reach[1]`` of the dial radius about the calibrated centre).
    """

    def __init__(self, size=GAUGE_SIZE, inner=0.22, outer=0.72, step_deg=ANGLE_STEP_DEG, background_deg=12.0,
                 margin_deg=8.0, reach=(0.72, 0.9)):
        self.size = size
        self.inner = inner
        self.outer = outer
        self.step_deg = step_deg
        self.background_deg = background_deg
        self.margin_deg = margin_deg
        self.radii = np.linspace(inner, outer, 48)
        self.reach_radii = np.linspace(reach[0], reach[1], 12)

    def face(self, image, quad, centre, radius, aspect):
        """The rectified face (Face); ReadFailed for a blank one."""
        aspect = float(aspect)
        width = self.size if aspect >= 1.0 else max(16, int(round(self.size * aspect)))
        height = max(16, int(round(width / aspect)))
        bgr, inside = rectify_face(image, quad, width, height)
        check_face(bgr)
        bgr = cv2.GaussianBlur(bgr, (3, 3), 0)
        rad = radius * (width - 1)
        return Face(bgr, cv2.cvtColor(bgr, cv2.COLOR_BGR2LAB), rad, (centre[0] * (width - 1), centre[1] * (height - 1)),
                    rad * self.reach_radii[-1], inside)

    def search_angles(self, scale):
        """Directions (deg clockwise from up) that cover the scale's sweep plus margin_deg; all
        around without a scale."""
        if scale is None:
            return np.arange(0.0, 360.0, self.step_deg)
        span = min(360.0, scale.sweep + 2 * self.margin_deg)
        start = scale.start_angle - (span - scale.sweep) / 2.0
        return start + np.arange(0.0, span, self.step_deg)

    def samples(self, face_lab, centre, radius, angles, radii):
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

    def profile(self, face, angles):
        """The radial profiles along the rays and their pointer candidates (NeedleProfile)."""
        dist, samples, background = self.samples(face.lab, face.centre, face.rad, angles, self.radii)
        reach_dist = self.samples(face.lab, face.centre, face.rad, angles, self.reach_radii)[0]
        full = np.median(dist, axis=1)
        candidates, base = self._candidates(full)
        # distance from the dial's own colour (median over the sweep at each radius): a pointer
        # differs from the dial, the bright or dark fringe that the local mean leaves beside a
        # strong needle does not
        dial = np.median(samples, axis=0)
        off_dial = np.median(np.sqrt(((samples - dial[None]) ** 2).sum(axis=2)), axis=1)
        return NeedleProfile(angles, dist, samples, background, reach_dist, full, base, candidates, off_dial)

    def _candidates(self, full):
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

    @staticmethod
    def describe(prof):
        """Each candidate's index, strength, colour class, reach towards the scale and score."""
        described = []
        for i, strength in prof.candidates:
            level = 0.5 * (prof.full[i] + prof.base)
            strong = prof.dist[i] > level
            colour = colour_class(np.median(prof.samples[i][strong], axis=0) if strong.any()
                                  else prof.samples[i].mean(0), prof.background[i].mean(axis=0))
            lo, hi = max(0, i - 2), i + 3
            reach = float((prof.reach_dist[lo:hi].max(axis=0) > level).mean())
            described.append({"index": i, "strength": strength, "colour": colour, "reach": reach,
                              "score": strength * (0.5 + float(strong.mean())) * (0.3 + reach)
                              * float(prof.off_dial[i])})
        return described

    @staticmethod
    def ranked(described, pointer_colour, ignore_colour):
        """The candidates the colour hints allow (all when none fits), best score first."""
        pool = described
        if pointer_colour:
            pool = [d for d in described if matches_colour(d["colour"], pointer_colour)] or described
        if ignore_colour:
            pool = [d for d in pool if not matches_colour(d["colour"], ignore_colour)] or pool
        return sorted(pool, key=lambda d: -d["score"])

    def needle_index(self, prof, index, window_deg=8.0):
        """Centre on the needle itself: of the peaks within +-``window_deg`` of ``index``, the one
        farthest from the dial's colour (a fringe beside the needle can win the profile)."""
        near = np.arange(max(0, index - int(window_deg / self.step_deg)),
                         min(len(prof.angles), index + int(window_deg / self.step_deg) + 1))
        return int(near[np.argmax(prof.off_dial[near] * (prof.full[near] > prof.base))])

    def visible_share(self, face, prof, line, width_px, gap=SIDE_GAP, ratio=SIDE_RATIO):
        """The share of the needle's length that is visibly a needle: along its fitted ``line`` (point,
        outward unit direction), at each of the profile's radii, the face just beside it (half its
        width ``width_px`` plus ``gap`` of the dial radius, each side, across the line) has the dial's colour (the
        median over the sweep at that radius: no farther from it than ``ratio`` of the needle
        itself). Where an object hides the needle, or the "needle" is an object's edge, one side or
        both are not the dial."""
        dial = np.median(prof.samples, axis=0)
        point, direction = np.asarray(line[0], float), np.asarray(line[1], float)
        q = point - np.asarray(face.centre, float)
        b = float(np.dot(q, direction))
        r = self.radii * face.rad
        t = -b + np.sqrt(np.maximum(b * b - (float(np.dot(q, q)) - r * r), 0.0))
        on = np.asarray(face.centre, float)[None] + q[None] + t[:, None] * direction[None]
        normal = np.array([-direction[1], direction[0]]) * (width_px / 2.0 + gap * face.rad)
        points = np.concatenate([on, on + normal, on - normal]).astype(np.float32)
        lab = cv2.remap(face.lab, points[:, :1], points[:, 1:], cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_REPLICATE).reshape(3, len(r), 3).astype(np.float32)
        off_dial = np.sqrt(((lab - dial[None]) ** 2).sum(axis=2))
        needle, beside = off_dial[0], np.maximum(off_dial[1], off_dial[2])
        return float(((beside < ratio * needle) & (needle > MIN_NEEDLE_DIST)).mean())

    def needle_width(self, prof, i, rad):
        """The needle's width (px): its angular extent above half its height at each radius."""
        window = np.arange(max(0, i - int(6.0 / self.step_deg)),
                           min(len(prof.angles), i + int(6.0 / self.step_deg) + 1))
        over = prof.dist[window] > 0.5 * (prof.dist[i][None] + np.median(prof.dist, axis=0)[None])
        return float(np.median(over.sum(axis=0) * math.radians(self.step_deg) * self.radii * rad))

    def _centres(self, dist, angles, i, centre, radius, like=None):
        """The needle's centre at every radius near direction index ``i``: the angular centroid of
        the needle's run of samples (``_run_about``) gives a point. ``like`` (angles x radii, 0..1):
        how much each sample has the needle's own colour; it scales the weights, so a number or
        tick of another colour beside the needle does not pull the centroid. Returns (points px,
        weights, run widths px, whether each radius has a point), one row per radius; a run's
        width is its weight over its peak's (not its count of samples: a continuous measure, not
        steps of one sample, up to 1 px at the outer radii)."""
        half = max(2, int(round(6.0 / self.step_deg)))
        idx = np.arange(max(0, i - half), min(len(angles), i + half + 1))
        columns = dist[idx] if like is None else dist[idx] * like[idx]
        level = 0.5 * (columns.max(axis=0) + np.median(dist, axis=0))
        n = len(self.radii)
        points, weights, widths = np.zeros((n, 2)), np.zeros(n), np.zeros(n)
        for k in range(n):
            w = _run_about(np.clip(columns[:, k] - level[k], 0.0, None), i - idx[0])
            weights[k] = float(w.sum())
            if weights[k] <= 0:
                continue
            theta = math.radians(float((w * angles[idx]).sum() / weights[k]))
            r = self.radii[k] * radius
            points[k] = (centre[0] + r * math.sin(theta), centre[1] - r * math.cos(theta))
            widths[k] = weights[k] / float(w.max()) * math.radians(self.step_deg) * r
        return points, weights, widths, weights > 0

    @staticmethod
    def _widened(widths, valid, radii, px_floor=WIDENED_PX, share=WIDENED_SHARE):
        """Radii where something of the needle's ink is joined to it: a numeral's strokes or a
        tick the needle lies on widen its run there (and pull its centroid to their side). The
        needle's own width changes smoothly along it (a taper): a robust straight line of width
        against radius (Theil-Sen), refitted without the radii it finds widened (joined ink only
        ever widens the run, so the first line lies too high); a run wider than that line by more
        than ``share`` of it and ``px_floor`` px is widened."""
        widened = np.zeros(len(widths), bool)
        for _ in range(3):
            k = np.flatnonzero(valid & ~widened)
            if len(k) < 4:
                break
            x, y = radii[k], widths[k]
            a, b = np.triu_indices(len(k), 1)
            slope = float(np.median((y[b] - y[a]) / (x[b] - x[a])))
            expected = float(np.median(y - slope * x)) + slope * radii
            found = valid & (widths - expected > np.maximum(px_floor, share * expected))
            if np.array_equal(found, widened):
                break
            widened = found
        return widened

    @staticmethod
    def _line(points, weights):
        """A weighted least-squares line through the needle's centre points, or None for fewer than
        4. Returns (point on the line, unit direction outwards)."""
        if len(points) < 4:
            return None
        pts, w = points, weights
        mean, u = _weighted_line(pts, w)
        # a numeral or tick touching the needle shifts the centroid at the radii it covers: those
        # points lie off the line the others agree on (beyond 3 robust deviations, at least a
        # pixel), and are left out of a second fit
        off = np.abs((pts - mean).dot(np.array([-u[1], u[0]])))
        keep = off <= max(1.0, 3.0 * 1.4826 * float(np.median(off)))
        if 4 <= keep.sum() < len(pts):
            mean, u = _weighted_line(pts[keep], w[keep])
        if np.dot(u, pts[-1] - pts[0]) < 0:
            u = -u
        return mean, u

    @staticmethod
    def _needle_likeness(prof, i, min_chroma=15.0):
        """How much every sample has the hue of a coloured needle at direction index ``i`` (angles
        x radii, 0..1), or None for a needle of the face's own hue (black on white: the numbers
        and ticks share its ink, colour cannot tell them apart). Only the chroma (Lab a, b) counts,
        so glare or shade along the needle do not matter: 1 at the needle's median chroma, falling
        linearly to 0 at the face's. A half-covered pixel at the needle's edge scores about its
        coverage on both edges alike (no bias); a white number beside a red needle scores near 0."""
        strong = prof.dist[i] > 0.5 * (prof.full[i] + prof.base)
        if not strong.any():
            return None
        needle = np.median(prof.samples[i][strong][:, 1:], axis=0)
        chroma = float(np.sqrt(((needle - np.median(prof.background[i][:, 1:], axis=0)) ** 2).sum()))
        if chroma < min_chroma:
            return None
        apart = np.sqrt(((prof.samples[:, :, 1:] - needle[None, None]) ** 2).sum(axis=2))
        return np.clip(1.0 - apart / chroma, 0.0, 1.0)

    def needle_lines(self, prof, face, i):
        """The needle's whole, inner-half and outer-half centre lines, or None. Fitted to the samples
        of the needle's own colour; to all of them where that leaves too few (a needle hardly apart
        from the face). The whole line, the one read, leaves out the radii where other ink is
        joined to the needle (``_joined``); the halves, which only measure how straight the needle
        is (needle_confidence), keep every radius."""
        n = len(self.radii)
        halves = (np.arange(n) < n // 2, np.arange(n) >= n // 2)
        for like in (self._needle_likeness(prof, i), None):
            points, weights, widths, valid = self._centres(prof.dist, prof.angles, i, face.centre, face.rad, like)
            whole = valid & ~self._joined(points, weights, widths, valid)
            lines = [self._line(points[whole], weights[whole])]
            lines += [self._line(points[valid & half], weights[valid & half]) for half in halves]
            if all(line is not None for line in lines):
                return lines
        return None

    def _joined(self, points, weights, widths, valid, px_floor=JOINED_PX):
        """Radii where a numeral or tick joined to the needle pulls its centre: the run is widened
        there (``_widened``) and its centre lies off the line through the other radii by more than
        ``px_floor`` px and 3 robust deviations of theirs. Both, so a needle whose own width is not
        a straight taper (widening towards a lance tip) keeps its radii: they stay on its line.
        None left out when that would leave fewer than half the radii."""
        widened = self._widened(widths, valid, self.radii)
        clean = valid & ~widened
        if not widened.any() or clean.sum() < 4 or 2 * clean.sum() < valid.sum():
            return np.zeros(len(valid), bool)
        mean, u = _weighted_line(points[clean], weights[clean])
        off = np.abs((points - mean).dot(np.array([-u[1], u[0]])))
        return widened & (off > max(px_floor, 3.0 * 1.4826 * float(np.median(off[clean]))))


def _run_about(weights, j):
    """``weights`` kept only on the contiguous run of positive samples at or nearest index ``j``
    (the needle's direction): a numeral or tick beside the needle, separated from it by face,
    does not pull the needle's centroid."""
    positive = np.flatnonzero(weights > 0)
    if not len(positive):
        return weights
    start = stop = int(positive[np.argmin(np.abs(positive - j))])
    while start > 0 and weights[start - 1] > 0:
        start -= 1
    while stop + 1 < len(weights) and weights[stop + 1] > 0:
        stop += 1
    out = np.zeros_like(weights)
    out[start:stop + 1] = weights[start:stop + 1]
    return out


def _weighted_line(pts, w):
    """(weighted mean, unit direction of the principal axis) of points ``pts`` with weights ``w``."""
    mean = (pts * w[:, None]).sum(axis=0) / w.sum()
    d = pts - mean
    _, vectors = np.linalg.eigh((d * w[:, None]).T.dot(d))
    return mean, vectors[:, -1]
