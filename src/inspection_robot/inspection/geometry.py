"""Box geometry: quads (TL, TR, BR, BL), flat roi_vertex lists, rectifying warps, IoU."""
import numpy as np

from inspection_robot.lazy import lazy_import
from inspection_robot.interface import ROI_VALUES_PER_BOX

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load


def quads_from_flat(values):
    """[x1, y1, ... x4, y4] * n -> list of 4x2 float arrays; raises ValueError on a bad length."""
    values = list(values)
    if len(values) % ROI_VALUES_PER_BOX != 0:
        raise ValueError("roi_vertex needs 8 numbers per box, got %d numbers" % len(values))
    return [np.array(values[i:i + 8], dtype=np.float64).reshape(4, 2)
            for i in range(0, len(values), ROI_VALUES_PER_BOX)]


def flat_from_quads(quads):
    """List of 4x2 quads -> flat list of ints (rounded), TL, TR, BR, BL per box."""
    out = []
    for quad in quads:
        out.extend(int(round(v)) for v in np.asarray(quad, dtype=np.float64).reshape(-1))
    return out


def quad_inside(quad, width, height, margin=0.0):
    """True when every corner lies inside a width x height picture (with ``margin`` px slack)."""
    q = np.asarray(quad, dtype=np.float64)
    return bool(np.all(q[:, 0] >= -margin) and np.all(q[:, 0] <= width - 1 + margin)
                and np.all(q[:, 1] >= -margin) and np.all(q[:, 1] <= height - 1 + margin))


def quad_overlap(quad, width, height):
    """The share (0..1) of a convex quad's area that lies inside a width x height picture."""
    q = np.asarray(quad, dtype=np.float32)
    area = abs(cv2.contourArea(q))
    if area <= 0:
        return 0.0
    frame = np.float32([[0, 0], [width - 1, 0], [width - 1, height - 1], [0, height - 1]])
    inter, _ = cv2.intersectConvexConvex(q, frame)
    return float(min(1.0, inter / area))


def quad_is_convex(quad):
    """True for a non-degenerate convex quad in clockwise (image) order TL, TR, BR, BL."""
    q = np.asarray(quad, dtype=np.float64)
    signs = []
    for i in range(4):
        a, b, c = q[i], q[(i + 1) % 4], q[(i + 2) % 4]
        signs.append((b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0]))
    return all(s > 1e-6 for s in signs)


def quad_center(quad):
    return np.asarray(quad, dtype=np.float64).mean(axis=0)


def grey(image):
    """``image`` as one grey channel (BGR converted, a grey image as it is)."""
    return image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)


def rectify(image, quad, size, height=None):
    """Warp the quad of ``image`` to a frontal ``size`` x ``height`` (default square) view, TL at (0, 0)."""
    height = size if height is None else height
    dst = np.array([[0, 0], [size - 1, 0], [size - 1, height - 1], [0, height - 1]], dtype=np.float32)
    matrix = cv2.getPerspectiveTransform(np.asarray(quad, dtype=np.float32), dst)
    return cv2.warpPerspective(image, matrix, (size, height), flags=cv2.INTER_LINEAR,
                               borderMode=cv2.BORDER_REPLICATE)


def quad_size(quad):
    """(width, height) of a quad TL, TR, BR, BL: the means of its opposite sides."""
    q = np.asarray(quad, dtype=np.float64).reshape(4, 2)
    return ((np.linalg.norm(q[1] - q[0]) + np.linalg.norm(q[2] - q[3])) / 2.0,
            (np.linalg.norm(q[3] - q[0]) + np.linalg.norm(q[2] - q[1])) / 2.0)


def sub_quad(quad, window):
    """The part of ``quad`` (TL, TR, BR, BL) between fractions ``window`` (left, top, right, bottom)
    of its own width and height, bilinear in its corners (fractions outside 0..1 reach beyond it)."""
    tl, tr, br, bl = np.asarray(quad, dtype=np.float64).reshape(4, 2)
    left, top, right, bottom = window

    def at(u, v):
        return (1 - v) * ((1 - u) * tl + u * tr) + v * ((1 - u) * bl + u * br)
    return np.array([at(left, top), at(right, top), at(right, bottom), at(left, bottom)])


def transform_quad(homography, quad):
    pts = np.asarray(quad, dtype=np.float64).reshape(-1, 1, 2)
    return cv2.perspectiveTransform(pts, np.asarray(homography, dtype=np.float64)).reshape(-1, 2)


def quad_iou(a, b):
    """Intersection over union of two convex quads."""
    a = np.asarray(a, dtype=np.float32)
    b = np.asarray(b, dtype=np.float32)
    area_a = abs(cv2.contourArea(a))
    area_b = abs(cv2.contourArea(b))
    if area_a <= 0 or area_b <= 0:
        return 0.0
    inter, _ = cv2.intersectConvexConvex(a, b)
    return float(inter / (area_a + area_b - inter))


def polygon_mask(shape, quad):
    mask = np.zeros(shape[:2], dtype=np.uint8)
    cv2.fillConvexPoly(mask, np.round(np.asarray(quad)).astype(np.int32), 255)
    return mask
