"""Simulation helpers of the inspection pipeline: a rendered head and calibration from ground truth.

``RenderedHead`` implements inspection.finder.Head on the camera team's renderer (robot pose,
pan/tilt, zoom -> picture), so finding and reading run end to end without ROS. ``world_specs``
turns the world's ground truth into calibration target descriptions (inspection.calibration),
which is how the calibration tool calibrates automatically in simulation
(``calibrate_from_world``, the CLI's ``--from-world``).
"""
import math
import os
import shutil
import tempfile

import cv2
import numpy as np

from inspection_robot.inspection.calibration import SelfCheck, calibrate
from inspection_robot.inspection.preset import PresetError, load_info
from inspection_robot.camera.optics import focal_for_hfov
from inspection_robot.sim.render import PinholeCamera, Renderer, ThermalRenderer, ground_truth
from inspection_robot.sim.world import DISPLAY_WINDOW
from inspection_robot.thermal.diagnosis import AMBIENT

MIN_BOX_PX = 24.0


class RenderedHead(object):
    """A pan/tilt/zoom camera (and thermal imager) on the robot, rendered from the simulated world."""

    def __init__(self, renderer, optics, pose, sensor_height, width, height, thermal_renderer=None,
                 thermal_size=(384, 288), thermal_hfov_deg=25.0):
        self.renderer = renderer
        self.optics = optics
        self.pose = tuple(pose)
        self.sensor_height = sensor_height
        self.width, self.height = int(width), int(height)
        self.pan_deg, self.tilt_deg, self.zoom = 0.0, 0.0, optics.min_zoom
        self.thermal_renderer = thermal_renderer
        self.thermal_size = thermal_size
        self.thermal_focal = focal_for_hfov(thermal_size[0], thermal_hfov_deg)
        self.moves = 0

    def camera(self):
        return PinholeCamera.from_pose(self.pose, math.radians(self.pan_deg), math.radians(self.tilt_deg),
                                       self.sensor_height, self.optics.focal_px(self.zoom, self.width),
                                       self.width, self.height)

    def thermal_camera(self):
        return PinholeCamera.from_pose(self.pose, math.radians(self.pan_deg), math.radians(self.tilt_deg),
                                       self.sensor_height, self.thermal_focal, *self.thermal_size)

    def set_angles(self, pan_deg, tilt_deg):
        self.pan_deg, self.tilt_deg = float(pan_deg), float(tilt_deg)
        self.moves += 1

    def set_zoom(self, zoom):
        self.zoom = min(max(float(zoom), self.optics.min_zoom), self.optics.max_zoom)

    def capture(self, path):
        image = self.renderer.render(self.camera())
        if path:
            cv2.imwrite(path, image, [cv2.IMWRITE_JPEG_QUALITY, 92])
        return image

    def capture_thermal(self, picture_path, frame_path):
        frame = self.thermal_renderer.render(self.thermal_camera())
        counts = np.clip(np.round((frame.astype(np.float64) + 273.15) * 100.0), 0, 65535).astype(np.uint16)
        cv2.imwrite(frame_path, counts)
        scaled = cv2.normalize(frame, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
        cv2.imwrite(picture_path, cv2.applyColorMap(scaled, cv2.COLORMAP_INFERNO))
        return frame


def _box_ok(corners, width, height):
    c = np.asarray(corners)
    return bool(np.all(c >= 0) and np.all(c[:, 0] < width) and np.all(c[:, 1] < height)
                and max(np.ptp(c[:, 0]), np.ptp(c[:, 1])) >= MIN_BOX_PX)


def world_specs(world, head, switch_picture_path=None, hot_spot_box_px=None):
    """Calibration target descriptions for every face (and hot spot) the head sees well now.

    Switches (and lamps) are rendered open and closed (on and off) into
    ``switch_picture_path % (face, state)`` for their references; without it switches are left out
    and lamps have no references. Thermal hot spots need ``head.thermal_renderer``.
    """
    camera = head.camera()
    truth = ground_truth(world, camera)
    specs = []
    for face_id in sorted(truth["faces"]):
        entry = truth["faces"][face_id]
        if not entry["visible"] or not _box_ok(entry["corners"], camera.width, camera.height):
            continue
        face = world.faces[face_id]
        spec = {"kind": None, "box": np.asarray(entry["corners"]).reshape(-1).tolist(), "name": face_id}
        if face.type == "gauge":
            fx, fy, radius_m = face.dial_layout()
            spec.update(kind="pointer", centre=[fx, fy], radius=radius_m / face.quad.width,
                        aspect=face.quad.width / face.quad.height, start_angle=face.start_angle,
                        end_angle=face.end_angle, start_value=face.range[0], end_value=face.range[1],
                        unit=face.unit)
            if face.drag is not None:
                spec["ignore_colour"] = "red"     # the operator marks the red drag pointer as one to leave alone
        elif face.type == "display":
            left, top, right, bottom = DISPLAY_WINDOW
            window = [face.quad.point(u, v) for u, v in ((left, top), (right, top), (right, bottom), (left, bottom))]
            corners, _depth = camera.project(np.array(window))
            spec.update(kind="digital", box=np.asarray(corners).reshape(-1).tolist(), shown=face.display_text(),
                        unit=face.spec.get("unit", ""))
            if face.spec.get("counter"):
                spec["counter"] = True
            if face.style == "drum":
                spec["style"] = "drum"
        elif face.type == "lamp" and switch_picture_path is None:
            spec.update(kind="lamp", colour=face.color)
        else:
            if switch_picture_path is None:
                continue
            state = face.value
            for name in (("on", "off") if face.type == "lamp" else ("open", "closed")):
                face.set_value(name)
                path = switch_picture_path % (face_id.replace("/", "_"), name)
                cv2.imwrite(path, head.renderer.render(camera))
                spec[name + "_picture"] = path
            face.set_value(state)
            spec["kind"] = face.type
            if face.type == "lamp":
                spec["colour"] = face.color
        specs.append(spec)
    if head.thermal_renderer is not None:
        tcam = head.thermal_camera()
        ttruth = ground_truth(world, tcam)["hot_spots"]
        for spot_id in sorted(truth["hot_spots"]):
            vis, therm = truth["hot_spots"][spot_id], ttruth[spot_id]
            if not (vis["visible"] and therm["visible"]):
                continue
            r = max(vis["radius_px"] * 2.0, MIN_BOX_PX / 2.0)
            calibration = world.hot_spots[spot_id].calibration
            if calibration.get("phase") == AMBIENT:   # a reference plate: its core, not the warmer surface around
                rt = therm["radius_px"] * 0.6
            else:
                rt = hot_spot_box_px or max(therm["radius_px"] * 2.0, 4.0)
            (u, v), (ut, vt) = vis["center"], therm["center"]
            box = [u - r, v - r, u + r, v - r, u + r, v + r, u - r, v + r]
            tbox = [ut - rt, vt - rt, ut + rt, vt - rt, ut + rt, vt + rt, ut - rt, vt + rt]
            if _box_ok(np.reshape(box, (4, 2)), camera.width, camera.height) and \
                    _box_ok(np.reshape(tbox, (4, 2)), tcam.width, tcam.height):
                specs.append(dict(calibration, kind="thermal", box=box, thermal_box=tbox, name=spot_id))
    return specs


def calibrate_from_world(preset_dir, world, optics, thermal_hfov_deg=25.0, thermal_size=(384, 288), names=None,
                         seed=5, check=None, true_pose=None):
    """Calibrate a recorded preset from the world's ground truth (the calibration tool's --from-world).

    The view is rebuilt from preset.ini (robot pose, pan/tilt, zoom, picture size), or from
    ``true_pose`` (x, y, yaw) when given: preset.ini holds the pose the robot's localizer reported,
    a few centimetres and tenths of a degree from where the simulator rendered the picture, enough
    to shift a gauge's calibrated centre and skew its readings by percents. Every face the
    view sees well becomes a target (``names``: only these ids), switch references are rendered
    open and closed, and infrared presets add their visible hot spots as thermal targets.
    Returns the Target list; raises PresetError (nothing written) when no target is in view.
    ``check``: a calibration.SelfCheck whose results say what the reader read.
    """
    info = load_info(preset_dir)
    width, height = (info.width, info.height) if info.width > 0 else (optics.width, optics.height)
    thermal = ThermalRenderer(world, seed=seed) if info.infrared else None
    pose = info.pose if true_pose is None else tuple(float(v) for v in true_pose)
    head = RenderedHead(Renderer(world, seed=seed), optics, pose, world.sensor_height, width, height,
                        thermal_renderer=thermal, thermal_size=tuple(thermal_size),
                        thermal_hfov_deg=thermal_hfov_deg)
    head.set_angles(info.pan_deg, info.tilt_deg)
    head.set_zoom(info.zoom_levels[0])
    scratch = tempfile.mkdtemp(prefix="calibrate_preset_")
    try:
        specs = world_specs(world, head, switch_picture_path=os.path.join(scratch, "%s_%s.png"))
        if names is not None:
            specs = [s for s in specs if s["name"] in set(names)]
        if not specs:
            raise PresetError("no face or hot spot of the world is in view of preset %s" % preset_dir)
        # the world knows every needle's value: the calibration checks itself against it
        # the reader's view of each needle is reported (check.results), not checked against the
        # world file: a running simulation may have moved the needles since it was written
        return calibrate(preset_dir, specs, optics, check=check or SelfCheck())
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
