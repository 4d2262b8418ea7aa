"""The dial's frame in the picture: an oblique dial straightened from its scale marks, and how much
of the dial (its pivot and scale arc) the picture shows.

One job: the geometry between the calibration's box and the dial's frontal frame, before any needle
is looked for.
"""
import math
from collections import namedtuple

import numpy as np

from inspection_robot.lazy import lazy_import
from inspection_robot.inspection.gauge import GaugeScale, wrap360

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load

SCALE_RING = 0.9          # the scale circle's radius, in dial radii (needle.NeedleFinder's reach[1])


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


def dial_outside(quad, width, height, centre, radius, aspect, scale, ring=SCALE_RING, points=64):
    """The share (0..1) of the dial's pivot and scale arc that lies outside a ``width`` x
    ``height`` picture, for the calibrated dial in ``quad`` (``centre``, ``radius``, ``aspect``
    as in the calibration; ``scale`` the sweep, all around without one). The pivot counts as much
    as the whole arc: a needle cannot be followed to a pivot the picture does not show."""
    aspect = float(aspect)
    sweep = scale.sweep if scale is not None else 360.0
    start = scale.start_angle if scale is not None else 0.0
    a = np.radians(start + np.linspace(0.0, sweep, points))
    u = centre[0] + ring * radius * np.sin(a)
    v = centre[1] - ring * radius * aspect * np.cos(a)
    face = np.vstack([np.stack([u, v], axis=1), [centre]])
    unit = np.float32([[0, 0], [1, 0], [1, 1], [0, 1]])
    to_image = cv2.getPerspectiveTransform(unit, np.asarray(quad, np.float32))
    seen = cv2.perspectiveTransform(face.reshape(-1, 1, 2).astype(np.float32), to_image).reshape(-1, 2)
    out = (seen[:, 0] < 0) | (seen[:, 0] > width - 1) | (seen[:, 1] < 0) | (seen[:, 1] > height - 1)
    return 0.5 * float(out[:-1].mean()) + 0.5 * float(out[-1])
