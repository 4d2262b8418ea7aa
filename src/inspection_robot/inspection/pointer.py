"""Pointer gauge reader: the needle found (needle), scored (needle_confidence) and mapped on the
scale (gauge), in the dial's frame (dial_frame).

Steps, each measured on the real set's tuning part (bench/real_set.py; docs/development.md,
"Meter reading accuracy"), none chosen on the test part:
1. the dial's frame: the calibrated box, or the frontal frame the scale marks' ellipse gives
   (dial_frame.dial_from_marks);
2. the needle in the inner band of the dial (``inner``..``outer`` dial radii): its line read where
   it meets the scale circle, its confidence from its contrast, the agreement of its inner and
   outer halves and the margin over the next pointer candidate;
3. only when that reading is uncertain, the outer band (``outer_band``: a needle hidden near its
   hub, an SF6 density meter's inner plate) as a second hypothesis. Its value replaces the first
   one only when the inner band shows no needle at all, or when both agree within
   ``agree_pct_fs``; otherwise the first value stays, flagged uncertain with both values;
4. the angle on the scale: a needle resting before the first mark or past the last (on its stop
   pin, within the search margin) reads as the scale's start or end, said in
   ``detail["stop"]``;
5. the dial partly outside the picture: read as it is when its pivot and scale arc are inside,
   uncertain (confidence scaled by the share seen) otherwise;
6. with this meter's needle model (needle_model, learned at calibration: ``learn``), the line fit's
   reading checked against the model's match (``_second_opinion``): a disagreement is uncertain
   with both values. A needle hidden along half its length, or read off the scale without being
   seen along STOP_VISIBLE of it, is uncertain whatever the model says.
Dropped (no effect on the tuning part, a gross error on unseen meters): the hub search in the
picture, the re-centring on the needle's line and the hub search along the scale's axis.
"""
import math

import numpy as np

from inspection_robot.inspection.dial_frame import dial_from_marks, dial_outside
from inspection_robot.inspection.needle import ANGLE_STEP_DEG, GAUGE_SIZE, NeedleFinder, meets_circle
from inspection_robot.inspection import needle_model
from inspection_robot.inspection.needle_confidence import CLEAR_CONTRAST, UNCERTAIN_BELOW, agreement, \
    needle_confidence, rival, weak_reason
from inspection_robot.inspection.readers import ReadFailed, Reading, clip_confidence

BAND_AGREE_PCT_FS = 2.0   # the outer band's value within this of the inner band's: the same needle
HIDDEN_BELOW = 0.5        # a needle visible along less of its length (NeedleFinder.visible_share) is uncertain
STOP_VISIBLE = 0.75       # a needle read on its stop (off the scale) is seen along at least this share
NEAR_DEG = 3.0            # the line fitted at the needle model's angle: the pointer within this of it
LEARN_PCT_FS = 5.0        # calibration: the needle learned lies within this of the value typed
GENERIC = ("generic: the calibration has no needle model (apply it again with the value the meter shows "
           "to learn this meter's needle)")


class PointerReader(object):
    """Reads a pointer gauge in one box (see the module docstring for the steps)."""

    def __init__(self, size=GAUGE_SIZE, inner=0.22, outer=0.72, step_deg=ANGLE_STEP_DEG, background_deg=12.0,
                 margin_deg=8.0, reach=(0.72, 0.9), uncertain_below=UNCERTAIN_BELOW, outer_band=(0.6, 0.95),
                 agree_pct_fs=BAND_AGREE_PCT_FS):
        self.uncertain_below = uncertain_below
        self.agree_pct_fs = agree_pct_fs
        self.inner_band = NeedleFinder(size, inner, outer, step_deg, background_deg, margin_deg, reach)
        self.outer_band = None
        if outer_band:
            self.outer_band = NeedleFinder(size, outer_band[0], outer_band[1], step_deg, background_deg, margin_deg,
                                           (outer_band[1] - 0.05, outer_band[1] + 0.05))

    def needle_angle(self, image, quad, centre=(0.5, 0.5), radius=0.45, aspect=1.0, scale=None,
                     pointer_colour="", ignore_colour="", finder=None, near=None, face=None):
        """Needle angle (deg clockwise from up, about the calibrated centre) in the face's frontal
        view, a confidence and a detail dict (``reason``: why the confidence is low, "" when it is
        not). ``finder``: the band to search (the inner one by default).

        From the calibration: ``centre`` (pivot as fractions of the box width, height), ``radius``
        (dial radius as a fraction of the box width), ``aspect`` (physical width / height of the
        box, so the frontal view is not stretched), ``scale`` (the search covers its sweep plus
        the margin; None: all around), colour hints. ``near`` (angle, window, deg): the pointer within
        the window of the angle (the needle model's, the calibration's value), not the best-ranked one.
        ``face``: the finder's Face of this box when the caller already has it (it is rectified once).
        """
        finder = finder or self.inner_band
        if face is None:
            face = finder.face(image, quad, centre, radius, aspect)
        prof = finder.profile(face, finder.search_angles(scale))
        detail = {"candidates": len(prof.candidates)}
        if not prof.candidates:
            detail.update(reason="needle not found", angle=None, contrast_ratio=0.0)
            return None, 0.0, detail
        described = finder.describe(prof)
        pool = finder.ranked(described, pointer_colour, ignore_colour)
        if near is None:
            i = finder.needle_index(prof, pool[0]["index"])
        else:
            gap = np.abs((prof.angles - near[0] + 180.0) % 360.0 - 180.0)
            i = finder.needle_index(prof, int(np.argmin(gap)), window_deg=near[1])
            if prof.full[i] <= prof.base:
                detail.update(reason="no pointer within %.3g deg of %.1f deg" % (near[1], near[0]), angle=None,
                              contrast_ratio=0.0)
                return None, 0.0, detail
            pool = sorted(pool, key=lambda d: abs(d["index"] - i))
        chosen = pool[0]
        lines = finder.needle_lines(prof, face, i)
        if lines is None:
            detail.update(reason="needle not found (no continuous needle along the radius)", angle=None,
                          contrast_ratio=0.0)
            return None, 0.0, detail
        # where the needle's line meets the scale circle: near the tip, so the line's direction
        # error (a tapered or shadowed needle) hardly matters, and a pivot off the calibrated
        # centre moves the reading only by the parallax at the scale, not by a ray's full error
        angle, inner_angle, outer_angle = (meets_circle(line, face.centre, face.ring) for line in lines)
        contrast, disagreement, confidence = needle_confidence(prof, i, inner_angle, outer_angle)
        margin, reason = rival(prof, described, pool, i, finder.step_deg, finder.background_deg,
                               bool(pointer_colour or ignore_colour))
        confidence *= margin
        line = lines[0]
        foot = line[0] + np.dot(np.asarray(face.centre) - line[0], line[1]) * line[1]
        normal = np.array([-lines[2][1][1], lines[2][1][0]])
        height, width = face.bgr.shape[:2]
        detail["pointers"] = [(round(float(prof.angles[d["index"]]) % 360.0, 1), round(d["score"], 1), d["reach"],
                               d["colour"]) for d in described]
        detail.update({"angle": angle, "inner_angle": inner_angle, "outer_angle": outer_angle,
                       "contrast": float(prof.full[i] - prof.base), "contrast_ratio": float(contrast),
                       "disagreement": disagreement, "candidate_margin": round(margin, 3),
                       "colour": chosen["colour"], "reach": chosen["reach"],
                       "needle_width": finder.needle_width(prof, i, face.rad) / face.rad,
                       "outer_line_miss": float(abs(np.dot(np.asarray(face.centre) - lines[2][0], normal))) / face.rad,
                       "pivot": (float(foot[0]) / (width - 1), float(foot[1]) / (height - 1)),
                       "box_inside": round(face.inside, 3)})
        visible = finder.visible_share(face, prof, lines[0], detail["needle_width"] * face.rad)
        detail["needle_visible"] = round(visible, 3)
        if visible < HIDDEN_BELOW:
            # an object over the needle, or an object's edge taken for it: never a confident value
            confidence = min(confidence, self.uncertain_below * visible / HIDDEN_BELOW)
            hidden = "needle hidden: %.0f %% of its length not visible" % (100.0 * (1.0 - visible))
            reason = "%s; %s" % (hidden, reason) if reason else hidden
        if confidence < self.uncertain_below and not reason:
            reason = weak_reason(face.bgr, contrast, disagreement)
        detail["reason"] = reason
        return angle, clip_confidence(confidence), detail

    def read(self, image, quad, scale, centre=(0.5, 0.5), radius=0.45, aspect=1.0, pointer_colour="",
             ignore_colour="", marks=None, model=None):
        """Reading of a pointer gauge; detail["reason"] is non-empty when the reading is uncertain.
        Raises ReadFailed when no reading is possible. ``marks`` [(value, u, v)] (the scale marks'
        positions as fractions of the box): when they fit an ellipse well, the dial is read in the
        frontal frame they give (dial_from_marks). ``model``: this meter's NeedleModel, the second
        opinion (``_second_opinion``); None reads with the line fit alone and says so."""
        frame, quad, scale, centre, radius, aspect = _framed(quad, scale, centre, radius, aspect, marks)
        face = self.inner_band.face(image, quad, centre, radius, aspect)   # the line fit's and the model's
        reading = self._read_bands(image, quad, scale, centre, radius, aspect, pointer_colour, ignore_colour, face)
        if frame is not None:
            reading.detail["frame"] = dict(frame.detail, source="marks")
        elif marks:
            reading.detail["frame"] = {"source": "calibration"}
        if model is None:
            reading.detail["needle_model"] = GENERIC
        else:
            reading = self._second_opinion(reading, model, face, image, quad, scale, centre, radius, aspect,
                                           pointer_colour, ignore_colour)
        return self._outside(reading, image, quad, scale, centre, radius, aspect)

    def learn(self, image, quad, scale, value, centre=(0.5, 0.5), radius=0.45, aspect=1.0, pointer_colour="",
              ignore_colour="", marks=None):
        """This meter's NeedleModel, learned from a picture showing ``value`` (calibration: the value
        the operator reads on the meter). ReadFailed with the reason when no needle lies at that value
        (within LEARN_PCT_FS) or when the model cannot tell it from another pointer of the dial."""
        _frame, quad, scale, centre, radius, aspect = _framed(quad, scale, centre, radius, aspect, marks)
        finder = self.inner_band
        face = finder.face(image, quad, centre, radius, aspect)
        window = max(NEAR_DEG, LEARN_PCT_FS / 100.0 * scale.sweep)
        angle, _confidence, detail = self.needle_angle(image, quad, centre, radius, aspect, scale, pointer_colour,
                                                       ignore_colour, near=(scale.angle(value), window), face=face)
        if angle is None or detail["contrast_ratio"] < CLEAR_CONTRAST:
            raise ReadFailed("no needle at %.4g: %s" % (value, detail["reason"] or "nothing there stands out of the "
                                                                                   "face"))
        apart, agree = agreement(scale.value(angle), value, scale.full_scale, LEARN_PCT_FS)
        if not agree:
            raise ReadFailed("no needle at %.4g: the pointer nearest it reads %.4g (%.1f %% FS apart)"
                             % (value, scale.value(angle), apart))
        model = needle_model.learn(finder, face, angle)
        found = needle_model.match(finder, face, model, finder.search_angles(scale))
        if found.rival > needle_model.RIVAL_MATCH * found.score:
            raise ReadFailed("the needle at %.4g cannot be told from the pointer-like line at %.4g (match %.2f "
                             "against %.2f)" % (value, scale.value(found.rival_angle), found.score, found.rival))
        return model

    def _second_opinion(self, reading, model, face, image, quad, scale, centre, radius, aspect, pointer_colour,
                        ignore_colour):
        """The line fit's reading checked against this meter's needle model (needle_model.match):
        - the model does not recognise its needle: uncertain, "this meter's needle not recognised";
        - they agree within ``agree_pct_fs``: the line fit's reading (the finer of the two); a rival
          pointer the model tells apart no longer lowers its confidence;
        - they disagree: the line fitted at the model's angle (this meter's needle), uncertain
          with both values."""
        finder = self.inner_band
        detail = reading.detail
        found = needle_model.match(finder, face, model, finder.search_angles(scale))
        detail.update(needle_model="learned", model_match=round(found.score, 3), model_angle=found.angle,
                      model_rival=round(found.rival, 3))
        if found.angle is None or found.score < needle_model.MIN_MATCH:
            why = "this meter's needle not recognised (match %.2f, at least %.2f)" % (
                found.score, needle_model.MIN_MATCH)
            return _doubted(reading, why, self.uncertain_below * max(found.score, 0.0) / needle_model.MIN_MATCH)
        model_value = scale.value(found.angle)
        if math.isfinite(reading.value):
            apart, agree = agreement(reading.value, model_value, scale.full_scale, self.agree_pct_fs)
            if agree:
                return _without_rival(reading, found)
        angle, confidence, refit = self.needle_angle(image, quad, centre, radius, aspect, scale, pointer_colour,
                                                     ignore_colour, near=(found.angle, NEAR_DEG), face=face)
        value = scale.value(angle) if angle is not None else model_value
        refit.update((k, v) for k, v in detail.items() if k.startswith("model_") or k in ("needle_model", "frame"))
        if not math.isfinite(reading.value):
            why = "the line fit found no needle; this meter's needle model reads %.4g" % value
            return _doubted(Reading(value, confidence, refit), why, self.uncertain_below * 0.5)
        apart, same = agreement(reading.value, value, scale.full_scale, self.agree_pct_fs)
        if same:        # the line fit's own pointer, the model's angle a little off it
            return _without_rival(reading, found)
        why = "this meter's needle reads %.4g, the strongest line %.4g (%.1f %% FS apart)" % (
            value, reading.value, apart)
        cap = self.uncertain_below * min(1.0, self.agree_pct_fs / max(apart, 1e-9)) * 0.99
        if not needle_model.decisive(found):
            # the model itself hesitates between two pointers: the line fit's value, flagged
            detail["model_value"] = value
            return _doubted(reading, why + " (the model's match is not decisive)", cap)
        refit["line_fit_value"] = reading.value
        return _doubted(Reading(value, confidence, refit), why, cap)

    def _outside(self, reading, image, quad, scale, centre, radius, aspect):
        """The reading of a box partly outside the picture: as it is when the dial's pivot and
        scale arc are inside (the rest of the box is only face), uncertain otherwise with its
        confidence scaled by the share of them the picture shows."""
        if reading.detail.get("box_inside", 1.0) >= 1.0:
            return reading
        share = dial_outside(quad, image.shape[1], image.shape[0], centre, radius, aspect, scale)
        reading.detail["dial_outside"] = round(share, 3)
        if share <= 0.0:
            return reading
        why = "the dial's pivot or scale arc is partly outside the picture (%.0f %%)" % (100.0 * share)
        own = reading.detail.get("reason", "")
        reading.detail["reason"] = "%s; %s" % (why, own) if own else why
        return Reading(reading.value, clip_confidence(reading.confidence * (1.0 - share)), reading.detail)

    def _read_bands(self, image, quad, scale, centre, radius, aspect, pointer_colour, ignore_colour, face):
        """The inner band's reading (on ``face``, the inner band's Face), or the outer band's when the
        inner one is uncertain and the outer one confident and not contradicting it (see the module
        docstring, step 3)."""
        inner = self._read_band(self.inner_band, image, quad, scale, centre, radius, aspect, pointer_colour,
                                ignore_colour, face)
        inner.detail["band"] = "inner"
        if inner.confidence >= self.uncertain_below or self.outer_band is None:
            return inner
        outer = self._read_band(self.outer_band, image, quad, scale, centre, radius, aspect, pointer_colour,
                                ignore_colour)
        if outer.confidence < self.uncertain_below:
            return inner
        outer.detail["band"] = "outer"
        if not math.isfinite(inner.value) or inner.detail.get("contrast_ratio", 0.0) < CLEAR_CONTRAST:
            return outer        # no needle in the inner band: nothing to contradict the outer one
        apart, agree = agreement(inner.value, outer.value, scale.full_scale, self.agree_pct_fs)
        outer.detail["bands_apart_pct_fs"] = round(apart, 2)
        if agree:
            return outer
        # two hypotheses for one needle: the first value, flagged, with both
        inner.detail["bands_apart_pct_fs"] = round(apart, 2)
        inner.detail["reason"] = "inner and outer bands read %.4g and %.4g (%.1f %% FS apart); %s" % (
            inner.value, outer.value, apart, inner.detail.get("reason", ""))
        confidence = inner.confidence * min(1.0, self.agree_pct_fs / apart)
        return Reading(inner.value, clip_confidence(confidence), inner.detail)

    def _read_band(self, finder, image, quad, scale, centre, radius, aspect, pointer_colour, ignore_colour,
                   face=None):
        angle, confidence, detail = self.needle_angle(image, quad, centre, radius, aspect, scale, pointer_colour,
                                                      ignore_colour, finder, face=face)
        if angle is None:
            return Reading(float("nan"), 0.0, detail)
        if not scale.in_sweep(angle):
            # before the first mark or past the last (the search reaches margin_deg beyond them):
            # a needle resting on its stop pin; the scale's end value, said so
            over = scale.offset(angle) - scale.sweep
            under = 360.0 - scale.offset(angle)
            detail["stop"] = ("needle at rest below the first mark (%.1f deg before it)" % under if under < over
                              else "needle past the last mark (%.1f deg beyond it)" % over)
            seen = detail.get("needle_visible", 1.0)
            if seen < STOP_VISIBLE:
                # a value off the scale only from a needle visibly there, on its stop
                why = "%s, only %.0f %% of its length visible" % (detail["stop"], 100.0 * seen)
                return _doubted(Reading(scale.value(angle), confidence, detail), why, self.uncertain_below * 0.99)
        return Reading(scale.value(angle), confidence, detail)


def _framed(quad, scale, centre, radius, aspect, marks):
    """(the frontal frame the scale marks give, None when they give none: dial_from_marks; and the
    dial's quad, scale, centre, radius and aspect to read in)."""
    frame = dial_from_marks(quad, centre, radius, aspect, marks) if marks else None
    if frame is None:
        return None, quad, scale, centre, radius, aspect
    return frame, frame.quad, frame.scale, frame.centre, frame.radius, frame.aspect


def _doubted(reading, why, cap):
    """``reading`` with its confidence at most ``cap`` and ``why`` first among its reasons."""
    own = reading.detail.get("reason", "")
    reading.detail["reason"] = "%s; %s" % (why, own) if own else why
    return Reading(reading.value, clip_confidence(min(reading.confidence, cap)), reading.detail)


def _without_rival(reading, found):
    """A reading the needle model confirms: when its confidence was lowered only for a rival pointer
    (needle_confidence.rival) and the model's own rival match is clearly below its match, the
    rival's share is given back (the model knows which of the two is this meter's needle)."""
    margin = reading.detail.get("candidate_margin", 1.0)
    reason = reading.detail.get("reason", "")
    if margin >= 1.0 or not reason.startswith("two pointers") or ";" in reason \
            or not needle_model.decisive(found):
        return reading
    confidence = reading.confidence / max(margin, 0.05)
    if confidence < UNCERTAIN_BELOW:
        return reading      # weak for another reason too: the rival stays named
    reading.detail["reason"] = ""
    reading.detail["rival_settled_by_model"] = True
    return Reading(reading.value, clip_confidence(confidence), reading.detail)
