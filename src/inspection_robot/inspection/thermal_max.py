"""Thermal box reader: the hottest valid pixel of a radiometric frame inside the box, or the
median of an ambient reference box (DL/T 664's T0 is the reference body's temperature, and the
hottest pixel of a box a little off that body is the warm equipment around it)."""
import numpy as np

from inspection_robot.lazy import lazy_import
from inspection_robot.inspection.geometry import polygon_mask
from inspection_robot.inspection.readers import Reading, clip_confidence
from inspection_robot.thermal.diagnosis import AMBIENT

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load


def read_thermal_max(frame, quad, phase=""):
    """Maximum temperature (deg C) of a radiometric frame inside the quad; for a box whose calibrated
    ``phase`` is the ambient reference, the median (half its pixels may fall off the plate and it
    still reads the plate).

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
    reference = phase == AMBIENT
    value = float(np.median(finite)) if reference else float(finite.max())
    return Reading(value, clip_confidence(confidence),
                   {"pixels": int(finite.size), "statistic": "median" if reference else "max"})
