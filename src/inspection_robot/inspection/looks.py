"""Two looks at one pointer meter: a value is confident only when two pictures agree on it.

find_scale takes a second picture of the found view right after the first (same pose, same
zoom) and read_scale reads every pointer target in both (docs/interface.md, read_scale, "Two
looks"). A needle read differently in two pictures a fraction of a second apart is being misread
in at least one of them (sensor noise, glare, a vibrating head, a hypothesis that flips), so the
pair decides how far the value is trusted.
"""
import math

from inspection_robot.inspection.readers import Reading

LOOKS_AGREE_FS = 0.01   # two looks farther apart than this share of full scale: uncertain


def _reason(reading):
    return reading.detail.get("reason", "") if reading.detail else ""


def combine_looks(first, second, full_scale, agree_fs=LOOKS_AGREE_FS):
    """One Reading from two Readings of the same pointer (``second`` None: only one look was taken,
    ``first`` is returned unchanged). A look that could not read the needle has a non-finite value.

    - both read and at most ``agree_fs`` x ``full_scale`` apart: the mean value (the looks'
      independent noise halves in variance), the lower confidence, the first look's reason or
      else the second's (a doubt either look had stays);
    - farther apart: uncertain, ``two looks disagree: <a> and <b> (<d> % FS)``, the value of the
      more confident look (the first on a tie), the lower confidence;
    - one look unreadable: the other's value, half its confidence, uncertain with the unreadable
      look's reason (``second look: needle not found ...``);
    - neither readable: the first look as it is.
    ``detail["looks"]`` = [first value, second value] (None when unreadable).
    """
    if second is None:
        return first
    if not full_scale > 0:
        raise ValueError("full scale must be positive, got %r" % (full_scale,))
    values = [first.value, second.value]
    readable = [v is not None and math.isfinite(v) for v in values]
    detail = dict(first.detail or {})
    detail["looks"] = [float(v) if ok else None for v, ok in zip(values, readable)]
    if not any(readable):
        return Reading(first.value, first.confidence, detail)
    if not all(readable):
        good, bad, name = (first, second, "second") if readable[0] else (second, first, "first")
        if good is second:
            detail = dict(second.detail or {}, looks=detail["looks"])
        detail["reason"] = "%s look: %s" % (name, _reason(bad) or "no reading")
        return Reading(good.value, good.confidence / 2.0, detail)
    apart = abs(first.value - second.value)
    confidence = min(first.confidence, second.confidence)
    if apart <= agree_fs * full_scale:
        detail["reason"] = _reason(first) or _reason(second)
        return Reading((first.value + second.value) / 2.0, confidence, detail)
    chosen = second if second.confidence > first.confidence else first
    if chosen is second:
        detail = dict(second.detail or {}, looks=detail["looks"])
    why = "two looks disagree: %.4g and %.4g (%.1f %% FS)" % (first.value, second.value,
                                                              100.0 * apart / full_scale)
    own = _reason(chosen)
    detail["reason"] = "%s; %s" % (why, own) if own else why
    return Reading(chosen.value, confidence, detail)
