"""Simulated thermal imager: the ThermalDriver behind infrared_imager when sim=true.

Fixed lens (``hfov_deg``) on the pan/tilt head next to the visible camera; frames come from
``sim.render.ThermalRenderer`` for the view ``view_source()`` returns ((x, y, yaw), pan, tilt).
``unsupported`` lists commands to refuse, to behave like a vendor with a subset.
"""
import threading

from inspection_robot.interface import INFRARED_COMMANDS
from inspection_robot.camera.optics import focal_for_hfov
from inspection_robot.sim.render import PinholeCamera
from inspection_robot.thermal.driver import ThermalDriver, ThermalError


class SimulatedImager(ThermalDriver):
    def __init__(self, renderer, view_source, sensor_height, width=384, height=288, hfov_deg=25.0, unsupported=()):
        self._renderer = renderer
        self._view_source = view_source
        self._sensor_height = float(sensor_height)
        self.width, self.height = int(width), int(height)
        self.focal_px = focal_for_hfov(self.width, float(hfov_deg))
        self.supported = tuple(c for c in INFRARED_COMMANDS if c not in set(unsupported))
        self._lock = threading.Lock()
        self.failing = None   # fault injection: a reason string makes every request fail
        self.focus_count = 0

    def camera(self):
        pose, pan, tilt = self._view_source()
        return PinholeCamera.from_pose(pose, pan, tilt, self._sensor_height, self.focal_px, self.width, self.height)

    def frame(self):
        if self.failing:
            raise ThermalError(self.failing)
        camera = self.camera()
        with self._lock:
            return self._renderer.render(camera)

    def auto_focus(self):
        if self.failing:
            raise ThermalError(self.failing)
        self.focus_count += 1

    def probe(self):
        if self.failing:
            raise ThermalError(self.failing)
