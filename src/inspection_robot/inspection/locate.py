"""Locating calibrated target boxes in a new picture against a reference picture.

Features (AKAZE, else ORB; SIFT when the OpenCV build has it and it is asked for) are matched
with a ratio test; a RANSAC homography maps the reference onto the new picture. Each box is then
refined with the matches near it (parallax after a pose error makes one global homography wrong
away from the dominant plane): the globally mapped box is shifted by the median residual of the
near matches that roughly agree with the global homography. Box corners TL, TR, BR, BL. Pictures
are matched at a reduced size for speed; coordinates are in the full pictures. Matching at half
size leaves each box 1-3 px off in a 1920 px picture, which on a 90 deg panel meter is up to 1 %
of its full scale: every box is then aligned at full resolution (``align``: an affine correction
by ECC image alignment of the reference's region about the box onto the new picture's).
"""
from collections import namedtuple

import numpy as np

from inspection_robot.lazy import lazy_import
from inspection_robot.inspection.geometry import grey, quad_center, quad_is_convex, transform_quad

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load

# gray: the full-resolution grey picture, for the boxes' alignment
Features = namedtuple("Features", "keypoints descriptors scale shape gray")
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
                 local_radius=2.5, align=True, align_side=600, align_max_px=0.05, align_mask=0.6):
        """``max_side``: longest side (px) pictures are reduced to for matching; ``local_radius``:
        matches within this many box sizes of a box refine that box's homography; ``align``: when
        the pictures were matched at a reduced size, align each box at full resolution (ECC, on a
        region 1.5 box sizes wide, reduced to ``align_side`` px at most), a correction moving a
        corner by more than three matching pixels or ``align_max_px`` box sizes being refused as a
        misalignment, the middle ``align_mask`` of the box left out (what changes by design).
        Chosen on the real set's tuning part and the simulated yard: without the mask the moving
        needle pulls the alignment on large dials; on pictures matched at full size it buys
        nothing and can slip (the bench's world cases at 800 px)."""
        self.align = align
        self.align_side = align_side
        self.align_max_px = align_max_px
        self.align_mask = align_mask
        self._detector, self._norm = make_detector(detector)
        self.max_side = max_side
        self.ratio = ratio
        self.ransac_px = ransac_px
        self.min_inliers = min_inliers
        self.local_radius = local_radius

    def features(self, image):
        gray = grey(image)
        scale = min(1.0, float(self.max_side) / max(gray.shape[:2]))
        if scale < 1.0:
            gray = cv2.resize(gray, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
        keypoints, descriptors = self._detector.detectAndCompute(gray, None)
        return Features(keypoints, descriptors, scale, image.shape[:2],
                        grey(image))

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

    def locate(self, ref, new, quads, align=None):
        """Map ``quads`` (boxes in the reference picture) into the new picture.

        ``ref``/``new``: Features or images; ``align``: align each box at full resolution (default:
        the Locator's ``align``; off for a box as large as the picture, where it buys nothing).
        Raises LocateError with a reason on failure.
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
            coarse = 1.0 / min(ref.scale, new.scale)     # one matching pixel, in picture pixels
            if (self.align if align is None else align) and coarse > 1.0:
                mapped = self._align(ref.gray, new.gray, np.asarray(quad, np.float64), mapped, 3.0 * coarse)
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

    def _align(self, ref_gray, new_gray, quad, mapped, max_move):
        """``mapped`` corrected by the affine map that best aligns (ECC: zero-mean normalised, so a
        change of lighting does not matter) the reference's region about ``quad``, warped into the
        new picture through ``quad`` -> ``mapped``, with the new picture's region about ``mapped``.
        The box's middle, where the target changes (a needle), is left out. ``mapped`` unchanged
        when the alignment does not converge or moves a corner farther than ``max_move`` px (three
        matching pixels: what the matching at reduced size can have missed) or ``align_max_px``
        box sizes."""
        size = max(np.ptp(mapped[:, 0]), np.ptp(mapped[:, 1]))
        height, width = new_gray.shape[:2]
        c = quad_center(mapped)
        x0, y0 = int(max(0, c[0] - 0.75 * size)), int(max(0, c[1] - 0.75 * size))
        x1, y1 = int(min(width, c[0] + 0.75 * size)), int(min(height, c[1] + 0.75 * size))
        if x1 - x0 < 16 or y1 - y0 < 16:
            return mapped
        k = min(1.0, float(self.align_side) / max(x1 - x0, y1 - y0))
        to_crop = np.array([[k, 0, -k * x0], [0, k, -k * y0], [0, 0, 1.0]])
        moved = cv2.getPerspectiveTransform(np.asarray(quad, np.float32), np.asarray(mapped, np.float32))
        out_size = (max(8, int(round(k * (x1 - x0)))), max(8, int(round(k * (y1 - y0)))))
        template = cv2.warpPerspective(ref_gray, to_crop.dot(moved), out_size, flags=cv2.INTER_LINEAR)
        crop = cv2.warpAffine(new_gray, to_crop[:2], out_size, flags=cv2.INTER_AREA if k < 1.0 else cv2.INTER_LINEAR)
        warp = np.eye(2, 3, dtype=np.float32)
        # what changes by design (a needle, a lamp's disc, a switch's lever) sits in the box's
        # middle: left out, so the alignment follows the dial's rim, ticks and the panel
        mask = np.full((out_size[1], out_size[0]), 255, np.uint8)
        middle = transform_quad(to_crop, quad_center(mapped) + self.align_mask * (mapped - quad_center(mapped)))
        cv2.fillConvexPoly(mask, np.round(middle).astype(np.int32), 0)
        try:
            criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-6)
            _, warp = cv2.findTransformECC(template.astype(np.float32), crop.astype(np.float32), warp,
                                           cv2.MOTION_AFFINE, criteria,
                                           mask if self.align_mask > 0 else None, 5)
        except cv2.error:      # did not converge: the matched box stands
            return mapped
        # template pixel x (the box as mapped, in the crop) lies at warp·x in the new picture's crop
        correction = np.linalg.inv(to_crop).dot(np.vstack([warp, [0.0, 0.0, 1.0]])).dot(to_crop)
        aligned = transform_quad(correction, mapped)
        if np.max(np.hypot(*(aligned - mapped).T)) > min(max_move, self.align_max_px * size):
            return mapped
        return aligned


def _plausible(matrix):
    """Reject homographies that flip, collapse or blow up the picture."""
    matrix = matrix / matrix[2, 2]
    det = np.linalg.det(matrix[:2, :2])
    return bool(0.01 < det < 100.0 and abs(matrix[2, 0]) < 0.01 and abs(matrix[2, 1]) < 0.01)


def view_shift(first, second, side=480):
    """How far (px of ``first``) the view moved between two pictures of it: the phase correlation
    of the two, grey and ``side`` px wide. A view at rest gives a fraction of a pixel."""
    scale = min(1.0, float(side) / max(first.shape[:2]))
    size = (int(round(first.shape[1] * scale)), int(round(first.shape[0] * scale)))
    small = [cv2.resize(grey(image), size, interpolation=cv2.INTER_AREA).astype(np.float32)
             for image in (first, second)]
    (dx, dy), _response = cv2.phaseCorrelate(small[0], small[1])
    return float(np.hypot(dx, dy)) / scale
