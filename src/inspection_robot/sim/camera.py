"""Simulated zoom camera: the CameraDriver behind camera_node when sim=true, backed by the renderer.

It keeps the settings a Hikvision block camera keeps (zoom, focus mode/position, minimum focus
distance, WDR, exposure, iris, OSD) and moves zoom and focus continuously at fixed rates while a
zoom_in/zoom_out/focus_far/focus_near is running. Pictures come from ``sim.render.Renderer`` for
the view that ``view_source()`` returns: (robot pose (x, y, yaw), pan rad, tilt rad).
"""
import threading
import time

from inspection_robot.lazy import lazy_import
from inspection_robot.camera.driver import CameraDriver, CameraError
from inspection_robot.camera.jpeg import encode_jpeg
from inspection_robot.interface import FOCUS_POSITION_MAX, FOCUS_POSITION_MIN
from inspection_robot.sim.render import PinholeCamera

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load


class _Motion(object):
    """A setting that moves continuously between start() and stop() (zoom, focus): ``law(value at
    the start, direction +1/-1, seconds since)`` gives its value meanwhile, kept in range."""

    def __init__(self, value, law, clock):
        self.value = value
        self._law = law
        self._clock = clock
        self._move = None     # (direction, start time, value at the start)

    def current(self):
        if self._move is None:
            return self.value
        direction, start, value0 = self._move
        return self._law(value0, direction, self._clock() - start)

    def set(self, value):
        self._move = None
        self.value = value

    def start(self, direction):
        self.value = self.current()
        self._move = (1 if direction > 0 else -1, self._clock(), self.value)

    def stop(self):
        self.value = self.current()
        self._move = None


class SimulatedCamera(CameraDriver):
    def __init__(self, renderer, optics, view_source, sensor_height, zoom_rate=2.0, focus_rate=0x4000,
                 jpeg_quality=90, clock=time.monotonic):
        """``zoom_rate``: magnification factor per second of continuous zoom; ``focus_rate``:
        focus units per second of continuous focus."""
        self._renderer = renderer
        self._optics = optics
        self._view_source = view_source
        self._sensor_height = float(sensor_height)
        self._zoom_rate = float(zoom_rate)
        self._focus_rate = float(focus_rate)
        self._jpeg_quality = int(jpeg_quality)
        self._clock = clock
        self._lock = threading.RLock()
        self._render_lock = threading.Lock()
        self._zoom = _Motion(optics.min_zoom, self._zoom_at, clock)
        self._focus = _Motion(0x6000, self._focus_at, clock)
        self.settings = {"focus_mode": "auto", "min_focus_distance": 150, "wdr_level": 50, "wdr_mode": False,
                         "exposure_mode": "auto", "iris": 400, "osd": True}
        self.failing = None        # fault injection: a reason string makes every request fail

    def _check(self):
        if self.failing:
            raise CameraError(self.failing)

    def _zoom_at(self, zoom0, direction, seconds):
        zoom = zoom0 * self._zoom_rate ** (direction * seconds)
        return min(max(zoom, self._optics.min_zoom), self._optics.max_zoom)

    def _focus_at(self, focus0, direction, seconds):
        focus = focus0 + direction * self._focus_rate * seconds
        return int(round(min(max(focus, FOCUS_POSITION_MIN), FOCUS_POSITION_MAX)))

    def _checked(self, action, *args):
        """``action(*args)`` under the lock, unless fault injection makes every request fail."""
        with self._lock:
            self._check()
            return action(*args)

    # --- zoom and focus ---------------------------------------------------------------------
    def set_zoom(self, zoom):
        self._checked(self._zoom.set, min(max(float(zoom), self._optics.min_zoom), self._optics.max_zoom))

    def get_zoom(self):
        return self._checked(self._zoom.current)

    def start_zoom(self, direction):
        self._checked(self._zoom.start, direction)

    def stop_zoom(self):
        self._checked(self._zoom.stop)

    def set_focus_position(self, position):
        self._checked(self._focus.set, int(position))

    def get_focus_position(self):
        return self._checked(self._focus.current)

    def start_focus(self, direction):
        self._checked(self._focus.start, direction)

    def stop_focus(self):
        self._checked(self._focus.stop)

    # --- settings ---------------------------------------------------------------------------
    def _set(self, key, value):
        self._checked(self.settings.__setitem__, key, value)

    def _get(self, key):
        return self._checked(self.settings.__getitem__, key)

    def set_focus_mode(self, mode):
        self._set("focus_mode", mode)

    def get_focus_mode(self):
        return self._get("focus_mode")

    def set_osd(self, enabled):
        self._set("osd", bool(enabled))

    def set_min_focus_distance(self, cm):
        self._set("min_focus_distance", int(cm))

    def get_min_focus_distance(self):
        return self._get("min_focus_distance")

    def set_wdr_level(self, level):
        self._set("wdr_level", int(level))

    def get_wdr_level(self):
        return self._get("wdr_level")

    def set_wdr_mode(self, enabled):
        self._set("wdr_mode", bool(enabled))

    def get_wdr_mode(self):
        return self._get("wdr_mode")

    def set_exposure_mode(self, mode):
        self._set("exposure_mode", mode)

    def get_exposure_mode(self):
        return self._get("exposure_mode")

    def set_iris(self, iris):
        self._set("iris", int(iris))

    def get_iris(self):
        return self._get("iris")

    def probe(self):
        self._checked(lambda: None)

    # --- pictures ---------------------------------------------------------------------------
    def camera_for(self, width):
        """The PinholeCamera of the current view for a picture ``width`` px wide (native aspect)."""
        with self._lock:
            zoom = self._zoom.current()
        height = int(round(width * self._optics.height / float(self._optics.width)))
        pose, pan, tilt = self._view_source()
        return PinholeCamera.from_pose(pose, pan, tilt, self._sensor_height, self._optics.focal_px(zoom, width),
                                       width, height), zoom

    def _picture(self, width):
        with self._lock:
            self._check()
            osd = self.settings["osd"]
            exposure = (self.settings["exposure_mode"], self.settings["iris"])
        camera, zoom = self.camera_for(width)
        with self._render_lock:
            img = self._renderer.render(camera)
        if exposure[0] == "manual":
            # f-number x100: F4.0 (400) is the auto-exposure equivalent; one stop = factor 2 in light
            gain = (400.0 / exposure[1]) ** 2
            img = cv2.convertScaleAbs(img, alpha=min(gain, 4.0))
        if osd:
            scale = width / 1280.0
            cv2.putText(img, "ZOOM x%.1f" % zoom, (int(20 * scale), int(40 * scale)), cv2.FONT_HERSHEY_SIMPLEX,
                        scale, (255, 255, 255), max(1, int(2 * scale)), cv2.LINE_AA)
        return img

    def capture_jpeg(self):
        try:
            return encode_jpeg(self._picture(self._optics.width), self._jpeg_quality)
        except ValueError as exc:
            raise CameraError(str(exc))

    def grab_frame(self, width):
        return self._picture(int(width))
