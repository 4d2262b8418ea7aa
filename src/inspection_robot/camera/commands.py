"""camera_control / camera_cmd command table (INTERFACE.md section 4, "Camera").

Values are checked against the spec's sets before the driver sees them; a driver failure becomes
``failed`` with the driver's reason and marks the device unhealthy (diagnostics, sensor_status).
Continuous zoom/focus commands take a duration in ms (0 = until camera_stop): the move starts,
the command answers at once, and a timer stops it; a newer move or camera_stop supersedes it.
capture_picture creates a new file inside the capture roots and never replaces one (the spec's
data is a bare path: there is no field to ask for a replacement), never under a hidden name (the
robot's own, files.new_file_path) and never beyond the roots' quota (data_layout.CaptureQuota).
"""
import functools
import threading

from inspection_robot.files import PUBLIC_FILE_MODE, is_staged_name, new_file_path, write_atomic
from inspection_robot.camera.driver import CameraError
from inspection_robot.command import (CommandError, CommandTable, no_data, parse_choice,
                                      parse_float, parse_int)
from inspection_robot.interface import (EXPOSURE_MODES, FOCUS_MODES, FOCUS_POSITION_MAX,
                                        FOCUS_POSITION_MIN, IRIS_VALUES, MIN_FOCUS_DISTANCES_CM,
                                        WDR_LEVEL_MAX, WDR_LEVEL_MIN)

MOVE_DURATION_MAX_MS = 600000
NO_DATA_COMMANDS = ("get_zoom_level", "get_focus_mode", "get_focus_position", "camera_stop", "get_min_focus_distance",
                    "get_wdr_level", "get_wdr_mode", "get_exposure_mode", "get_iris")


def format_zoom(zoom):
    return "%.2f" % zoom


def parse_focus_position(text):
    """Decimal (4096) or hexadecimal with 0x (0x1000), within 0x1000..0xC000."""
    text = str(text)
    if text.lower().startswith("0x") and text[2:] and all(c in "0123456789abcdefABCDEF" for c in text[2:]):
        value = int(text, 16)
    else:
        value = parse_int(text, "focus position")
    if not FOCUS_POSITION_MIN <= value <= FOCUS_POSITION_MAX:
        raise CommandError("focus position out of range [0x%X, 0x%X]: %s" % (FOCUS_POSITION_MIN, FOCUS_POSITION_MAX,
                                                                             text))
    return value


class CameraCommands(object):
    """Builds the camera's CommandTable over ``driver``; ``roots`` (the capture roots, see
    data_layout.capture_roots) confine capture paths; ``quota`` (data_layout.CaptureQuota, None: none) bounds
    the bytes they hold."""

    def __init__(self, driver, optics, roots, health, timer_factory=threading.Timer, quota=None):
        self._driver = driver
        self._optics = optics
        self._roots = list(roots)
        self._quota = quota
        self._call = functools.partial(health.command, error=CameraError)
        self._timer_factory = timer_factory
        self._moves = {"zoom": (0, None), "focus": (0, None)}   # generation, timer
        self._moves_lock = threading.Lock()
        handlers = {
            "set_zoom_level": self.set_zoom_level,
            "get_zoom_level": lambda data: format_zoom(self._call(driver.get_zoom)),
            "capture_picture": self.capture_picture,
            "set_focus_mode": lambda data: self._call(driver.set_focus_mode,
                                                      parse_choice(data, "focus mode", FOCUS_MODES)),
            "get_focus_mode": lambda data: self._call(driver.get_focus_mode),
            "get_focus_position": lambda data: str(self._call(driver.get_focus_position)),
            "set_focus_position": lambda data: self._call(driver.set_focus_position, parse_focus_position(data)),
            "zoom_in": lambda data: self._start_move("zoom", +1, data),
            "zoom_out": lambda data: self._start_move("zoom", -1, data),
            "focus_far": lambda data: self._start_move("focus", +1, data),
            "focus_near": lambda data: self._start_move("focus", -1, data),
            "camera_stop": self.camera_stop,
            "set_osd_mode": lambda data: self._call(driver.set_osd, parse_choice(data, "osd mode", ("0", "1")) == "1"),
            "set_min_focus_distance": lambda data: self._call(
                driver.set_min_focus_distance, int(parse_choice(data, "min focus distance (cm)",
                                                                MIN_FOCUS_DISTANCES_CM))),
            "get_min_focus_distance": lambda data: str(self._call(driver.get_min_focus_distance)),
            "set_wdr_level": lambda data: self._call(driver.set_wdr_level,
                                                     parse_int(data, "wdr level", WDR_LEVEL_MIN, WDR_LEVEL_MAX)),
            "get_wdr_level": lambda data: str(self._call(driver.get_wdr_level)),
            "set_wdr_mode": lambda data: self._call(driver.set_wdr_mode,
                                                    parse_choice(data, "wdr mode", ("0", "1")) == "1"),
            "get_wdr_mode": lambda data: "1" if self._call(driver.get_wdr_mode) else "0",
            "set_exposure_mode": lambda data: self._call(driver.set_exposure_mode,
                                                         parse_choice(data, "exposure mode", EXPOSURE_MODES)),
            "get_exposure_mode": lambda data: self._call(driver.get_exposure_mode),
            "set_iris": self.set_iris,
            "get_iris": lambda data: str(self._call(driver.get_iris)),
        }
        for name in NO_DATA_COMMANDS:
            handlers[name] = no_data(handlers[name])
        self.table = CommandTable(handlers)
        # preset_scale's and find_scale's pictures, under a fresh hidden staged name they move away at
        # once: a table of its own behind a service of its own, which the backend surface does not offer
        self.staging_table = CommandTable({"capture_picture": lambda data: self.capture_picture(data, True)})

    def set_zoom_level(self, data):
        zoom = parse_float(data, "zoom level", self._optics.min_zoom, self._optics.max_zoom)
        self._cancel_move("zoom")
        self._call(self._driver.set_zoom, zoom)
        return ""

    def set_iris(self, data):
        iris = int(parse_choice(data, "iris", IRIS_VALUES))
        if self._call(self._driver.get_exposure_mode) != "manual":
            raise CommandError("set_iris needs exposure mode manual (set_exposure_mode manual first)")
        self._call(self._driver.set_iris, iris)
        return ""

    def capture_picture(self, data, staging=False):
        """A new JPEG at ``data`` (relative: in the first root); the answer is the absolute path.
        ``staging``: through :attr:`staging_table` only (a fresh files.staged_name is allowed)."""
        path = new_file_path(data, self._roots, staged=staging)   # refused before the camera is asked
        staged = staging and is_staged_name(data)
        if self._quota is not None:
            self._quota.check(1, "a picture", staged)  # full already: refused before the camera is asked
        jpeg = self._call(self._driver.capture_jpeg)
        if self._quota is not None:
            self._quota.check(len(jpeg), "this picture", staged)
        # a file that appeared meanwhile is not replaced either; 644: a backend fetches captures
        write_atomic(path, jpeg, replace=False, mode=PUBLIC_FILE_MODE)
        if self._quota is not None:
            self._quota.add(len(jpeg))
        return path

    def _start_move(self, kind, direction, data):
        duration_ms = parse_int(data, "duration (ms)", 0, MOVE_DURATION_MAX_MS)
        start = self._driver.start_zoom if kind == "zoom" else self._driver.start_focus
        stop = self._driver.stop_zoom if kind == "zoom" else self._driver.stop_focus
        generation = self._cancel_move(kind)
        self._call(start, direction)
        if duration_ms > 0:
            timer = self._timer_factory(duration_ms / 1000.0, self._end_move, (kind, generation, stop))
            timer.daemon = True
            with self._moves_lock:
                self._moves[kind] = (generation, timer)
            timer.start()
        return ""

    def _cancel_move(self, kind):
        """Forget any timed stop of ``kind``; returns the generation of the next move."""
        with self._moves_lock:
            generation, timer = self._moves[kind]
            if timer is not None:
                timer.cancel()
            self._moves[kind] = (generation + 1, None)
            return generation + 1

    def _end_move(self, kind, generation, stop):
        with self._moves_lock:
            if self._moves[kind][0] != generation:
                return   # superseded by a newer move or camera_stop
            self._moves[kind] = (generation, None)
        try:
            self._call(stop)
        except CommandError:
            pass   # recorded in health; nobody waits for this answer

    def camera_stop(self, _data):
        self._cancel_move("zoom")
        self._cancel_move("focus")
        self._call(self._driver.stop_zoom)
        self._call(self._driver.stop_focus)
        return ""

    def shutdown(self):
        """Stop any continuous move (node shutdown)."""
        for kind in ("zoom", "focus"):
            self._cancel_move(kind)
        try:
            self._driver.stop_zoom()
            self._driver.stop_focus()
        except CameraError:
            pass
