"""infrared_control / infrared_cmd command table (INTERFACE.md section 4, "Thermal imager").

Pixel coordinates ("x,y") are thermal-frame pixels, x right and y down from the top-left pixel
(0,0). The measurement area of get_max_temperature is a square of ``measure_box_px`` pixels
centred on the spot set by set_measure_spot (default: the frame centre), clipped to the frame.
Temperatures are degC with two decimals. Radiometric files: see ``save_radiometric``.
save_temperature and capture_picture create a new file inside the imager's roots and never
replace one, never under a hidden name and never beyond the roots' quota, as the camera's
capture_picture. capture_picture writes the imager's own JPEG where the driver has one
(``capture_jpeg``), else a false-colour picture of the frame. A request the imager reports it
cannot do (ThermalUnsupported) answers ``failed``/``unsupported``.
"""
import functools
import io
import os

import numpy as np

from inspection_robot.camera.jpeg import encode_jpeg
from inspection_robot.lazy import lazy_import
from inspection_robot.files import PUBLIC_FILE_MODE, is_staged_name, new_file_path, write_atomic
from inspection_robot.command import CommandError, CommandTable, no_data, parse_int, split_fields
from inspection_robot.command import failed
from inspection_robot.interface import INFRARED_COMMANDS, UNSUPPORTED
from inspection_robot.thermal.driver import ThermalError, ThermalUnsupported

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load

NO_DATA_COMMANDS = ("get_max_temperature", "get_high_temperature", "get_low_temperature", "auto_focus")
KELVIN_OFFSET = 273.15
CENTIKELVIN = 100.0


def format_temperature(value):
    return "%.2f" % float(value)


def false_colour(frame, low=None, high=None):
    """BGR false-colour picture of a radiometric frame (inferno palette, scaled to [low, high])."""
    low = float(np.min(frame)) if low is None else float(low)
    high = float(np.max(frame)) if high is None else float(high)
    scaled = np.clip((frame - low) * (255.0 / max(high - low, 1e-6)), 0, 255).astype(np.uint8)
    return cv2.applyColorMap(scaled, cv2.COLORMAP_INFERNO)


def hottest_point(frame):
    """The hottest pixel of a frame: {"x", "y" (px, x right, y down), "temperature" (degC)}."""
    y, x = np.unravel_index(int(np.argmax(frame)), frame.shape)
    return {"x": int(x), "y": int(y), "temperature": round(float(frame[y, x]), 2)}


def save_radiometric(path, frame):
    """Write a radiometric frame (radiometric_bytes). An existing file at ``path`` is never replaced
    (FileError)."""
    write_atomic(path, radiometric_bytes(path, frame), replace=False, mode=PUBLIC_FILE_MODE)


def radiometric_bytes(path, frame):
    """The file of a radiometric frame, its format chosen by ``path``'s extension. ``.png``: 16-bit
    single-channel PNG, pixel = temperature in centikelvin (degC = p / 100 - 273.15; 0..655.35 K).
    ``.npy``: float32 array in degC."""
    extension = os.path.splitext(path)[1].lower()
    if extension == ".npy":
        stream = io.BytesIO()
        np.save(stream, frame.astype(np.float32))
        return stream.getvalue()
    if extension != ".png":
        raise CommandError("radiometric file must end in .png (16-bit centikelvin) or .npy (float32 degC): '%s'"
                           % path)
    counts = np.clip(np.round((frame.astype(np.float64) + KELVIN_OFFSET) * CENTIKELVIN), 0, 65535)
    ok, buf = cv2.imencode(".png", counts.astype(np.uint16))
    if not ok:
        raise CommandError("PNG encoding failed")
    return buf.tobytes()


def load_radiometric(path):
    """Read a file written by save_radiometric back into degC (float32)."""
    if path.lower().endswith(".npy"):
        return np.load(path)
    counts = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    if counts is None or counts.dtype != np.uint16:
        raise ValueError("%s is not a 16-bit radiometric PNG" % path)
    return (counts.astype(np.float32) / np.float32(CENTIKELVIN) - np.float32(KELVIN_OFFSET)).astype(np.float32)


class ThermalCommands(object):
    """The imager's CommandTable; ``roots`` confine the paths of new files, ``quota``
    (data_layout.CaptureQuota, None: none) bounds the bytes they hold."""

    def __init__(self, driver, roots, health, width, height, measure_box_px=16, jpeg_quality=90, quota=None):
        self._driver = driver
        self._roots = list(roots)
        self._quota = quota
        self._call = functools.partial(health.command, error=ThermalError, unsupported=ThermalUnsupported)
        self.width, self.height = int(width), int(height)
        self._box = int(measure_box_px)
        self._jpeg_quality = int(jpeg_quality)
        self.measure_spot = (self.width // 2, self.height // 2)
        handlers = {
            "save_temperature": self.save_temperature,
            "capture_picture": self.capture_picture,
            "get_max_temperature": self.get_max_temperature,
            "get_spot_temperature": self.get_spot_temperature,
            "get_high_temperature": lambda data: format_temperature(self._frame().max()),
            "get_low_temperature": lambda data: format_temperature(self._frame().min()),
            "auto_focus": lambda data: self._call(driver.auto_focus),
            "set_measure_spot": self.set_measure_spot,
        }
        for name in NO_DATA_COMMANDS:
            handlers[name] = no_data(handlers[name])
        for name in INFRARED_COMMANDS:
            if not driver.supports(name):
                handlers[name] = lambda data: failed(UNSUPPORTED)
        self.table = CommandTable(handlers)
        # preset_scale's and find_scale's files, under a fresh hidden staged name (camera.commands)
        self.staging_table = CommandTable({"capture_picture": lambda data: self.capture_picture(data, True),
                                           "save_temperature": lambda data: self.save_temperature(data, True)})

    def _frame(self):
        frame = self._call(self._driver.frame)
        if frame.shape != (self.height, self.width):
            raise CommandError("imager delivered a %dx%d frame, expected %dx%d: set infrared_imager ~width and "
                               "~height to the imager's resolution"
                               % (frame.shape[1], frame.shape[0], self.width, self.height))
        return frame

    def _pixel(self, data):
        x_text, y_text = split_fields(data, 2, "spot")
        return (parse_int(x_text, "x", 0, self.width - 1), parse_int(y_text, "y", 0, self.height - 1))

    def _target(self, data, staging=False):
        """(path, staged) of a new file's ``data``; refused before the imager is asked, also when the
        quota is full already. ``staging``: through staging_table only (a fresh staged_name allowed)."""
        path, staged = new_file_path(data, self._roots, staged=staging), staging and is_staged_name(data)
        self._count(1, staged)
        return path, staged

    def _count(self, size, staged):
        if self._quota is not None:
            self._quota.check(size, "this file" if size > 1 else "a file", staged)

    def _write(self, path, staged, data, mode=None):
        self._count(len(data), staged)
        write_atomic(path, data, replace=False, mode=mode)
        if self._quota is not None:
            self._quota.add(len(data))

    def save_temperature(self, data, staging=False):
        path, staged = self._target(data, staging)
        self._write(path, staged, radiometric_bytes(path, self._frame()), PUBLIC_FILE_MODE)
        return path

    def capture_picture(self, data, staging=False):
        path, staged = self._target(data, staging)
        picture = self._call(self._driver.capture_jpeg) or None   # _call answers "" for None
        if picture is None:
            try:
                picture = encode_jpeg(false_colour(self._frame()), self._jpeg_quality)
            except ValueError as exc:
                raise CommandError(str(exc))
        self._write(path, staged, picture)
        return path

    def live_view(self):
        """(false-colour BGR picture, hottest point) of one fresh frame, for the live thermal view."""
        frame = self._frame()
        return false_colour(frame), hottest_point(frame)

    def set_measure_spot(self, data):
        self.measure_spot = self._pixel(data)
        return ""

    def measure_area(self):
        """(x0, y0, x1, y1), exclusive upper bounds, of the measurement area."""
        x, y = self.measure_spot
        half = self._box // 2
        return (max(0, x - half), max(0, y - half), min(self.width, x - half + self._box),
                min(self.height, y - half + self._box))

    def get_max_temperature(self, _data):
        x0, y0, x1, y1 = self.measure_area()
        return format_temperature(self._frame()[y0:y1, x0:x1].max())

    def get_spot_temperature(self, data):
        x, y = self._pixel(data)
        return format_temperature(self._frame()[y, x])
