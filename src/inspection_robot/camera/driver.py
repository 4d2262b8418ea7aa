"""The visible camera's driver interface and the device health record shared with the thermal imager.

A driver speaks to one zoom camera (Hikvision ISAPI over HTTP, or the simulator). Every method
either returns or raises ``CameraError`` with a reason fit for an ack; value checking against the
spec's sets happens before a driver is called (camera.commands).
"""
import threading
import time

from inspection_robot.command import CommandError
from inspection_robot.drivers import not_fitted_class
from inspection_robot.interface import UNSUPPORTED


class CameraError(Exception):
    """The camera could not carry out a request (unreachable, refused, malformed reply)."""


class DeviceHealth(object):
    """Last known state of a device: ok, or the reason of the most recent failure."""

    def __init__(self, clock=time.monotonic):
        self._clock = clock
        self._lock = threading.Lock()
        self.ok = True
        self.message = "ok"
        self.failures = 0
        self.since = clock()

    def success(self):
        with self._lock:
            if not self.ok:
                self.since = self._clock()
            self.ok, self.message = True, "ok"

    def failure(self, reason):
        with self._lock:
            if self.ok:
                self.since = self._clock()
            self.ok, self.message = False, str(reason)
            self.failures += 1

    def command(self, method, *args, error, unsupported=()):
        """``method(*args)`` for a command handler: its result ("" for None), the outcome recorded
        here. ``error`` (the driver's exception) becomes a CommandError with its reason;
        ``unsupported`` (the device answered that it cannot do this) the spec's UNSUPPORTED, the
        device still counting as healthy."""
        try:
            result = method(*args)
        except unsupported:
            self.success()
            raise CommandError(UNSUPPORTED)
        except error as err:
            self.failure(err)
            raise CommandError(str(err))
        self.success()
        return "" if result is None else result


class CameraDriver(object):
    """Interface of a zoom camera. Zoom is a magnification (1.0 = widest); focus positions are
    the spec's 0x1000..0xC000 scale; iris is the f-number x 100 (the spec's value set)."""

    def set_zoom(self, zoom):
        raise NotImplementedError

    def get_zoom(self):
        raise NotImplementedError

    def start_zoom(self, direction):
        """Continuous zoom, ``direction`` +1 (in, tele) or -1 (out, wide), until stop_zoom()."""
        raise NotImplementedError

    def stop_zoom(self):
        raise NotImplementedError

    def set_focus_mode(self, mode):
        """``mode``: auto | manual | semiauto."""
        raise NotImplementedError

    def get_focus_mode(self):
        raise NotImplementedError

    def set_focus_position(self, position):
        raise NotImplementedError

    def get_focus_position(self):
        raise NotImplementedError

    def start_focus(self, direction):
        """Continuous focus, ``direction`` +1 (far) or -1 (near), until stop_focus()."""
        raise NotImplementedError

    def stop_focus(self):
        raise NotImplementedError

    def set_osd(self, enabled):
        raise NotImplementedError

    def set_min_focus_distance(self, cm):
        raise NotImplementedError

    def get_min_focus_distance(self):
        raise NotImplementedError

    def set_wdr_level(self, level):
        raise NotImplementedError

    def get_wdr_level(self):
        raise NotImplementedError

    def set_wdr_mode(self, enabled):
        raise NotImplementedError

    def get_wdr_mode(self):
        raise NotImplementedError

    def set_exposure_mode(self, mode):
        """``mode``: manual | auto."""
        raise NotImplementedError

    def get_exposure_mode(self):
        raise NotImplementedError

    def set_iris(self, iris):
        raise NotImplementedError

    def get_iris(self):
        raise NotImplementedError

    def capture_jpeg(self):
        """A full-resolution picture as JPEG bytes."""
        raise NotImplementedError

    def grab_frame(self, width):
        """A BGR picture about ``width`` px wide (for the live image topic)."""
        raise NotImplementedError

    def probe(self):
        """Cheap request that proves the camera answers; raises CameraError if not."""
        raise NotImplementedError

    def close(self):
        pass


NoCamera = not_fitted_class(CameraDriver, CameraError, "camera")
"""``~driver: none``: every request fails with the reason."""
