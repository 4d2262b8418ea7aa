"""Test and benchmark fixtures: single faces and planar scenes with known truth.

The renderer draws the simulated world; this module puts single faces (pointer gauges of several
styles, painted by the world's own gauge painter ``sim.faces.paint_gauge``, lamps, switches) into a
textured scene through a known homography, so tests know the exact box and value of every target
without the world.
"""
import json
import math
import os

import cv2
import numpy as np

from inspection_robot.camera.optics import ZoomOptics
from inspection_robot.files import write_atomic
from inspection_robot.inspection.calibration_commands import CalibrationCommands
from inspection_robot.inspection.gauge import GaugeScale
from inspection_robot.inspection.preset import PresetInfo
from inspection_robot.sim.faces import paint_gauge

GAUGE_STYLES = {
    # face BGR, ink BGR, needle BGR, start, end angle (deg cw from up)
    "classic": ((235, 235, 235), (30, 30, 30), (20, 20, 20), 225.0, 135.0),
    "dark": ((40, 40, 40), (220, 220, 220), (240, 240, 240), 225.0, 135.0),
    "red_needle": ((225, 240, 245), (40, 40, 40), (20, 20, 200), 240.0, 120.0),
    "quarter": ((230, 230, 230), (30, 30, 30), (15, 15, 15), 300.0, 60.0),
}


class _FixtureDial(object):
    """The geometry ``sim.faces.paint_gauge`` asks of a world face, for a frontal test face: a
    square 1 m wide, the dial radius 0.45 of it around the centre."""

    class _Quad(object):
        width = height = 1.0

    quad = _Quad()

    def __init__(self, scale, value, colours, ticks):
        self._scale = scale
        self.value = float(value)
        self.colours = colours
        start = scale.start_angle - 360.0 if scale.start_angle >= scale.end_angle else scale.start_angle
        self.start_angle, self.end_angle = start, start + scale.sweep
        self.range = (min(scale.start_value, scale.end_value), max(scale.start_value, scale.end_value))
        self.style = "round_white"
        self.zones = []
        self.major_ticks, self.minor_ticks = ticks + 1, 4
        self.unit = ""

    def needle_angle_deg(self, value=None):
        angle = self._scale.angle(self.value if value is None else value)
        return angle - 360.0 if angle > self.end_angle else angle

    def dial_layout(self):
        return 0.5, 0.5, 0.45

    def needle_length_m(self):
        return 0.85 * 0.45


def draw_gauge_face(scale, value, size=400, style="classic", ticks=10):
    """A frontal gauge face ``size`` px square, dial radius 0.45 * size around the centre, painted
    by the simulated world's gauge painter in the colours of ``style``."""
    face_bgr, ink, needle, _, _ = GAUGE_STYLES[style]
    img = np.full((size, size, 3), 110, np.uint8)
    # painted one pixel smaller: the painter puts the pivot at width / 2, rectify() at (size - 1) / 2
    paint_gauge(img[:size - 1, :size - 1], _FixtureDial(scale, value, (face_bgr, ink, needle), ticks))
    return img


def draw_off_centre_face(scale, value, size=300, drop=0.3, hub_cap=False, hidden_hub=False):
    """A dial of radius 0.45 * ``size`` whose needle pivots ``drop`` dial radii below its centre, the
    scale's ticks on an arc (0.55 of the dial radius) about the pivot, a dark needle; ``hub_cap``: a
    dark cap over the pivot; ``hidden_hub``: the needle shows only from 0.35 of the arc out, as if
    its hub were under a plate of the face's colour. Returns (face, pivot px, arc radius px)."""
    face = np.full((size, size, 3), 60, np.uint8)
    c, r = size / 2.0, 0.45 * size
    cv2.circle(face, (int(c), int(c)), int(r), (235, 235, 235), -1, cv2.LINE_AA)
    pivot = np.array([c, c + drop * r])
    arc = 0.55 * r
    for k in range(11):
        a = np.radians(scale.start_angle + k * scale.sweep / 10.0)
        u = np.array([np.sin(a), -np.cos(a)])
        cv2.line(face, tuple(int(v) for v in pivot + 0.92 * arc * u), tuple(int(v) for v in pivot + 1.05 * arc * u),
                 (20, 20, 20), 2, cv2.LINE_AA)
    u = np.array([np.sin(np.radians(scale.angle(value))), -np.cos(np.radians(scale.angle(value)))])
    start = pivot + 0.35 * arc * u if hidden_hub else pivot
    cv2.line(face, tuple(int(v) for v in start), tuple(int(v) for v in pivot + 0.9 * arc * u), (15, 15, 15), 3,
             cv2.LINE_AA)
    if hub_cap and not hidden_hub:
        cv2.circle(face, tuple(int(v) for v in pivot), 7, (15, 15, 15), -1, cv2.LINE_AA)
    return face, pivot, arc


def draw_lamp(colour_bgr, on, size=128):
    img = np.full((size, size, 3), 70, np.uint8)
    c = size // 2
    cv2.circle(img, (c, c), int(size * 0.47), (45, 45, 45), -1, cv2.LINE_AA)
    if on:
        cv2.circle(img, (c, c), int(size * 0.33), colour_bgr, -1, cv2.LINE_AA)
        glow = tuple(int(min(255, 0.5 * v + 140)) for v in colour_bgr)
        cv2.circle(img, (c, c), int(size * 0.12), glow, -1, cv2.LINE_AA)
    else:
        dim = tuple(int(v * 0.3 + 20) for v in colour_bgr)
        cv2.circle(img, (c, c), int(size * 0.33), dim, -1, cv2.LINE_AA)
    return img


def draw_switch(closed, size=128):
    """A rotary switch: a bar vertical when closed, horizontal when open."""
    img = np.full((size, size, 3), 150, np.uint8)
    c = size // 2
    cv2.circle(img, (c, c), int(size * 0.42), (90, 90, 90), -1, cv2.LINE_AA)
    w, h = int(size * 0.1), int(size * 0.36)
    if closed:
        cv2.rectangle(img, (c - w, c - h), (c + w, c + h), (20, 20, 20), -1)
    else:
        cv2.rectangle(img, (c - h, c - w), (c + h, c + w), (20, 20, 20), -1)
    cv2.circle(img, (c, c - h + w) if closed else (c + h - w, c), w // 2, (240, 240, 240), -1)
    return img


def textured_background(width, height, rng):
    """Cluttered structure (rectangles, lines, circles) that feature matching can lock on."""
    img = np.full((height, width, 3), 0, np.uint8)
    img[:] = rng.integers(60, 140, 3)
    for _ in range(int(width * height / 2500)):
        kind = rng.integers(0, 3)
        colour = tuple(int(v) for v in rng.integers(0, 256, 3))
        x, y = int(rng.integers(0, width)), int(rng.integers(0, height))
        s = int(rng.integers(4, max(6, min(width, height) // 8)))
        if kind == 0:
            cv2.rectangle(img, (x, y), (x + s, y + int(rng.integers(4, s + 5))), colour, -1)
        elif kind == 1:
            cv2.circle(img, (x, y), s // 2, colour, int(rng.integers(-1, 4)) or -1)
        else:
            cv2.line(img, (x, y), (x + int(rng.integers(-s, s)), y + int(rng.integers(-s, s))), colour, 2)
    return cv2.GaussianBlur(img, (3, 3), 0)


def paste(scene, patch, quad):
    """Warp ``patch`` (a frontal square) into ``scene`` at ``quad`` (TL, TR, BR, BL)."""
    h, w = patch.shape[:2]
    src = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], np.float32)
    matrix = cv2.getPerspectiveTransform(src, np.asarray(quad, np.float32))
    size = (scene.shape[1], scene.shape[0])
    warped = cv2.warpPerspective(patch, matrix, size, flags=cv2.INTER_AREA)
    mask = cv2.warpPerspective(np.full((h, w), 255, np.uint8), matrix, size, flags=cv2.INTER_LINEAR)
    alpha = (mask.astype(np.float32) / 255.0)[:, :, None]
    scene[:] = (scene * (1 - alpha) + warped * alpha).astype(np.uint8)
    return scene


def perspective_quad(centre, side, yaw_deg=0.0, pitch_deg=0.0, roll_deg=0.0):
    """Quad of a square of ``side`` px at ``centre`` seen turned by yaw/pitch (foreshortening)."""
    h = side / 2.0
    pts = np.array([[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]], np.float64)
    ya, pa, ra = (math.radians(v) for v in (yaw_deg, pitch_deg, roll_deg))
    ry = np.array([[math.cos(ya), 0, math.sin(ya)], [0, 1, 0], [-math.sin(ya), 0, math.cos(ya)]])
    rx = np.array([[1, 0, 0], [0, math.cos(pa), -math.sin(pa)], [0, math.sin(pa), math.cos(pa)]])
    rz = np.array([[math.cos(ra), -math.sin(ra), 0], [math.sin(ra), math.cos(ra), 0], [0, 0, 1]])
    pts = pts.dot((rz.dot(rx).dot(ry)).T)
    dist = side * 3.0
    proj = pts[:, :2] * dist / (dist + pts[:, 2:3])
    return proj + np.asarray(centre, np.float64)


def degrade(img, rng, noise=3.0, blur=0.0, gain=1.0, offset=0.0, glare=None, occlusion=None):
    """Lighting gain/offset, a glare blob (x, y, r), an occluding bar (quad), blur and noise."""
    out = img.astype(np.float32) * gain + offset
    if glare is not None:
        x, y, r = glare
        yy, xx = np.mgrid[0:img.shape[0], 0:img.shape[1]]
        out += 150.0 * np.exp(-((xx - x) ** 2 + (yy - y) ** 2) / (2.0 * r * r))[:, :, None]
    if occlusion is not None:
        cv2.fillConvexPoly(out, np.round(np.asarray(occlusion)).astype(np.int32), (70.0, 80.0, 60.0))
    if blur > 0:
        out = cv2.GaussianBlur(out, (0, 0), blur)
    if noise > 0:
        out += rng.normal(0.0, noise, out.shape)
    return np.clip(out, 0, 255).astype(np.uint8)


def style_scale(style, start_value=0.0, end_value=1.6):
    _, _, _, start, end = GAUGE_STYLES[style]
    return GaugeScale(start, end, start_value, end_value)


class PlanarScene(object):
    """A flat textured wall with targets on it, seen by a pan/tilt/zoom camera far away.

    Views are similarity transforms of the wall (pan/tilt shift it, zoom scales it about the
    picture centre), plus optional perspective, so pictures at several zooms and head positions
    share exact ground truth. ``targets``: list of dicts with kind (pointer|lamp|switch),
    wall ``quad`` and state (``value`` for pointers, ``on``/``colour`` for lamps, ``closed``).
    """

    def __init__(self, rng, wall_size=(2400, 1500), targets=None):
        self.wall = textured_background(wall_size[0], wall_size[1], rng)
        self.targets = targets or []
        self.rng = rng

    def homography(self, centre_xy, zoom, size, tilt_h=(0.0, 0.0)):
        """Wall -> picture: wall point ``centre_xy`` lands at the picture centre, scaled by ``zoom``."""
        w, h = size
        cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
        matrix = np.array([[zoom, 0, cx - zoom * centre_xy[0]], [0, zoom, cy - zoom * centre_xy[1]],
                           [tilt_h[0], tilt_h[1], 1.0]])
        return matrix

    def render(self, matrix, size, faces=None):
        w, h = size
        image = cv2.warpPerspective(self.wall, matrix, (w, h), flags=cv2.INTER_AREA,
                                    borderMode=cv2.BORDER_REFLECT)
        for target in self.targets:
            patch = faces.get(id(target)) if faces else None
            if patch is None:
                patch = self.face(target)
            quad = cv2.perspectiveTransform(np.asarray(target["quad"], np.float64).reshape(-1, 1, 2),
                                            matrix).reshape(-1, 2)
            paste(image, patch, quad)
        return image

    def face(self, target):
        kind = target["kind"]
        if kind == "pointer":
            return draw_gauge_face(target["scale"], target["value"], 400, target.get("style", "classic"))
        if kind == "lamp":
            return draw_lamp(LAMP_BGR[target["colour"]], target["on"])
        return draw_switch(target["closed"])

    def quad_in_view(self, target, matrix):
        return cv2.perspectiveTransform(np.asarray(target["quad"], np.float64).reshape(-1, 1, 2),
                                        matrix).reshape(-1, 2)


LAMP_BGR = {"red": (30, 30, 230), "green": (40, 210, 40), "yellow": (20, 220, 230), "blue": (230, 90, 20),
            "white": (235, 235, 235)}


def linear_optics(width, height, hfov1_deg=40.0, max_zoom=30.0):
    """Optics whose focal length is exactly proportional to the zoom (matches PlanarScene)."""
    from inspection_robot.camera.optics import ZoomOptics
    f1 = width / 2.0 / math.tan(math.radians(hfov1_deg) / 2.0)
    rows = [[1.0, hfov1_deg], [max_zoom, math.degrees(2 * math.atan(width / 2.0 / (max_zoom * f1)))]]
    return ZoomOptics(rows, width, height)


def demo_targets(centre=(1200.0, 750.0)):
    """A pointer gauge, a red lamp and a switch side by side on the wall (wall px)."""
    x, y = centre
    return [
        {"kind": "pointer", "quad": perspective_quad((x - 60, y), 100, 15, -8, 2), "scale": style_scale("classic"),
         "value": 0.5, "style": "classic"},
        {"kind": "lamp", "quad": perspective_quad((x + 30, y - 25), 30), "colour": "red", "on": True},
        {"kind": "switch", "quad": perspective_quad((x + 30, y + 25), 36), "closed": True},
    ]


def record_synthetic_preset(root, preset_id, stamp, scene, view_centre, zoom_levels, size, optics,
                            wall_px_per_zoom=1.0):
    """Write a calibrated preset of ``scene`` seen at ``view_centre``: zoom<k>.jpg, preset.ini,
    preset_calib_info.ini, zoom<k>.xml, switch references. Returns the preset directory."""
    from inspection_robot.inspection.calibration import calibrate
    from inspection_robot.files import write_atomic
    from inspection_robot.inspection.preset import PresetDirWriter, PresetInfo, zoom_picture_name
    with PresetDirWriter(root, preset_id, stamp) as writer:
        for k, level in enumerate(zoom_levels):
            matrix = scene.homography(view_centre, level * wall_px_per_zoom, size)
            cv2.imwrite(writer.file(zoom_picture_name(k)), scene.render(matrix, size))
        info = PresetInfo(preset_id, "visible", False, stamp, 0.0, 0.0, zoom_levels[0], 0x4000, (0.0, 0.0, 0.0),
                          zoom_levels, size[0], size[1])
        write_atomic(writer.file("preset.ini"), info.to_ini())
        matrix0 = scene.homography(view_centre, zoom_levels[0] * wall_px_per_zoom, size)
        specs = []
        for i, target in enumerate(scene.targets):
            box = scene.quad_in_view(target, matrix0).reshape(-1).tolist()
            spec = {"kind": target["kind"], "box": box, "name": "t%d" % i}
            if target["kind"] == "pointer":
                s = target["scale"]
                spec.update(start_angle=s.start_angle, end_angle=s.end_angle, start_value=s.start_value,
                            end_value=s.end_value, unit="MPa")
            elif target["kind"] == "lamp":
                spec["colour"] = target["colour"]
            else:
                state = target["closed"]
                for name, closed in (("open", False), ("closed", True)):
                    target["closed"] = closed
                    path = writer.file("calib_%s.png" % name)
                    cv2.imwrite(path, scene.render(matrix0, size))
                    spec[name + "_picture"] = path
                target["closed"] = state
            specs.append(spec)
        calibrate(writer.path, specs, optics)
        for name in ("open", "closed"):
            if os.path.exists(writer.file("calib_%s.png" % name)):
                os.unlink(writer.file("calib_%s.png" % name))
        return writer.commit()


def make_lamp_preset(data_root, preset_id):
    """A calibrated one-lamp preset ``preset_id`` under <data_root>/presets (what the calibration tool
    writes): the patrol's inspect steps have something real to read."""
    folder = os.path.join(data_root, "presets", preset_id, "20260101_000000")
    os.makedirs(folder)
    info = PresetInfo(preset_id, "visible", False, "20260101_000000", 10.0, -5.0, 1.0, 0x4000, (5.0, 5.0, 0.0),
                      [1.0, 2.0], 640, 360)
    write_atomic(os.path.join(folder, "preset.ini"), info.to_ini())
    optics = ZoomOptics([[1.0, 59.8], [2.0, 31.6]], 640, 360)
    commands = CalibrationCommands(data_root, ["presets"], ["presets"], optics)
    reply = commands.table.dispatch("upload", json.dumps({
        "preset": "presets/%s/20260101_000000" % preset_id,
        "targets": [{"kind": "lamp", "box": [100, 100, 200, 100, 200, 200, 100, 200], "colour": "red"}]}))
    assert reply.ack == "success", reply.data
