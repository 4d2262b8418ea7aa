"""The calibration tool's library: turns target descriptions into preset_calib_info.ini + zoomX.xml.

A target description (a dict, e.g. one entry of the YAML the command-line tool reads, or what a
web page would post) has ``kind`` (pointer | lamp | switch | thermal), ``box`` (8 numbers: TL,
TR, BR, BL in zoom0.jpg) and the kind's parameters (see preset.Target). Switch targets give
``open_picture`` / ``closed_picture``: pictures of the same view with the switch open / closed,
from which reference patches are cut; lamps may give ``on_picture`` / ``off_picture`` likewise.
Boxes in the wider zoom pictures follow from the zoom levels and the camera's optics (the pictures
share the optical centre).
"""
import os

import cv2
import numpy as np

from inspection_robot.inspection.geometry import quad_inside, quad_is_convex
from inspection_robot.inspection.preset import PresetError, Target, load_info, write_calibration
from inspection_robot.inspection.readers import lamp_patch, switch_patch


def derive_zoom_boxes(box0, zoom_levels, optics, width, height):
    """{zoom index: quad} of a box given in zoom0 for every zoom picture (pure zoom about the centre)."""
    box0 = np.asarray(box0, np.float64).reshape(4, 2)
    centre = np.array([(width - 1) / 2.0, (height - 1) / 2.0])
    f0 = optics.focal_px(zoom_levels[0], width)
    return dict((k, centre + (box0 - centre) * optics.focal_px(level, width) / f0)
                for k, level in enumerate(zoom_levels))


def _picture_size(preset_dir, info):
    if info.width > 0 and info.height > 0:
        return info.width, info.height
    image = cv2.imread(os.path.join(preset_dir, "zoom0.jpg"))
    if image is None:
        raise PresetError("zoom0.jpg missing or unreadable in %s" % preset_dir)
    return image.shape[1], image.shape[0]


def build_targets(preset_dir, specs, optics):
    """Validate ``specs`` and return Target objects (writing switch reference patches)."""
    info = load_info(preset_dir)
    width, height = _picture_size(preset_dir, info)
    if not specs:
        raise PresetError("no targets given")
    targets = []
    for i, spec in enumerate(specs):
        spec = dict(spec)
        kind = spec.pop("kind", None)
        try:
            box = np.asarray(spec.pop("box"), np.float64).reshape(4, 2)
        except (KeyError, ValueError) as err:
            raise PresetError("target %d: box must be 8 numbers TL,TR,BR,BL (%s)" % (i, err))
        if not quad_is_convex(box):
            raise PresetError("target %d: box is not a convex TL,TR,BR,BL quad" % i)
        if not quad_inside(box, width, height):
            raise PresetError("target %d: box lies outside the %dx%d picture" % (i, width, height))
        states = {"switch": ("open", "closed"), "lamp": ("on", "off")}.get(kind, ())
        if kind == "lamp" and not any(spec.get(state + "_picture") for state in states):
            states = ()   # lamp references are optional
        for state in states:
            picture = spec.pop(state + "_picture", None)
            image = cv2.imread(picture) if picture else None
            if image is None:
                raise PresetError("target %d: %s_picture missing or unreadable: %s" % (i, state, picture))
            name = "target_%d_%s.png" % (i, state)
            patch = switch_patch(image, box) if kind == "switch" else lamp_patch(image, box)
            cv2.imwrite(os.path.join(preset_dir, name), patch)
            spec[state + "_reference"] = name
        name = str(spec.pop("name", ""))
        try:
            targets.append(Target(kind, derive_zoom_boxes(box, info.zoom_levels, optics, width, height),
                                  name=name, **spec))
        except (KeyError, TypeError, ValueError) as err:
            raise PresetError("target %d (%s): bad or missing parameter: %s" % (i, kind, err))
    return info, targets


def calibrate(preset_dir, specs, optics):
    """Write the calibration of ``preset_dir``; returns the Target list. Raises PresetError."""
    info, targets = build_targets(preset_dir, specs, optics)
    write_calibration(preset_dir, targets, info)
    return targets
