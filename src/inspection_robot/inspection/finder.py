"""Meter finding without ROS: restore a preset's view, locate its targets, re-centre the head.

The head, camera and thermal imager are reached through a ``Head`` object (the find_scale node
implements it with terrace_control / camera_control / infrared_control; tests and the bench
with the simulated renderer). Steps for find_scale | find_foreign | find_both:

1. pan = recorded pan + (recorded - current robot heading), tilt and zoom as recorded;
2. capture at the final zoom (zoom0 level) as ``zoom0_<stamp>_<xx>.jpg`` (xx = PTZ moves so far)
   and locate every target against zoom0.jpg; if that fails, step out through the wider
   reference pictures (zoom1.jpg ...) until one matches and aim the head at the targets from it;
3. while the targets sit farther than ``centre_tolerance`` (fraction of the picture) from where
   they were in the reference, or outside the picture (a pointer's box may reach out of it when
   its dial's pivot and scale arc are inside: readable_in), turn the head by the pixel offset
   converted to angles through the field of view, up to ``max_moves`` moves;
4. presets with a pointer target: a second picture at once from the same pose,
   ``zoom0_<stamp>_<xx>_look2.jpg``, for read_scale's second look (inspection.looks); when it
   shows the view moved (the robot or the head still settling), the targets are located in it, it
   becomes the found picture (``zoom0_<stamp>_<xx>_still<k>.jpg``) and one more is taken;
5. thermal presets: thermal picture + radiometric frame, boxes moved by the same angles;
   foreign detection: one more picture at the first wider zoom.
"""
import os
from collections import namedtuple

import numpy as np

from inspection_robot.lazy import lazy_import
from inspection_robot.inspection.gauge import angle_diff
from inspection_robot.inspection.dial_frame import dial_outside
from inspection_robot.inspection.geometry import flat_from_quads, quad_center, quad_inside, transform_quad
from inspection_robot.inspection.locate import LocateError, view_shift
from inspection_robot.interface import FIND_GOAL_BOTH, FIND_GOAL_FOREIGN

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load

# two pictures of a view at rest differ by a fraction of a pixel; in simulated patrols 4 of 762
# second looks were 45-83 px over (1920 px wide) after the robot's arrival
STILL_SHIFT = 0.003   # share of the picture's width
STILL_TRIES = 3       # pictures taken for a second look before the view is given up as moving

FindResult = namedtuple("FindResult", "filename infrared_filename foreign_filename roi_vertex infrared_roi_vertex "
                                      "moves second_filename")


class FindError(Exception):
    """Finding failed; the message is the reason returned in the action result."""


class Cancelled(Exception):
    """The goal was cancelled (preempted)."""


class Head(object):
    """What the finder needs from the robot; every method raises FindError on failure."""

    def set_angles(self, pan_deg, tilt_deg):
        raise NotImplementedError

    def set_zoom(self, zoom):
        raise NotImplementedError

    def capture(self, path):
        """Take a visible picture into ``path`` and return it as a BGR array."""
        raise NotImplementedError

    def capture_thermal(self, picture_path, frame_path):
        raise NotImplementedError


class ThermalGeometry(object):
    """Fixed thermal lens next to the visible camera: focal length in px, picture size, lens offset.

    ``offset_px`` (dx, dy): where the visible camera's optical axis lands in the thermal picture,
    relative to the thermal picture's centre (0, 0 when both lenses are aligned, as in simulation;
    on a robot it is measured once by pointing both at one distant hot object).
    """

    def __init__(self, focal_px, width, height, offset_px=(0.0, 0.0)):
        self.focal_px, self.width, self.height = float(focal_px), int(width), int(height)
        self.offset = np.asarray(offset_px, np.float64).reshape(2)

    def from_visible(self, points, focal_px, width, height):
        """Visible picture pixels (N, 2) at focal length ``focal_px`` -> thermal picture pixels."""
        c_v = np.array([(width - 1) / 2.0, (height - 1) / 2.0])
        c_t = np.array([(self.width - 1) / 2.0, (self.height - 1) / 2.0]) + self.offset
        return c_t + (np.asarray(points, np.float64).reshape(-1, 2) - c_v) * (self.focal_px / float(focal_px))

    def to_visible(self, points, focal_px, width, height):
        """The inverse of ``from_visible``."""
        c_v = np.array([(width - 1) / 2.0, (height - 1) / 2.0])
        c_t = np.array([(self.width - 1) / 2.0, (self.height - 1) / 2.0]) + self.offset
        return c_v + (np.asarray(points, np.float64).reshape(-1, 2) - c_t) * (float(focal_px) / self.focal_px)


def readable_in(target, quad, shape):
    """True when ``target``'s box ``quad`` can be read in a picture of ``shape``: the box inside the
    picture, or for a pointer its dial's pivot and scale arc inside (the box's corners beyond
    the dial are only face; docs/interface.md, read_scale, "A box partly outside the picture")."""
    height, width = shape[:2]
    if quad_inside(quad, width, height):
        return True
    if target.kind != "pointer":
        return False
    p = target.params
    return dial_outside(quad, width, height, p.get("centre", (0.5, 0.5)), p.get("radius", 0.45),
                        p.get("aspect", 1.0), target.scale) == 0.0


def _readable(preset, quads, shape):
    """Every target of ``preset`` readable at its found box in a picture of ``shape`` (readable_in)."""
    return all(readable_in(t, q, shape) for t, q in zip(preset.targets, quads))


class Finder(object):
    def __init__(self, head, optics, locator, picture_root, max_moves=3, centre_tolerance=0.05,
                 thermal=None, is_cancelled=lambda: False, feedback=lambda code, data: None):
        self.head = head
        self.optics = optics
        self.locator = locator
        self.picture_root = picture_root
        self.max_moves = int(max_moves)
        self.centre_tolerance = float(centre_tolerance)
        self.thermal = thermal
        self.is_cancelled = is_cancelled
        self.feedback = feedback
        self._ref_cache = {}

    def _check_cancel(self):
        if self.is_cancelled():
            raise Cancelled()

    def restore(self, preset, heading_correction_deg=0.0):
        """Point the head and zoom as recorded (pan corrected by the heading difference)."""
        info = preset.info
        pan = angle_diff(info.pan_deg + heading_correction_deg, 0.0)
        self.head.set_angles(pan, info.tilt_deg)
        self.head.set_zoom(info.zoom_levels[0])
        return pan, info.tilt_deg

    def _reference(self, preset, k, read_image):
        key = (preset.path, k)
        if key not in self._ref_cache:
            image = read_image(preset.picture(k))
            if image is None:
                raise FindError("reference picture %s missing or unreadable" % preset.picture(k))
            self._ref_cache = {key: self.locator.features(image)}
        return self._ref_cache[key]

    def _angles_between(self, zoom, shape, from_px, to_px):
        """Pan/tilt change (deg) that moves what is at ``from_px`` to ``to_px`` in the picture."""
        h, w = shape[:2]
        c = ((w - 1) / 2.0, (h - 1) / 2.0)
        pan_a, tilt_a = self.optics.pixel_to_angles(zoom, from_px[0] - c[0], c[1] - from_px[1], w, h)
        pan_b, tilt_b = self.optics.pixel_to_angles(zoom, to_px[0] - c[0], c[1] - to_px[1], w, h)
        return pan_a - pan_b, tilt_a - tilt_b

    def find(self, preset, kind, heading_correction_deg, stamp, read_image):
        """Run find_scale | find_foreign | find_both; returns FindResult or raises FindError/Cancelled."""
        if not preset.targets:
            raise FindError("preset has no calibrated target")
        folder = os.path.join(self.picture_root, preset.preset_id)
        os.makedirs(folder, exist_ok=True)
        pan, tilt = self.restore(preset, heading_correction_deg)
        self.feedback("0", {"pan": round(pan, 2), "tilt": round(tilt, 2), "zoom": preset.info.zoom_levels[0],
                            "heading_correction_deg": round(heading_correction_deg, 2)})
        levels = preset.info.zoom_levels
        ref_quads = [t.boxes[0] for t in preset.targets]
        ref_centre = np.mean([quad_center(q) for q in ref_quads], axis=0)
        moves = 0
        last = None
        while True:
            self._check_cancel()
            self.feedback("1", {"moves": moves})
            path = os.path.join(folder, "zoom0_%s_%02d.jpg" % (stamp, moves))
            image = self.head.capture(path)
            try:
                quads = self._locate(preset, image, read_image)
            except LocateError as err:
                quads = None
                reason = str(err)
            if quads is not None:
                inside = _readable(preset, quads, image.shape)
                centre = np.mean([quad_center(q) for q in quads], axis=0)
                offset = np.abs(centre - ref_centre) / [image.shape[1], image.shape[0]]
                last = (path, quads, image) if inside else last
                if inside and (offset.max() <= self.centre_tolerance or moves >= self.max_moves):
                    break
                if moves >= self.max_moves:
                    raise FindError("targets still outside the picture after %d PTZ moves" % moves)
                d_pan, d_tilt = self._angles_between(levels[0], image.shape, centre, ref_centre)
            else:
                if moves >= self.max_moves:
                    raise FindError("target not found after %d PTZ moves: %s" % (moves, reason))
                d_pan, d_tilt = self._coarse(preset, folder, stamp, moves, read_image, reason)
                self.head.set_zoom(levels[0])
            pan, tilt = angle_diff(pan + d_pan, 0.0), min(max(tilt + d_tilt, -90.0), 90.0)
            self.head.set_angles(pan, tilt)
            moves += 1
        filename, quads, image = last
        second_filename = ""
        if kind != FIND_GOAL_FOREIGN and any(t.kind == "pointer" for t in preset.targets):
            self._check_cancel()
            filename, quads, image, second_filename = self._second_look(preset, filename, quads, image, read_image)
        roi, shape = flat_from_quads(quads), image.shape
        infrared_filename, infrared_roi = "", []
        if preset.info.infrared and self.thermal is not None:
            self._check_cancel()
            infrared_filename, infrared_roi = self._thermal(preset, folder, stamp, moves, quads, shape)
        foreign_filename = ""
        if kind in (FIND_GOAL_FOREIGN, FIND_GOAL_BOTH):
            self._check_cancel()
            k = 1 if len(levels) > 1 else 0
            self.head.set_zoom(levels[k])
            foreign_filename = os.path.join(folder, "zoom%d_%s_%02d.jpg" % (k, stamp, moves))
            self.head.capture(foreign_filename)
            self.head.set_zoom(levels[0])
        if kind == FIND_GOAL_FOREIGN:
            roi, filename = [], ""
        return FindResult(filename, infrared_filename, foreign_filename, roi, infrared_roi, moves, second_filename)

    def _second_look(self, preset, filename, quads, image, read_image):
        """(filename, quads, image, second): a second picture of the found view for read_scale's two
        looks (inspection.looks), taken at once, so the found boxes hold for it too. When it shows
        the view moved (more than STILL_SHIFT: the robot or the head still settling), the targets
        are located in it, it becomes the found picture and one more is taken; a view still moving
        after STILL_TRIES pictures, or whose targets are lost, gives no second look ("")."""
        base, ext = os.path.splitext(filename)
        for attempt in range(1, STILL_TRIES + 1):
            second = "%s_look2%s" % (os.path.splitext(filename)[0], ext)
            look = self.head.capture(second)
            if view_shift(image, look) <= STILL_SHIFT * image.shape[1]:
                return filename, quads, image, second
            try:
                moved = self._locate(preset, look, read_image)
            except LocateError:
                break
            if not _readable(preset, moved, look.shape):
                break
            filename = "%s_still%d%s" % (base, attempt, ext)
            os.replace(second, filename)
            quads, image = moved, look
        return filename, quads, image, ""

    def _locate(self, preset, image, read_image):
        """The preset's target boxes found in ``image`` against its final zoom's reference; LocateError."""
        return self.locator.locate(self._reference(preset, 0, read_image), image,
                                   [t.boxes[0] for t in preset.targets]).quads

    def _coarse(self, preset, folder, stamp, moves, read_image, reason):
        """Step out through the wider references; the head turn that brings the targets back."""
        levels = preset.info.zoom_levels
        for k in range(1, len(levels)):
            self._check_cancel()
            self.head.set_zoom(levels[k])
            image = self.head.capture(os.path.join(folder, "zoom%d_%s_%02d.jpg" % (k, stamp, moves)))
            quads_k = [t.boxes[k] for t in preset.targets if k in t.boxes]
            if len(quads_k) != len(preset.targets):
                continue
            try:
                located = self.locator.locate(self._reference(preset, k, read_image), image, quads_k)
            except LocateError:
                continue
            centre = np.mean([quad_center(q) for q in located.quads], axis=0)
            ref_centre = np.mean([quad_center(q) for q in quads_k], axis=0)
            return self._angles_between(levels[k], image.shape, centre, ref_centre)
        raise FindError("target not found at the final zoom (%s) nor in any wider reference picture" % reason)

    def _thermal(self, preset, folder, stamp, moves, quads, shape):
        """Thermal picture + frame; thermal boxes moved like their visible boxes.

        Both lenses share the head (same centre of projection up to the lens offset), so a thermal
        pixel and a visible pixel are related by the ratio of focal lengths about the optical axes.
        The recorded thermal box is taken into the reference visible picture, carried by the
        homography from the reference box to the box found now (exact for the target's plane,
        parallax and perspective included), and taken back into the thermal picture.
        """
        picture = os.path.join(folder, "thermal_%s_%02d.jpg" % (stamp, moves))
        frame = os.path.join(folder, "thermal_%s_%02d.png" % (stamp, moves))
        self.head.capture_thermal(picture, frame)
        height, width = shape[:2]
        focal = self.optics.focal_px(preset.info.zoom_levels[0], width)
        out = []
        for target, quad in zip(preset.targets, quads):
            if target.kind != "thermal":
                continue
            moved = cv2.getPerspectiveTransform(np.asarray(target.boxes[0], np.float32),
                                                np.asarray(quad, np.float32))
            ref = self.thermal.to_visible(np.reshape(target.params["thermal_box"], (4, 2)), focal, width, height)
            now = transform_quad(moved, ref)
            out.extend(flat_from_quads([self.thermal.from_visible(now, focal, width, height)]))
        return frame, out
