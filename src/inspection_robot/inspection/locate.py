"""Locating calibrated target boxes in a new picture against a reference picture.

Features (AKAZE, else ORB; SIFT when the OpenCV build has it and it is asked for) are matched
with a ratio test; a RANSAC homography maps the reference onto the new picture. Each box is then
refined with the matches near it (parallax after a pose error makes one global homography wrong
away from the dominant plane): the globally mapped box is shifted by the median residual of the
near matches that roughly agree with the global homography. Box corners TL, TR, BR, BL. Pictures
are matched at a reduced size for speed; coordinates are in the full pictures.
"""
from collections import namedtuple

import numpy as np

from inspection_robot.lazy import lazy_import
from inspection_robot.inspection.geometry import quad_center, quad_is_convex, transform_quad

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load

Features = namedtuple("Features", "keypoints descriptors scale shape")
# points: the inlier matches in the new picture (where the scene agrees with the homography)
Located = namedtuple("Located", "quads homography inliers matches confidence points")


class LocateError(Exception):
    """The target could not be located; the message is the reason."""


def make_detector(name):
    """A feature detector by name (akaze | orb | sift), falling back to AKAZE then ORB."""
    if name == "sift" and hasattr(cv2, "SIFT_create"):
        return cv2.SIFT_create(nfeatures=4000), cv2.NORM_L2
    if name in ("sift", "akaze") and hasattr(cv2, "AKAZE_create"):
        return cv2.AKAZE_create(threshold=0.0005), cv2.NORM_HAMMING
    return cv2.ORB_create(nfeatures=4000), cv2.NORM_HAMMING


class Locator(object):
    def __init__(self, detector="akaze", max_side=960, ratio=0.8, ransac_px=3.0, min_inliers=12,
                 local_radius=2.5):
        """``max_side``: longest side (px) pictures are reduced to for matching; ``local_radius``:
        matches within this many box sizes of a box refine that box's homography."""
        self._detector, self._norm = make_detector(detector)
        self.max_side = max_side
        self.ratio = ratio
        self.ransac_px = ransac_px
        self.min_inliers = min_inliers
        self.local_radius = local_radius

    def features(self, image):
        gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        scale = min(1.0, float(self.max_side) / max(gray.shape[:2]))
        if scale < 1.0:
            gray = cv2.resize(gray, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
        keypoints, descriptors = self._detector.detectAndCompute(gray, None)
        return Features(keypoints, descriptors, scale, image.shape[:2])

    def _matches(self, ref, new):
        if ref.descriptors is None or new.descriptors is None or len(ref.keypoints) < 2 \
                or len(new.keypoints) < 2:
            return np.zeros((0, 2)), np.zeros((0, 2))
        matcher = cv2.BFMatcher(self._norm)
        pairs = matcher.knnMatch(ref.descriptors, new.descriptors, k=2)
        good = [p[0] for p in pairs if len(p) == 2 and p[0].distance < self.ratio * p[1].distance]
        src = np.array([ref.keypoints[m.queryIdx].pt for m in good], np.float64).reshape(-1, 2) / ref.scale
        dst = np.array([new.keypoints[m.trainIdx].pt for m in good], np.float64).reshape(-1, 2) / new.scale
        return src, dst

    def _homography(self, src, dst):
        if len(src) < max(4, self.min_inliers):
            return None, 0, None
        matrix, mask = cv2.findHomography(src, dst, cv2.RANSAC, self.ransac_px / 1.0, maxIters=2000,
                                          confidence=0.995)
        if matrix is None:
            return None, 0, None
        return matrix, int(mask.sum()), dst[mask.ravel() > 0]

    def locate(self, ref, new, quads):
        """Map ``quads`` (boxes in the reference picture) into the new picture.

        ``ref``/``new``: Features or images. Raises LocateError with a reason on failure.
        """
        if not isinstance(ref, Features):
            ref = self.features(ref)
        if not isinstance(new, Features):
            new = self.features(new)
        src, dst = self._matches(ref, new)
        matrix, inliers, points = self._homography(src, dst)
        if matrix is None or inliers < self.min_inliers:
            raise LocateError("too few feature matches with the reference (%d inliers, %d needed)"
                              % (inliers, self.min_inliers))
        if not _plausible(matrix):
            raise LocateError("degenerate homography against the reference")
        height, width = new.shape
        out, confidences = [], []
        for quad in quads:
            mapped, box_inliers = self._refine(np.asarray(quad, np.float64), src, dst, matrix, inliers)
            if not quad_is_convex(mapped):
                raise LocateError("target box maps to a degenerate shape")
            out.append(mapped)
            confidences.append(min(100.0, 100.0 * box_inliers / (4.0 * self.min_inliers)))
        return Located(out, matrix, inliers, len(src), confidences, points)

    def _refine(self, quad, src, dst, matrix, inliers):
        """The box through the global homography, shifted by the median residual of the matches near it.

        Parallax after a pose error moves a small region off the dominant plane mostly sideways;
        a local homography fitted to a few clustered matches on a plain panel is exact where they
        are and wild at the box (measured on the simulated yard: up to 8 px corner error against
        2-4 px for the shift), so only the shift is estimated locally.
        """
        centre = quad_center(quad)
        size = max(np.ptp(quad[:, 0]), np.ptp(quad[:, 1]))
        mapped = transform_quad(matrix, quad)
        near = np.hypot(src[:, 0] - centre[0], src[:, 1] - centre[1]) < self.local_radius * size
        if near.sum() < 4:
            return mapped, inliers
        residual = dst[near] - transform_quad(matrix, src[near])
        agree = np.hypot(residual[:, 0], residual[:, 1]) < max(0.5 * size, 4.0 * self.ransac_px)
        if agree.sum() < 4:
            return mapped, inliers
        return mapped + np.median(residual[agree], axis=0), max(inliers, int(agree.sum()))


def _plausible(matrix):
    """Reject homographies that flip, collapse or blow up the picture."""
    matrix = matrix / matrix[2, 2]
    det = np.linalg.det(matrix[:2, :2])
    return bool(0.01 < det < 100.0 and abs(matrix[2, 0]) < 0.01 and abs(matrix[2, 1]) < 0.01)
