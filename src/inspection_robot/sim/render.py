"""Pinhole rendering of the simulated yard: visible pictures, radiometric thermal frames, ground truth.

Camera model: the pan/tilt head sits ``sensor_height`` m above the robot's map position (x, y);
the optical axis points along the robot's yaw plus the head's pan (counter-clockwise +) and
``tilt`` below the horizon (down +), no roll. Optical frame: x right, y down, z forward;
pixel (u, v) = (f X/Z + W/2, f Y/Z + H/2), integer pixel coordinates at pixel centres (OpenCV).

Rendering is a painter's algorithm over planar quads (ground, fence walls, equipment sides and
tops, faces), each quad clipped to the view frustum and filled by warpPerspective of its texture
through the plane's homography, only over the quad's bounding box. Face textures are cached per
(face, value, resolution). Post-processing (lighting gain and gradient, Gaussian blur, sensor
noise) is seeded: the same seed, view and frame index give the same picture bit for bit.

No rospy here: the inspection team uses ``ground_truth`` and ``Renderer`` on its own.
"""
import functools
import math
import zlib

import numpy as np

from inspection_robot.lazy import lazy_import
from inspection_robot.sim import faces as painter
from inspection_robot.sim.world import Quad

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load

NEAR_M = 0.05
FRUSTUM_MARGIN_PX = 4.0
WALL_HEIGHT_M = 2.5
GROUND_MARGIN_M = 10.0
GROUND_PX_PER_M = 25.0
PANEL_PX_PER_M = 100.0
FACE_CACHE_BYTES = 64 * 1024 * 1024  # rendered face textures kept for reuse


def head_rotation(yaw, tilt):
    """World-from-optical rotation for a head looking along ``yaw`` (rad, CCW from +x), ``tilt`` down +."""
    cy, sy, ct, st = math.cos(yaw), math.sin(yaw), math.cos(tilt), math.sin(tilt)
    forward = np.array([cy * ct, sy * ct, -st])
    right = np.array([sy, -cy, 0.0])
    down = -np.array([cy * st, sy * st, ct])
    return np.column_stack([right, down, forward])


class PinholeCamera(object):
    """A pinhole camera at ``position`` (map, m) with world-from-optical ``rotation``."""

    def __init__(self, position, rotation, focal_px, width, height):
        self.position = np.asarray(position, dtype=float)
        self.rotation = np.asarray(rotation, dtype=float)
        self.focal_px = float(focal_px)
        self.width = int(width)
        self.height = int(height)
        self.K = np.array([[self.focal_px, 0.0, self.width / 2.0],
                           [0.0, self.focal_px, self.height / 2.0],
                           [0.0, 0.0, 1.0]])

    @classmethod
    def from_pose(cls, pose, pan, tilt, sensor_height, focal_px, width, height):
        """``pose`` = (x, y, yaw) of the robot in the map; pan/tilt in rad (standard convention)."""
        x, y, yaw = pose
        return cls((x, y, sensor_height), head_rotation(yaw + pan, tilt), focal_px, width, height)

    def to_camera(self, points):
        return (np.asarray(points, dtype=float).reshape(-1, 3) - self.position).dot(self.rotation)

    def project(self, points):
        """(uv (N, 2), depth (N,)) of world points; uv is meaningless where depth <= 0."""
        cam = self.to_camera(points)
        depth = cam[:, 2]
        safe = np.where(np.abs(depth) < 1e-9, 1e-9, depth)
        uv = np.column_stack([self.focal_px * cam[:, 0] / safe + self.width / 2.0,
                              self.focal_px * cam[:, 1] / safe + self.height / 2.0])
        return uv, depth

    def plane_homography(self, quad, tex_width, tex_height):
        """3x3 map from texture pixel (x, y) of ``quad`` to image pixel; x/W, y/H are quad fractions."""
        rt = self.rotation.T
        origin = quad.centre - 0.5 * quad.width * quad.right + 0.5 * quad.height * quad.up - self.position
        columns = np.column_stack([rt.dot(quad.right * quad.width / float(tex_width)),
                                   rt.dot(-quad.up * quad.height / float(tex_height)),
                                   rt.dot(origin)])
        return self.K.dot(columns)

    def facing(self, quad):
        return float(np.dot(quad.normal, self.position - quad.centre)) > 0.0

    def clip_polygon(self, points):
        """Image polygon (M, 2) of the part of the 3D polygon inside the view frustum (M may be 0)."""
        poly = [p for p in self.to_camera(points)]
        half_w = self.width / 2.0 + FRUSTUM_MARGIN_PX
        half_h = self.height / 2.0 + FRUSTUM_MARGIN_PX
        f = self.focal_px
        planes = (np.array([0.0, 0.0, 1.0, -NEAR_M]),       # z >= near
                  np.array([f, 0.0, half_w, 0.0]),          # u >= -margin
                  np.array([-f, 0.0, half_w, 0.0]),         # u <= W + margin
                  np.array([0.0, f, half_h, 0.0]),
                  np.array([0.0, -f, half_h, 0.0]))
        for plane in planes:
            poly = _clip(poly, plane)
            if not poly:
                return np.zeros((0, 2))
        pts = np.array(poly)
        return np.column_stack([f * pts[:, 0] / pts[:, 2] + self.width / 2.0,
                                f * pts[:, 1] / pts[:, 2] + self.height / 2.0])


def _clip(poly, plane):
    """Sutherland-Hodgman: keep the part of ``poly`` where plane[:3].p + plane[3] >= 0."""
    out = []
    count = len(poly)
    for i in range(count):
        a, b = poly[i], poly[(i + 1) % count]
        da = plane[:3].dot(a) + plane[3]
        db = plane[:3].dot(b) + plane[3]
        if da >= 0:
            out.append(a)
        if (da >= 0) != (db >= 0):
            out.append(a + (b - a) * (da / (da - db)))
    return out


# --- ground truth ---------------------------------------------------------------------------
def ground_truth(world, camera):
    """Where every face and hot spot lands in ``camera``'s picture.

    Returns {"faces": {id: {...}}, "hot_spots": {id: {...}}, "foreign": {id: {...}}}. Each face entry: type, value,
    corners (TL, TR, BR, BL as seen from the front, px), center, depth (m, along the optical axis),
    facing, in_picture (all corners inside), visible (in front, facing, in picture; occlusion by
    other equipment is not checked); gauges add pivot, needle_tip (px) and needle_angle_deg.
    Hot spot entries: center (px), radius_px, temperature, visible. Foreign objects present:
    corners, visible.
    """
    faces = {}
    for face in world.faces.values():
        corners, depth = camera.project(face.quad.corners())
        centre, centre_depth = camera.project(face.quad.centre)
        in_front = bool(np.all(depth > NEAR_M))
        inside = bool(in_front and np.all((corners >= 0) & (corners <= [camera.width, camera.height])))
        facing = camera.facing(face.quad)
        entry = {"type": face.type, "value": face.value, "corners": corners.tolist(),
                 "center": centre[0].tolist(), "depth": float(centre_depth[0]), "facing": facing,
                 "in_picture": inside, "visible": bool(in_front and facing and inside)}
        if face.type == "gauge":
            fx, fy, _ = face.dial_layout()
            tx, ty = face.needle_tip_fraction()
            pts, _ = camera.project(np.array([face.quad.point(fx, fy), face.quad.point(tx, ty)]))
            entry.update(pivot=pts[0].tolist(), needle_tip=pts[1].tolist(),
                         needle_angle_deg=face.needle_angle_deg(), range=list(face.range))
        faces[face.id] = entry
    spots = {}
    for spot in world.hot_spots.values():
        centre, depth = camera.project(spot.quad.centre)
        radius_px = camera.focal_px * spot.radius / max(float(depth[0]), 1e-6)
        u, v = centre[0]
        visible = bool(depth[0] > NEAR_M and camera.facing(spot.quad)
                       and 0 <= u < camera.width and 0 <= v < camera.height)
        spots[spot.id] = {"center": centre[0].tolist(), "radius_px": float(radius_px), "depth": float(depth[0]),
                          "temperature": spot.temperature, "visible": visible}
    foreign = {}
    for thing in world.foreign.values():
        if not thing.present:
            continue
        corners, depth = camera.project(thing.quad.corners())
        inside = bool(np.all(depth > NEAR_M) and np.all((corners >= 0) & (corners <= [camera.width, camera.height])))
        foreign[thing.id] = {"corners": corners.tolist(), "visible": bool(inside and camera.facing(thing.quad))}
    return {"faces": faces, "hot_spots": spots, "foreign": foreign}


# --- scene ------------------------------------------------------------------------------------
class _Surface(object):
    """A textured quad of the static scene and the equipment it belongs to (None: ground/walls)."""

    def __init__(self, quad, texture, equipment_id=None):
        self.quad = quad
        self.texture = texture
        self.equipment_id = equipment_id


def _ground_quad(world):
    sx, sy = world.size
    m = GROUND_MARGIN_M
    centre = np.array([sx / 2.0, sy / 2.0, 0.0])
    # texture x along +x, texture y (down) along -y: "up" in the texture is +y
    return Quad(centre, np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]), sx + 2 * m, sy + 2 * m,
                np.array([0.0, 0.0, 1.0]))


def _wall_quads(world):
    sx, sy = world.size
    m = world.fence_margin
    z = WALL_HEIGHT_M / 2.0
    up = np.array([0.0, 0.0, 1.0])
    walls = []
    # inner faces of a fence around [m, sx-m] x [m, sy-m], normals pointing into the yard
    for centre, normal, length in (((sx / 2.0, m, z), (0, 1, 0), sx - 2 * m),
                                   ((sx / 2.0, sy - m, z), (0, -1, 0), sx - 2 * m),
                                   ((m, sy / 2.0, z), (1, 0, 0), sy - 2 * m),
                                   ((sx - m, sy / 2.0, z), (-1, 0, 0), sy - 2 * m)):
        normal = np.array(normal, dtype=float)
        walls.append(Quad(np.array(centre, dtype=float), np.cross(up, normal), up, length, WALL_HEIGHT_M, normal))
    return walls


def _shade(normal, sun):
    return 0.6 + 0.4 * max(0.0, float(np.dot(normal, sun)))


class Renderer(object):
    """Visible-light pictures of ``world``; all randomness from ``seed``."""

    def __init__(self, world, seed=0, noise_sigma=2.0, blur_sigma=0.6, lighting_variation=0.08):
        self.world = world
        self.seed = int(seed)
        self.noise_sigma = float(noise_sigma)
        self.blur_sigma = float(blur_sigma)
        self.lighting_variation = float(lighting_variation)
        self._frame = 0
        self._face_cache = {}
        self._noise_fields = {}
        rng = np.random.RandomState(world.seed)
        sun = np.array([0.4, -0.5, 0.75])
        self._sun = sun / np.linalg.norm(sun)
        ground = _ground_quad(world)
        gw, gh = int(ground.width * GROUND_PX_PER_M), int(ground.height * GROUND_PX_PER_M)
        ground_tex = painter.paint_ground(rng, gw, gh, GROUND_PX_PER_M,
                                          (GROUND_MARGIN_M * GROUND_PX_PER_M,) * 2, world.size)
        # painted with rows growing with map y; texture rows grow towards -y (the quad's "down")
        self._ground = _Surface(ground, np.ascontiguousarray(ground_tex[::-1]))
        self._walls = [_Surface(q, self._shaded(painter.paint_panel(rng, int(q.width * 40), int(q.height * 40),
                                                                    (150, 160, 165)), q.normal))
                       for q in _wall_quads(world)]
        self._boxes = {}
        palette = [(95, 110, 100), (150, 150, 140), (120, 130, 150), (110, 115, 120)]
        for index, eq in enumerate(sorted(world.equipment.values(), key=lambda e: e.id)):
            colour = palette[index % len(palette)]
            surfaces = []
            for side in ("front", "back", "left", "right"):
                quad = eq.side_quad(side)
                tex = painter.paint_panel(rng, max(16, int(quad.width * PANEL_PX_PER_M)),
                                          max(16, int(quad.height * PANEL_PX_PER_M)), colour,
                                          label=eq.id if side == "front" else None)
                surfaces.append(_Surface(quad, self._shaded(tex, quad.normal), eq.id))
            top = eq.top_quad()
            tex = painter.paint_panel(rng, max(16, int(top.width * PANEL_PX_PER_M)),
                                      max(16, int(top.height * PANEL_PX_PER_M)), colour)
            surfaces.append(_Surface(top, self._shaded(tex, top.normal), eq.id))
            self._boxes[eq.id] = surfaces
        self._faces_by_equipment = {}
        for face in world.faces.values():
            self._faces_by_equipment.setdefault(face.equipment.id, []).append(face)

    def _shaded(self, texture, normal):
        return cv2.convertScaleAbs(texture, alpha=_shade(normal, self._sun))

    def _face_texture(self, face, longest_px):
        size = int(2 ** math.ceil(math.log(max(longest_px, 64.0), 2)))
        size = min(size, 2048)
        key = (face.id, face.value, size)
        tex = self._face_cache.get(key)
        if tex is None:
            tex = cv2.convertScaleAbs(painter.paint_face(face, size), alpha=0.85 + 0.15 * _shade(face.quad.normal,
                                                                                                 self._sun))
            self._cache_texture(key, tex)
        return tex

    def _cache_texture(self, key, tex):
        # bounded in bytes, not entries: 128 entries of up to 2048 px were 1.5 GB, and the chaos soak
        # saw camera_node's memory climb for minutes as the head panned over new faces and zooms
        if sum(t.nbytes for t in self._face_cache.values()) + tex.nbytes > FACE_CACHE_BYTES:
            self._face_cache.clear()
        self._face_cache[key] = tex

    def render(self, camera, frame_index=None):
        """BGR uint8 picture of ``camera``'s view. Frame ``frame_index`` (default: a counter) seeds noise."""
        if frame_index is None:
            frame_index = self._frame
            self._frame += 1
        img = self._sky(camera)
        _draw(img, camera, self._ground.quad, self._ground.texture)
        for wall in self._walls:
            if camera.facing(wall.quad):
                _draw(img, camera, wall.quad, wall.texture)
        for eq_id in self._far_to_near(camera):
            for surface in self._boxes[eq_id]:
                if camera.facing(surface.quad):
                    _draw(img, camera, surface.quad, surface.texture)
            for face in self._faces_by_equipment.get(eq_id, ()):
                if not camera.facing(face.quad):
                    continue
                uv, depth = camera.project(face.quad.corners())
                if np.any(depth <= NEAR_M):
                    continue
                extent = max(np.linalg.norm(uv[1] - uv[0]), np.linalg.norm(uv[3] - uv[0]))
                if extent < 1.0:
                    continue
                _draw(img, camera, face.quad, self._face_texture(face, extent))
            for thing in self.world.foreign.values():
                if thing.present and thing.equipment.id == eq_id and camera.facing(thing.quad):
                    _draw(img, camera, thing.quad, self._foreign_texture(thing))
        return self._post(img, frame_index)

    def _foreign_texture(self, thing):
        key = ("foreign", thing.id, thing.value)
        tex = self._face_cache.get(key)
        if tex is None:
            width = max(16, int(thing.quad.width * 400))
            height = max(16, int(thing.quad.height * 400))
            tex = painter.paint_foreign(zlib.crc32(thing.id.encode("utf-8")), width, height)
            self._cache_texture(key, tex)
        return tex

    def _far_to_near(self, camera):
        return sorted(self.world.equipment,
                      key=lambda e: -np.linalg.norm(self.world.equipment[e].position[:2] - camera.position[:2]))

    def _sky(self, camera):
        rows = np.arange(camera.height, dtype=np.float32)
        # elevation (up +) of each row's centre ray; no roll, so rows are level
        tilt = math.asin(max(-1.0, min(1.0, -camera.rotation[2, 2])))
        elev = -tilt - np.arctan((rows - camera.height / 2.0) / camera.focal_px)
        t = np.clip(elev / 0.8, 0.0, 1.0)[:, None]
        top, horizon = np.array([200, 150, 90], np.float32), np.array([235, 215, 190], np.float32)
        column = (horizon * (1 - t) + top * t).astype(np.uint8)[:, None, :]
        return cv2.resize(column, (camera.width, camera.height), interpolation=cv2.INTER_NEAREST)

    def _post(self, img, frame_index):
        rng = np.random.RandomState((self.seed * 7919 + frame_index) % (2 ** 31))
        if self.blur_sigma > 0:
            img = cv2.GaussianBlur(img, (0, 0), self.blur_sigma)
        if self.lighting_variation > 0:
            corners = (1.0 + self.lighting_variation * rng.uniform(-1, 1, (2, 2))).astype(np.float32)
            gain = cv2.resize(corners, (img.shape[1], img.shape[0]), interpolation=cv2.INTER_LINEAR)
            img = cv2.multiply(img, cv2.merge([gain, gain, gain]), dtype=cv2.CV_8U)
        if self.noise_sigma > 0:
            # sensor noise in 2x2 cells, cut at a seeded offset from a field drawn once per size
            half = (img.shape[0] // 2 + 1, img.shape[1] // 2 + 1)
            field = self._noise_fields.get(half)
            if field is None:
                field_rng = np.random.RandomState(self.seed)
                field = field_rng.normal(0.0, self.noise_sigma, (half[0] + 64, half[1] + 64, 3)).astype(np.float32)
                self._noise_fields[half] = field
            oy, ox = rng.randint(0, 64, 2)
            noise = cv2.resize(field[oy:oy + half[0], ox:ox + half[1]], (img.shape[1], img.shape[0]),
                               interpolation=cv2.INTER_NEAREST)
            img = cv2.add(img, noise, dtype=cv2.CV_8U)
        return _infrared(img) if self.world.light.value == "night" else img


def _infrared(img):
    """The picture a camera takes at night by its own infrared illuminator: grey (no colour), its
    light falling off from the middle of the view, dimmer and flatter than by day."""
    grey = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(np.float32)
    lit = 20.0 + grey * _illuminated(*grey.shape)
    return cv2.cvtColor(np.clip(lit, 0, 255).astype(np.uint8), cv2.COLOR_GRAY2BGR)


@functools.lru_cache(maxsize=4)
def _illuminated(h, w):
    """The infrared illuminator's gain over an ``h`` x ``w`` picture (once per picture size)."""
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    r2 = ((x - w / 2.0) / (w / 2.0)) ** 2 + ((y - h / 2.0) / (h / 2.0)) ** 2
    gain = 0.7 * (1.0 - 0.3 * np.clip(r2 / 2.0, 0.0, 1.0))
    gain.setflags(write=False)   # shared by every frame of that size
    return gain


def _draw(img, camera, quad, texture):
    """Warp ``texture`` of ``quad`` into ``img`` over the quad's visible polygon."""
    poly = camera.clip_polygon(quad.corners())
    if len(poly) < 3:
        return
    height, width = img.shape[:2]
    x0 = max(0, int(math.floor(poly[:, 0].min())))
    y0 = max(0, int(math.floor(poly[:, 1].min())))
    x1 = min(width, int(math.ceil(poly[:, 0].max())) + 1)
    y1 = min(height, int(math.ceil(poly[:, 1].max())) + 1)
    if x1 <= x0 or y1 <= y0:
        return
    homography = camera.plane_homography(quad, texture.shape[1], texture.shape[0])
    shift = np.array([[1.0, 0.0, -x0], [0.0, 1.0, -y0], [0.0, 0.0, 1.0]])
    warped = cv2.warpPerspective(texture, shift.dot(homography), (x1 - x0, y1 - y0),
                                 flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    mask = np.zeros((y1 - y0, x1 - x0), np.uint8)
    pts = np.round((poly - [x0, y0]) * painter._SCALE).astype(np.int32)
    cv2.fillConvexPoly(mask, pts, 255, cv2.LINE_8, painter.SUBPIXEL_SHIFT)
    roi = img[y0:y1, x0:x1]
    out = cv2.bitwise_and(warped, warped, dst=roi, mask=mask)   # masked: leaves the rest of roi as is
    if out is not roi:   # the binding had to copy the strided view
        roi[...] = out


# --- thermal ----------------------------------------------------------------------------------
class ThermalRenderer(object):
    """Radiometric frames (float32 degC per pixel) of ``world``; noise (NETD) seeded by ``seed``."""

    def __init__(self, world, seed=0, noise_sigma=0.05, hot_spot_px=64):
        self.world = world
        self.seed = int(seed)
        self.noise_sigma = float(noise_sigma)
        self._frame = 0
        self._profile = painter.paint_hot_spot(hot_spot_px)
        self._ground = _ground_quad(world)
        self._walls = _wall_quads(world)
        self._spots_by_equipment = {}
        for spot in world.hot_spots.values():
            self._spots_by_equipment.setdefault(spot.equipment.id, []).append(spot)

    def render(self, camera, frame_index=None):
        if frame_index is None:
            frame_index = self._frame
            self._frame += 1
        world = self.world
        frame = np.full((camera.height, camera.width), world.sky_c, np.float32)
        _fill(frame, camera, self._ground, world.ground_c)
        for wall in self._walls:
            if camera.facing(wall):
                _fill(frame, camera, wall, world.ambient_c)
        for eq_id in sorted(world.equipment, key=lambda e: -np.linalg.norm(
                world.equipment[e].position[:2] - camera.position[:2])):
            eq = world.equipment[eq_id]
            surface_c = world.surface_temperature(eq_id)
            for quad in [eq.side_quad(s) for s in ("front", "back", "left", "right")] + [eq.top_quad()]:
                if camera.facing(quad):
                    _fill(frame, camera, quad, surface_c)
            for spot in self._spots_by_equipment.get(eq_id, ()):
                if camera.facing(spot.quad):
                    self._add_spot(frame, camera, spot, spot.temperature - surface_c)
        if self.noise_sigma > 0:
            rng = np.random.RandomState((self.seed * 7919 + frame_index) % (2 ** 31))
            frame += rng.normal(0.0, self.noise_sigma, frame.shape).astype(np.float32)
        return frame

    def _add_spot(self, frame, camera, spot, delta_c):
        uv, depth = camera.project(spot.quad.corners())
        if np.any(depth <= NEAR_M):
            return
        height, width = frame.shape
        x0, y0 = max(0, int(math.floor(uv[:, 0].min()))), max(0, int(math.floor(uv[:, 1].min())))
        x1 = min(width, int(math.ceil(uv[:, 0].max())) + 1)
        y1 = min(height, int(math.ceil(uv[:, 1].max())) + 1)
        if x1 <= x0 or y1 <= y0:
            return
        size = self._profile.shape[0]
        homography = camera.plane_homography(spot.quad, size, size)
        # texture pixel centres at (i + 0.5) / size of the quad
        centre_shift = np.array([[1.0, 0.0, 0.5], [0.0, 1.0, 0.5], [0.0, 0.0, 1.0]])
        shift = np.array([[1.0, 0.0, -x0], [0.0, 1.0, -y0], [0.0, 0.0, 1.0]])
        warped = cv2.warpPerspective(self._profile, shift.dot(homography).dot(centre_shift), (x1 - x0, y1 - y0),
                                     flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        frame[y0:y1, x0:x1] += warped * np.float32(delta_c)


def _fill(frame, camera, quad, value):
    poly = camera.clip_polygon(quad.corners())
    if len(poly) >= 3:
        pts = np.round(poly * painter._SCALE).astype(np.int32)
        cv2.fillConvexPoly(frame, pts, float(value), cv2.LINE_8, painter.SUBPIXEL_SHIFT)
