"""How much a needle reading is worth: confidence from measured agreement, and why it is low.

One job: score what needle.NeedleFinder found. Every figure comes from a measurement of the picture
(the needle's contrast against the other directions, the agreement of its inner and outer halves,
the margin over the next pointer candidate, the agreement of two bands); none is a fixed cap. A
reading under ``UNCERTAIN_BELOW`` carries the reason read_scale reports (``uncertain: box <i>:
<why>``).
"""
import math

import numpy as np

from inspection_robot.inspection.gauge import angle_diff
from inspection_robot.inspection.geometry import grey


UNCERTAIN_BELOW = 50.0    # confidence under which a reading is reported "uncertain" with its reason
CLEAR_CONTRAST = 1.5      # contrast ratio under which no needle stands out of the face
RIVAL_SHARE = 0.6         # another pointer scoring this share of the chosen one's is a rival


def needle_confidence(prof, i, inner_angle, outer_angle):
    """(contrast ratio, inner/outer disagreement in deg, confidence 0..100) of the needle at index
    ``i``: the contrast over the profile's spread (2.5: full marks), times the agreement of the
    lines fitted to the needle's inner and outer halves (1/e at 10 deg)."""
    spread = float(np.percentile(prof.full, 90) - prof.base) + 1.0
    contrast = (prof.full[i] - prof.base) / max(spread, 1.0)
    disagreement = abs(angle_diff(inner_angle, outer_angle))
    return contrast, disagreement, 100.0 * min(1.0, contrast / 2.5) * math.exp(-disagreement / 10.0)


def rival(prof, described, pool, i, step_deg, background_deg, hinted):
    """(margin factor 0..1, reason) for another pointer nearly as strong as the chosen one that
    colour hints do not tell apart: the factor is 1 - its score's share of the chosen one's (the
    candidate margin), the reason "two pointers ..."; (1.0, "") when there is none. A rival is
    another pointer: not the same needle's other edge, nor its counterweight (opposite, falling
    short of the scale)."""
    chosen, angles = pool[0], prof.angles
    rivals = [d for d in pool[1:] if d["score"] > RIVAL_SHARE * chosen["score"]
              and abs(d["index"] - i) * step_deg > 2.0 * background_deg
              and not (abs(abs(angle_diff(angles[d["index"]], angles[i])) - 180.0) < 15.0
                       and d["reach"] < 0.5 * chosen["reach"])]
    hinted = hinted and any(d["colour"] != chosen["colour"] for d in described)
    if not rivals or hinted:
        return 1.0, ""
    share = min(1.0, rivals[0]["score"] / max(chosen["score"], 1e-9))
    gap = abs(angle_diff(angles[rivals[0]["index"]], angles[i]))
    return 1.0 - share, "two pointers %.0f deg apart (set pointer_colour / ignore_colour in the calibration)" % gap


def weak_reason(face_bgr, contrast, disagreement):
    """Why a confidence is low when no rival pointer explains it."""
    glare = float((grey(face_bgr) >= 245).mean())
    if glare > 0.05:
        return "glare over %.0f %% of the dial" % (100.0 * glare)
    if contrast < CLEAR_CONTRAST:
        return "needle not found (no clear needle against the face)"
    return "inner and outer needle halves disagree by %.1f deg" % disagreement


def agreement(primary_value, other_value, full_scale, tolerance_pct_fs):
    """How far two hypotheses' values lie apart (% FS) and whether that is within ``tolerance_pct_fs``."""
    apart = 100.0 * abs(primary_value - other_value) / full_scale
    return apart, apart <= tolerance_pct_fs
