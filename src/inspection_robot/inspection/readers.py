"""What every reader of a target box returns, and how it refuses.

The readers, one module each: pointer (a pointer gauge: dial_frame, needle, needle_confidence),
lamp (an indicator lamp), switch (a switch's position; the box-still-shows-the-gauge check),
thermal_max (the hottest pixel of a thermal box, an ambient box's median). Each takes the picture
and the target's quad (TL, TR, BR, BL in picture pixels) and returns a Reading(value, confidence 0..100, detail).
Confidence comes from measurable evidence (contrast, agreement of two estimates, margin between
references), never a constant.
"""
from collections import namedtuple

Reading = namedtuple("Reading", "value confidence detail")


def clip_confidence(value):
    return float(min(max(value, 0.0), 100.0))


class ReadFailed(ValueError):
    """The picture cannot give a reading at all (blank, overexposed, not the gauge); the message says why."""
