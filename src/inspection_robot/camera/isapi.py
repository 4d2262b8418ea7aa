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
import urllib.error
import urllib.parse
import urllib.request
import xml.etree.ElementTree as ElementTree

import numpy as np

from inspection_robot.lazy import lazy_import
from inspection_robot.camera.driver import CameraDriver, CameraError

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load

FOCUS_STYLES = {"auto": "AUTO", "manual": "MANUAL", "semiauto": "SEMIAUTOMATIC"}
CONTINUOUS_SPEED = 60
JPEG_MAGIC = b"\xff\xd8"


def _local(tag):
    return tag.rsplit("}", 1)[-1]


def _find_all(root, name):
    return [el for el in root.iter() if _local(el.tag) == name]


class CameraUnreachable(CameraError):
    """No HTTP exchange with the camera (connection refused/reset, timeout, DNS)."""


class CameraRefused(CameraError):
    """The camera refused the credentials (HTTP 401 after the digest challenge)."""


class IsapiCamera(CameraDriver):
    def __init__(self, url, user, password, channel=1, timeout=2.0, snapshot_url="/onvif-http/snapshot?Profile_1"):
        self._base = url.rstrip("/")
        self._channel = int(channel)
        self._timeout = float(timeout)
        self._snapshot_url = urllib.parse.urljoin(self._base + "/", snapshot_url.lstrip("/")) \
            if not snapshot_url.startswith("http") else snapshot_url
        passwords = urllib.request.HTTPPasswordMgrWithDefaultRealm()
        passwords.add_password(None, self._base, user, password)
        passwords.add_password(None, self._snapshot_url, user, password)
        self._digest = urllib.request.HTTPDigestAuthHandler(passwords)
        self._opener = urllib.request.build_opener(self._digest)

    # --- transport --------------------------------------------------------------------------
    def _request(self, method, path_or_url, body=None, accept_jpeg=False):
        url = path_or_url if path_or_url.startswith("http") else self._base + path_or_url
        data = None if body is None else body.encode("utf-8")
        request = urllib.request.Request(url, data=data, method=method)
        if data is not None:
            request.add_header("Content-Type", "application/xml; charset=UTF-8")
        # urllib counts digest retries per handler and resets the count only after a success: once
        # the camera refused the credentials, every later challenge would fail at once ("digest auth
        # failed") even after the camera accepts them again. Each request gets its own count.
        self._digest.reset_retry_count()
        try:
            with self._opener.open(request, timeout=self._timeout) as response:
                payload = response.read()
        except urllib.error.HTTPError as err:
            if err.code == 401:
                raise CameraRefused("camera %s refused the credentials (HTTP 401, digest)" % self._base)
            where = url[len(self._base):] if url.startswith(self._base) else url
            raise CameraError("camera %s answered HTTP %d to %s %s" % (self._base, err.code, method, where))
        except (urllib.error.URLError, OSError) as err:
            reason = getattr(err, "reason", err)
            raise CameraUnreachable("camera unreachable at %s: %s" % (self._base, reason))
        return payload

    def _get_xml(self, path):
        payload = self._request("GET", path)
        try:
            root = ElementTree.fromstring(payload)
        except ElementTree.ParseError as err:
            raise CameraError("camera %s sent malformed XML for %s: %s" % (self._base, path, err))
        # keep the camera's default namespace as a plain xmlns attribute (no ns0: prefixes on PUT)
        namespace = root.tag[1:].split("}", 1)[0] if root.tag.startswith("{") else None
        for element in root.iter():
            element.tag = _local(element.tag)
        if namespace:
            root.set("xmlns", namespace)
        return root

    def _put_xml(self, path, root):
        self._check_status(self._request("PUT", path, ElementTree.tostring(root, encoding="unicode")), path)

    def _check_status(self, payload, path):
        """ISAPI answers PUTs with a ResponseStatus; statusCode 1 is OK."""
        try:
            root = ElementTree.fromstring(payload)
        except ElementTree.ParseError:
            return
        codes = _find_all(root, "statusCode")
        if codes and codes[0].text not in ("1", None):
            status = _find_all(root, "statusString")
            reason = status[0].text if status else codes[0].text
            raise CameraError("camera %s refused %s: %s" % (self._base, path, reason))

    def _read(self, path, name):
        elements = _find_all(self._get_xml(path), name)
        if not elements or elements[0].text is None:
            raise CameraError("camera %s does not report %s in %s" % (self._base, name, path))
        return elements[0].text.strip()

    def _update(self, path, values):
        """Read ``path``, set each element named in ``values`` (all occurrences), write it back."""
        root = self._get_xml(path)
        for name, value in values.items():
            elements = _find_all(root, name)
            if not elements:
                raise CameraError("camera %s does not support %s in %s" % (self._base, name, path))
            for element in elements:
                element.text = str(value)
        self._put_xml(path, root)

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
        elevation = _find_all(status, "elevation")
        azimuth = _find_all(status, "azimuth")
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
