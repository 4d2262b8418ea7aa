"""Hikvision ISAPI driver: HTTP with digest authentication, XML documents, JPEG snapshots.

Endpoints (channel ``c``, default 1; settings are read, modified and written back so that the
camera's other fields are preserved):

| what | method and path | element(s) |
|---|---|---|
| zoom (absolute) | PUT /ISAPI/PTZCtrl/channels/c/absolute | PTZData/AbsoluteHigh/absoluteZoom (x10) |
| zoom (read), probe | GET /ISAPI/PTZCtrl/channels/c/status | PTZStatus/AbsoluteHigh/absoluteZoom |
| continuous zoom | PUT /ISAPI/PTZCtrl/channels/c/continuous | PTZData/zoom (-100..100, 0 stops) |
| continuous focus | PUT /ISAPI/System/Video/inputs/channels/c/focus | FocusData/focus (-100..100, 0 stops) |
| focus position | /ISAPI/PTZCtrl/channels/c/absoluteEx | PTZAbsoluteEx/focus |
| focus mode, min focus distance | /ISAPI/Image/channels/c/focusConfiguration | focusStyle, focusLimited (cm) |
| WDR | /ISAPI/Image/channels/c/WDR | mode (open/close), WDRLevel |
| exposure mode | /ISAPI/Image/channels/c/exposure | ExposureType |
| iris | /ISAPI/Image/channels/c/Iris | IrisLevel (f-number x 100) |
| OSD | /ISAPI/System/Video/inputs/channels/c/overlays | every ``enabled`` |
| picture | GET /ISAPI/Streaming/channels/c01/picture, else the snapshot URL | JPEG |
"""
import urllib.parse

import numpy as np

from inspection_robot.isapi import JPEG_MAGIC, IsapiClient, IsapiErrors, IsapiHints, find_all
from inspection_robot.lazy import lazy_import
from inspection_robot.camera.driver import CameraDriver, CameraError

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load

FOCUS_STYLES = {"auto": "AUTO", "manual": "MANUAL", "semiauto": "SEMIAUTOMATIC"}
CONTINUOUS_SPEED = 60


class CameraUnreachable(CameraError):
    """No HTTP exchange with the camera (connection refused/reset, timeout, DNS)."""


class CameraRefused(CameraError):
    """The camera refused the credentials (HTTP 401 after the digest challenge)."""


ERRORS = IsapiErrors(CameraError, CameraUnreachable, CameraRefused, CameraError)
HINTS = IsapiHints("camera", "camera_node ~isapi/url", "camera_node ~isapi/user and ~isapi/password")


class IsapiCamera(CameraDriver):
    def __init__(self, url, user, password, channel=1, timeout=2.0, snapshot_url="/onvif-http/snapshot?Profile_1"):
        base = url.rstrip("/")
        self._channel = int(channel)
        self._snapshot_url = urllib.parse.urljoin(base + "/", snapshot_url.lstrip("/")) \
            if not snapshot_url.startswith("http") else snapshot_url
        self._http = IsapiClient(base, user, password, timeout, ERRORS, HINTS, (self._snapshot_url,))
        self._base = self._http.base

    # --- transport (inspection_robot.isapi) --------------------------------------------------
    def _request(self, method, path_or_url, body=None):
        return self._http.request(method, path_or_url, body).payload

    def _get_xml(self, path):
        return self._http.get_xml(path)

    def _check_status(self, payload, path):
        self._http.check_status(payload, path)

    def _read(self, path, name):
        return self._http.read(path, name)

    def _update(self, path, values):
        self._http.update(path, values)

    def _ptz(self, leaf):
        return "/ISAPI/PTZCtrl/channels/%d/%s" % (self._channel, leaf)

    def _image(self, leaf):
        return "/ISAPI/Image/channels/%d/%s" % (self._channel, leaf)

    def _video(self, leaf):
        return "/ISAPI/System/Video/inputs/channels/%d/%s" % (self._channel, leaf)

    def _int(self, text, what):
        try:
            return int(float(text))
        except ValueError:
            raise CameraError("camera %s sent a non-numeric %s: %r" % (self._base, what, text))

    # --- zoom and focus ---------------------------------------------------------------------
    def get_zoom(self):
        return self._int(self._read(self._ptz("status"), "absoluteZoom"), "absoluteZoom") / 10.0

    def set_zoom(self, zoom):
        status = self._get_xml(self._ptz("status"))
        elevation = find_all(status, "elevation")
        azimuth = find_all(status, "azimuth")
        body = ("<PTZData><AbsoluteHigh><elevation>%s</elevation><azimuth>%s</azimuth>"
                "<absoluteZoom>%d</absoluteZoom></AbsoluteHigh></PTZData>"
                % (elevation[0].text if elevation else "0", azimuth[0].text if azimuth else "0",
                   int(round(zoom * 10))))
        self._check_status(self._request("PUT", self._ptz("absolute"), body), "absolute")

    def _continuous_zoom(self, speed):
        body = "<PTZData><pan>0</pan><tilt>0</tilt><zoom>%d</zoom></PTZData>" % speed
        self._check_status(self._request("PUT", self._ptz("continuous"), body), "continuous")

    def start_zoom(self, direction):
        self._continuous_zoom(CONTINUOUS_SPEED if direction > 0 else -CONTINUOUS_SPEED)

    def stop_zoom(self):
        self._continuous_zoom(0)

    def _continuous_focus(self, speed):
        body = "<FocusData><focus>%d</focus></FocusData>" % speed
        self._check_status(self._request("PUT", self._video("focus"), body), "focus")

    def start_focus(self, direction):
        self._continuous_focus(CONTINUOUS_SPEED if direction > 0 else -CONTINUOUS_SPEED)

    def stop_focus(self):
        self._continuous_focus(0)

    def get_focus_position(self):
        return self._int(self._read(self._ptz("absoluteEx"), "focus"), "focus")

    def set_focus_position(self, position):
        self._update(self._ptz("absoluteEx"), {"focus": int(position)})

    def get_focus_mode(self):
        style = self._read(self._image("focusConfiguration"), "focusStyle").upper()
        for mode, name in FOCUS_STYLES.items():
            if name == style:
                return mode
        raise CameraError("camera %s reports an unknown focusStyle %r" % (self._base, style))

    def set_focus_mode(self, mode):
        self._update(self._image("focusConfiguration"), {"focusStyle": FOCUS_STYLES[mode]})

    def get_min_focus_distance(self):
        return self._int(self._read(self._image("focusConfiguration"), "focusLimited"), "focusLimited")

    def set_min_focus_distance(self, cm):
        self._update(self._image("focusConfiguration"), {"focusLimited": int(cm)})

    # --- picture settings -------------------------------------------------------------------
    def set_osd(self, enabled):
        self._update(self._video("overlays"), {"enabled": "true" if enabled else "false"})

    def get_wdr_level(self):
        return self._int(self._read(self._image("WDR"), "WDRLevel"), "WDRLevel")

    def set_wdr_level(self, level):
        self._update(self._image("WDR"), {"WDRLevel": int(level)})

    def get_wdr_mode(self):
        return self._read(self._image("WDR"), "mode") == "open"

    def set_wdr_mode(self, enabled):
        self._update(self._image("WDR"), {"mode": "open" if enabled else "close"})

    def get_exposure_mode(self):
        # vendor modes IrisFirst, ShutterFirst, GainFirst ... are automatic exposure for the spec
        return "manual" if self._read(self._image("exposure"), "ExposureType").lower() == "manual" else "auto"

    def set_exposure_mode(self, mode):
        self._update(self._image("exposure"), {"ExposureType": mode})

    def get_iris(self):
        return self._int(self._read(self._image("Iris"), "IrisLevel"), "IrisLevel")

    def set_iris(self, iris):
        self._update(self._image("Iris"), {"IrisLevel": int(iris)})

    # --- pictures ---------------------------------------------------------------------------
    def capture_jpeg(self):
        path = "/ISAPI/Streaming/channels/%d01/picture" % self._channel
        try:
            payload = self._request("GET", path)
            if payload.startswith(JPEG_MAGIC):
                return payload
        except (CameraUnreachable, CameraRefused):
            raise   # the snapshot URL would fail the same way
        except CameraError:
            pass    # e.g. HTTP 400/404: no ISAPI picture endpoint on this firmware
        # some firmware lacks the ISAPI picture endpoint: the snapshot URL still serves JPEG
        payload = self._request("GET", self._snapshot_url)
        if not payload.startswith(JPEG_MAGIC):
            raise CameraError("camera %s snapshot is not a JPEG" % self._base)
        return payload

    def grab_frame(self, width):
        img = cv2.imdecode(np.frombuffer(self.capture_jpeg(), np.uint8), cv2.IMREAD_COLOR)
        if img is None:
            raise CameraError("camera %s sent an undecodable JPEG" % self._base)
        height = int(round(img.shape[0] * width / float(img.shape[1])))
        return cv2.resize(img, (int(width), max(1, height)), interpolation=cv2.INTER_AREA)

    def probe(self):
        self._request("GET", "/ISAPI/System/deviceInfo")
