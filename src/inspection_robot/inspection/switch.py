"""Switch position by edge correlation with reference patches, and the same edge signature's
similarity of two boxes (is the box still showing the calibrated gauge?)."""
import numpy as np

from inspection_robot.lazy import lazy_import
from inspection_robot.inspection.geometry import grey, rectify
from inspection_robot.inspection.readers import Reading, clip_confidence

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load

SWITCH_SIZE = 64
# a switch in its box matches its reference at 100 (correlations ~0.98 against ~0.08); a box a
# sixth of its size off it, under 20 (test_inspection_readers)
SWITCH_MIN_CONFIDENCE = 50.0


def edge_signature(gray):
    """The smoothed gradient magnitude, zero-mean and unit-norm: the dot product of two is their
    correlation, whatever the lighting's gain and offset."""
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
        return edge_signature(grey(patch))
    return float((signature(image, quad) * signature(reference, reference_quad)).sum())


def switch_patch(image, quad):
    """Rectified grey patch of a switch box, as stored for references."""
    return grey(rectify(image, quad, SWITCH_SIZE))


def read_switch(image, quad, open_ref, closed_ref):
    """Switch position: value 1 closed, 0 open, by edge correlation with the two reference patches;
    uncertain (``detail["reason"]``) under SWITCH_MIN_CONFIDENCE: the box matches neither reference
    well or both alike."""
    sig = edge_signature(switch_patch(image, quad))
    score_open = float((sig * edge_signature(_as_gray(open_ref))).sum())
    score_closed = float((sig * edge_signature(_as_gray(closed_ref))).sum())
    margin = abs(score_closed - score_open)
    best = max(score_open, score_closed)
    confidence = 100.0 * min(1.0, margin / 0.3) * min(1.0, max(best, 0.0) / 0.5)
    value = 1.0 if score_closed > score_open else 0.0
    detail = {"open": score_open, "closed": score_closed}
    if confidence < SWITCH_MIN_CONFIDENCE:
        detail["reason"] = ("switch unclear: the box matches the closed reference %.2f and the open one %.2f "
                            "(box off the switch, or neither position)" % (score_closed, score_open))
    return Reading(value, clip_confidence(confidence), detail)


def _as_gray(patch):
    return grey(cv2.resize(np.asarray(patch), (SWITCH_SIZE, SWITCH_SIZE), interpolation=cv2.INTER_AREA))
