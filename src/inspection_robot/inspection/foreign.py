"""Foreign-object detection: differences between a picture and its aligned reference.

The reference is warped onto the new picture with the homography from localisation. Both are
normalised for lighting (each pixel and colour channel divided by its local mean, so a global gain or a
smooth shadow cancels); structure present in the new picture but not in the reference and
larger than ``min_area_px`` becomes a box with a confidence from its contrast and size.
"""
from collections import namedtuple

import numpy as np

from inspection_robot.lazy import lazy_import

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load

Foreign = namedtuple("Foreign", "quad confidence area")


def _normalised(image, sigma):
    image = image.astype(np.float32) + 8.0
    local = cv2.GaussianBlur(image, (0, 0), sigma)
    return cv2.GaussianBlur(image, (0, 0), 1.5) / local


def _tolerant_difference(new, ref, tolerance):
    """Per pixel, how far ``new`` lies outside the range ``ref`` takes within ``tolerance`` px (per
    colour channel, the largest channel): a registration error or a little parallax of that size
    leaves no trace, an object that is not in the reference does."""
    kernel = np.ones((2 * tolerance + 1, 2 * tolerance + 1), np.uint8)
    high = cv2.dilate(ref, kernel)
    low = cv2.erode(ref, kernel)
    outside = cv2.max(cv2.subtract(new, high), cv2.subtract(low, new))
    channels = cv2.split(outside)
    diff = channels[0]
    for channel in channels[1:]:
        diff = cv2.max(diff, channel)
    return np.maximum(diff, 0.0)


def detect_foreign(reference, picture, homography, region=None, exclude=(), min_area_px=None,
                   threshold=0.12, max_side=640, min_confidence=40.0, tolerance=0.006):
    """Boxes (TL, TR, BR, BL in ``picture`` pixels) of objects in ``picture`` absent in ``reference``.

    ``homography`` maps reference pixels to picture pixels (the registration of the live picture to
    the preset's); ``region`` (a quad in the picture) limits the search, default the whole
    overlap; ``exclude`` (quads in the picture, e.g. the calibrated targets, whose needles and
    lamps change by design) are ignored. Both pictures are normalised for lighting (each pixel and
    colour channel divided by its local mean: a global gain, a tint or a smooth shadow cancel);
    a pixel differs only when no reference pixel within ``tolerance`` (fraction of the picture's
    longer side) matches it, so the residual misregistration after a stop off the preset pose
    raises nothing. Returns a list of Foreign, largest first.
    """
    height, width = picture.shape[:2]
    scale = min(1.0, float(max_side) / max(height, width))
    size = (int(round(width * scale)), int(round(height * scale)))
    down = np.diag([scale, scale, 1.0])
    matrix = down.dot(np.asarray(homography, np.float64))
    ref_img = reference if reference.ndim == 3 else cv2.cvtColor(reference, cv2.COLOR_GRAY2BGR)
    new_img = picture if picture.ndim == 3 else cv2.cvtColor(picture, cv2.COLOR_GRAY2BGR)
    new_small = cv2.resize(new_img, size, interpolation=cv2.INTER_AREA)
    ref_small = cv2.warpPerspective(ref_img, matrix, size, flags=cv2.INTER_AREA)
    valid = cv2.warpPerspective(np.full(ref_img.shape[:2], 255, np.uint8), matrix, size,
                                flags=cv2.INTER_NEAREST)
    # outside the reference's footprint, use the picture itself so no artificial edge appears
    ref_small = np.where(valid[:, :, None] > 0, ref_small, new_small)
    valid = cv2.erode(valid, np.ones((9, 9), np.uint8))
    if region is not None:
        mask = np.zeros(valid.shape, np.uint8)
        cv2.fillConvexPoly(mask, np.round(np.asarray(region) * scale).astype(np.int32), 255)
        valid = cv2.bitwise_and(valid, mask)
    for quad in exclude:
        cv2.fillConvexPoly(valid, np.round(np.asarray(quad) * scale).astype(np.int32), 0)
    sigma = max(size) / 20.0
    shift = max(1, int(round(tolerance * max(size))))
    # per colour channel, so an object of another hue but the same grey level still shows
    diff = _tolerant_difference(_normalised(new_small, sigma), _normalised(ref_small, sigma), shift)
    binary = ((diff > threshold) & (valid > 0)).astype(np.uint8) * 255
    binary = cv2.morphologyEx(binary, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    # one object often splits where it crosses background edges: join fragments close together
    join = max(5, int(max(size) / 40) | 1)
    binary = cv2.morphologyEx(binary, cv2.MORPH_CLOSE, np.ones((join, join), np.uint8))
    if min_area_px is None:
        min_area_px = 0.002 * size[0] * size[1]
    count, labels, stats, _ = cv2.connectedComponentsWithStats(binary)
    found = []
    for i in range(1, count):
        x, y, w, h, area = stats[i]
        if area < min_area_px:
            continue
        values = diff[labels == i]
        strength = float(values.mean())
        confidence = 100.0 * min(1.0, strength / (2 * threshold)) * min(1.0, area / (2.0 * min_area_px))
        if confidence < min_confidence:
            continue  # faint specks: compression artefacts, slight misalignment
        # the box holds the object's core: the local-mean normalisation leaves a faint halo around it
        core = (labels == i) & (diff > 0.5 * float(np.percentile(values, 95)))
        ys, xs = np.nonzero(core)
        if len(xs):
            x, y, w, h = xs.min(), ys.min(), xs.max() - xs.min() + 1, ys.max() - ys.min() + 1
        quad = np.array([[x, y], [x + w, y], [x + w, y + h], [x, y + h]], np.float64) / scale
        found.append(Foreign(quad, float(min(100.0, confidence)), float(area / scale / scale)))
    found.sort(key=lambda f: -f.area)
    return found
