"""The simulated world seen as tests need it, without ROS: the camera's optics, a preset recorded in
front of a piece of equipment (as preset_scale records one), one of the world's dials painted
frontally with its calibration, a bird's nest over part of a picture. One place for the set-up the
inspection tests and bench_inspection share.
"""
import math

import numpy as np
import yaml

from inspection_robot.camera.optics import ZoomOptics
from inspection_robot.inspection.gauge import GaugeScale
from inspection_robot.inspection.recorder import record_preset
from inspection_robot.sim.faces import paint_face, paint_foreign
from inspection_robot.sim.inspection_sim import RenderedHead
from inspection_robot.sim.render import Renderer
from inspection_robot_testing.yard_patrol import config_file

SENSOR_HEIGHT_M = 1.2   # the head above the ground, as the simulated robot carries it


def camera_optics(width, height):
    """The visible camera's ZoomOptics (config/camera_optics.yaml) for ``width`` x ``height`` pictures."""
    with open(config_file("camera_optics.yaml")) as f:
        table = yaml.safe_load(f)["camera_optics"]
    return ZoomOptics(table["zoom_hfov_deg"], width, height)


def front_pose(world, equipment, distance):
    """(x, y, yaw) ``distance`` m in front of ``equipment``'s front side, facing it."""
    base, normal, _right, _width = world.equipment[equipment].side_frame("front")
    p = base + normal * distance
    return float(p[0]), float(p[1]), math.atan2(-normal[1], -normal[0])


def recorded_preset(world, root, preset_id, equipment, distance, aim_height, zoom, width, height, seed=3,
                    stamp="20260101_000000"):
    """A preset recorded ``distance`` m in front of ``equipment``, the head aimed at ``aim_height`` m
    above the ground at ``zoom``; returns (its directory, the head, the optics, the pose)."""
    optics = camera_optics(width, height)
    pose = front_pose(world, equipment, distance)
    tilt = math.degrees(math.atan2(SENSOR_HEIGHT_M - aim_height, distance))   # up is negative
    head = RenderedHead(Renderer(world, seed=seed), optics, pose, SENSOR_HEIGHT_M, width, height)
    head.set_angles(0.0, tilt)
    head.set_zoom(zoom)
    state = {"pan_deg": 0.0, "tilt_deg": tilt, "zoom": zoom, "focus_position": 0, "pose": pose}
    return record_preset(head, root, preset_id, stamp, state), head, optics, pose


def painted_dial(face, value, px=400):
    """The world's gauge ``face`` at ``value`` painted frontally, ``px`` wide, and its calibration as a
    pointer reader takes it: (picture, quad, scale, centre, radius, aspect)."""
    face.set_value(value)
    image = paint_face(face, px)
    h, w = image.shape[:2]
    fx, fy, radius_m = face.dial_layout()
    quad = np.array([[-0.5, -0.5], [w - 0.5, -0.5], [w - 0.5, h - 0.5], [-0.5, h - 0.5]])
    return (image, quad, GaugeScale(face.start_angle, face.end_angle, *face.range), (fx, fy),
            radius_m / face.quad.width, face.quad.width / face.quad.height)


def cover_with_nest(image, x, y, half, seed):
    """A bird's nest (sim.faces.paint_foreign, ``seed``) pasted over ``image`` in place: a square of
    ``half`` px either side of (``x``, ``y``), cut at the picture's edges."""
    x0, y0 = int(x) - half, int(y) - half
    nest = paint_foreign(seed, 2 * half, 2 * half)
    h, w = image.shape[:2]
    rows, cols = slice(max(0, y0), min(h, y0 + 2 * half)), slice(max(0, x0), min(w, x0 + 2 * half))
    image[rows, cols] = nest[rows.start - y0:rows.stop - y0, cols.start - x0:cols.stop - x0]
