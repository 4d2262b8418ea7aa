"""Hikvision thermographic cameras over ISAPI: the ThermalDriver of infrared_imager ``~driver: isapi``.

Endpoints (Hikvision "Intelligent Security API (Thermal)"; channel ``c`` is the thermal channel:
2 on bi-spectrum cameras, 1 on thermal-only ones; transport, digest authentication and timeouts
are the visible camera's, inspection_robot.isapi):

| what | method and path | answer |
|---|---|---|
| temperature matrix | GET /ISAPI/Thermal/channels/c/thermometry/jpegPicWithAppendData?format=json | multipart |
| picture without a matrix | GET /ISAPI/Streaming/channels/c01/picture | JPEG (the camera's palette) |
| auto_focus | PUT /ISAPI/PTZCtrl/channels/c/onepushfoucs/start (sic: Hikvision's spelling) | ResponseStatus |
| probe | GET /ISAPI/Thermal/channels/c/thermometry/basicParam | ThermometryBasicParam |

jpegPicWithAppendData answers ``multipart/form-data`` (or ``multipart/mixed``) with these parts:
``application/json`` ``{"JpegPictureWithAppendData": {"channel", "jpegPicLen", "jpegPicWidth",
"jpegPicHeight", "p2pDataLen", "isFreezedata", "temperatureDataLength", "scale", "offset"}}``, the
thermal JPEG (``image/jpeg``), the pixel-to-pixel temperature matrix (``application/octet-stream``,
p2pDataLen bytes, row by row from the top-left pixel, little-endian), and on bi-spectrum cameras a
visible JPEG. The matrix is jpegPicWidth x jpegPicHeight values of temperatureDataLength bytes:
4 = float32 degC; 2 = unsigned 16-bit ``v`` with degC = v / scale + offset - 273.15 (Kelvin
counts: never negative, so unsigned). Spot, box, high and low temperatures are read from this
matrix, the camera's own per-pixel thermometry. A camera without it (HTTP 404 or ResponseStatus
subStatusCode notSupport) answers the temperature commands ``failed``/``unsupported``; a fixed-lens
camera answers auto_focus the same way.
"""
import json
from collections import namedtuple

import numpy as np

from inspection_robot.files import read_secret_file
from inspection_robot.lazy import lazy_import
from inspection_robot.interface import INFRARED_COMMANDS
from inspection_robot.isapi import JPEG_MAGIC, NOT_SUPPORTED, IsapiClient, IsapiErrors, IsapiHints, \
    multipart_parts, response_status
from inspection_robot.thermal.driver import ThermalDriver, ThermalError, ThermalRefused, ThermalUnreachable, \
    ThermalUnsupported

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load

ERRORS = IsapiErrors(ThermalError, ThermalUnreachable, ThermalRefused, ThermalUnsupported)
HINTS = IsapiHints("thermal imager", "infrared_imager ~isapi/host and ~isapi/port",
                   "infrared_imager ~isapi/user and ~isapi/password_file")
CHANNEL_HINT = ("infrared_imager ~isapi/channel: the thermal channel, 2 on bi-spectrum cameras, 1 on thermal-only "
                "ones")
DEVICE_HINT = ("that infrared_imager ~isapi/host and ~isapi/port name a Hikvision thermographic camera and "
               "~isapi/channel its thermal channel")
MAX_SIDE_PX = 4096
PLAUSIBLE_DEGC = (-273.15, 3000.0)   # beyond any radiometric range Hikvision sells (-20..2000 degC)
KELVIN_OFFSET = 273.15
SETTINGS = ("host", "port", "user", "password_file", "channel", "timeout", "picture_timeout")

RadiometricPicture = namedtuple("RadiometricPicture", "matrix jpeg visible_jpeg frozen")
"""matrix: float32 degC (height x width); jpeg: the thermal JPEG; visible_jpeg: bytes or None;
frozen: isFreezedata (the camera held the last data during a shutter calibration)."""


def _positive_int(meta, key, limit=None):
    value = meta.get(key)
    if isinstance(value, bool) or not isinstance(value, int) or value <= 0 or (limit and value > limit):
        raise ValueError("JpegPictureWithAppendData %s is %r, not a positive integer%s"
                         % (key, value, " up to %d" % limit if limit else ""))
    return value


def decode_temperature_matrix(meta, data):
    """The float32 degC matrix of a JpegPictureWithAppendData description ``meta`` and its binary
    part ``data``. ValueError with the reason when they disagree or the values make no sense."""
    width = _positive_int(meta, "jpegPicWidth", MAX_SIDE_PX)
    height = _positive_int(meta, "jpegPicHeight", MAX_SIDE_PX)
    size = meta.get("temperatureDataLength", 4)
    if size not in (2, 4):
        raise ValueError("JpegPictureWithAppendData temperatureDataLength is %r, not 2 or 4" % (size,))
    expected = width * height * size
    declared = meta.get("p2pDataLen", expected)
    if declared != expected:
        raise ValueError("p2pDataLen %r does not match %dx%d values of %d bytes (%d)"
                         % (declared, width, height, size, expected))
    if len(data) != expected:
        raise ValueError("temperature matrix has %d bytes, %dx%d values of %d bytes need %d"
                         % (len(data), width, height, size, expected))
    if size == 4:
        matrix = np.frombuffer(data, "<f4").astype(np.float32)
    else:
        try:
            scale, offset = float(meta["scale"]), float(meta["offset"])
        except (KeyError, TypeError, ValueError):
            raise ValueError("16-bit temperature matrix without a numeric scale and offset")
        if not np.isfinite(scale) or scale <= 0 or not np.isfinite(offset):
            raise ValueError("16-bit temperature matrix with scale %r and offset %r"
                             % (meta["scale"], meta["offset"]))
        matrix = (np.frombuffer(data, "<u2").astype(np.float64) / scale + offset - KELVIN_OFFSET).astype(np.float32)
    matrix = matrix.reshape(height, width)
    if not np.all(np.isfinite(matrix)):
        raise ValueError("temperature matrix holds NaN or infinite values")
    low, high = float(matrix.min()), float(matrix.max())
    if low < PLAUSIBLE_DEGC[0] or high > PLAUSIBLE_DEGC[1]:
        raise ValueError("temperature matrix spans %.1f..%.1f degC, no thermographic camera measures that"
                         % (low, high))
    return matrix


def parse_picture_with_append_data(payload, content_type):
    """RadiometricPicture of a jpegPicWithAppendData answer; ValueError with the reason otherwise."""
    parts = multipart_parts(payload, content_type)
    meta, jpegs, matrix_data = None, [], None
    for headers, body in parts:
        kind = headers.get("content-type", "").split(";")[0].strip().lower()
        if kind == "application/json" and meta is None:
            try:
                doc = json.loads(body.decode("utf-8"))
            except ValueError as err:
                raise ValueError("malformed JSON description: %s" % err)
            meta = doc.get("JpegPictureWithAppendData") if isinstance(doc, dict) else None
            if not isinstance(meta, dict):
                raise ValueError("JSON part has no JpegPictureWithAppendData object")
        elif kind == "image/jpeg":
            jpegs.append(body)
        elif kind == "application/octet-stream" and matrix_data is None:
            matrix_data = body
    if meta is None:
        raise ValueError("no JpegPictureWithAppendData description among %d parts" % len(parts))
    if matrix_data is None:
        raise ValueError("no temperature matrix (application/octet-stream part): is the camera radiometric?")
    matrix = decode_temperature_matrix(meta, matrix_data)
    if not jpegs or not jpegs[0].startswith(JPEG_MAGIC):
        raise ValueError("no thermal JPEG part")
    visible = jpegs[1] if len(jpegs) > 1 and jpegs[1].startswith(JPEG_MAGIC) else None
    return RadiometricPicture(matrix, jpegs[0], visible, bool(meta.get("isFreezedata", False)))


def _number(settings, key, default, minimum, kind=float):
    value = settings.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float) if kind is float else int) or \
            not value >= minimum or value != value:
        raise ValueError("infrared_imager ~isapi/%s must be %s >= %s, got %r"
                         % (key, "a number" if kind is float else "an integer", minimum, value))
    return kind(value)


def imager_from_settings(settings, read_secret=read_secret_file):
    """IsapiImager for infrared_imager's ``~isapi`` dict (host, port 80, user "admin", password_file,
    channel 2, timeout 2.0 s, picture_timeout 5.0 s); ValueError naming the setting to fix."""
    unknown = sorted(set(settings) - set(SETTINGS))
    if unknown:
        raise ValueError("infrared_imager ~isapi has unknown setting(s) %s (known: %s)"
                         % (", ".join(unknown), ", ".join(SETTINGS)))
    host = str(settings.get("host", "")).strip()
    if not host:
        raise ValueError("infrared_imager ~isapi/host is not set: the thermal camera's address")
    port = _number(settings, "port", 80, 1, int)
    if port > 65535:
        raise ValueError("infrared_imager ~isapi/port must be 1..65535, got %r" % port)
    password_file = str(settings.get("password_file", "")).strip()
    if not password_file:
        raise ValueError("infrared_imager ~isapi/password_file is not set: a file (mode 600) holding the "
                         "thermal camera's password")
    password = read_secret(password_file, "infrared_imager ~isapi/password_file")
    url = "http://%s:%d" % ("[%s]" % host if ":" in host else host, port)
    return IsapiImager(url, str(settings.get("user", "admin")), password, _number(settings, "channel", 2, 1, int),
                       _number(settings, "timeout", 2.0, 0.01), _number(settings, "picture_timeout", 5.0, 0.01))


class IsapiImager(ThermalDriver):
    supported = INFRARED_COMMANDS   # what the camera lacks it reports per request (ThermalUnsupported)

    def __init__(self, url, user, password, channel=2, timeout=2.0, picture_timeout=5.0):
        self._channel = int(channel)
        self._picture_timeout = float(picture_timeout)
        self._http = IsapiClient(url, user, password, timeout, ERRORS, HINTS)

    def _thermal(self, leaf):
        return "/ISAPI/Thermal/channels/%d/thermometry/%s" % (self._channel, leaf)

    def picture(self):
        """RadiometricPicture of one exchange with the camera."""
        path = self._thermal("jpegPicWithAppendData?format=json")
        response = self._http.request("GET", path, timeout=self._picture_timeout)
        status = response_status(response.payload)
        if status is not None and status[1] == NOT_SUPPORTED:
            raise ThermalUnsupported("thermal imager %s has no temperature matrix on channel %d (%s)"
                                     % (self._http.base, self._channel, status[1]))
        try:
            picture = parse_picture_with_append_data(response.payload, response.content_type)
        except ValueError as err:
            raise ThermalError("thermal imager %s sent no radiometric picture for %s: %s (check %s)"
                               % (self._http.base, path, err, DEVICE_HINT))
        return picture

    def frame(self):
        return self.picture().matrix

    def capture_jpeg(self):
        """The thermal JPEG of jpegPicWithAppendData: the picture of the temperature matrix, pixel for
        pixel, so boxes drawn on it fit the frame. None (false colour of the matrix) when its size
        differs; the streaming picture on a camera without the matrix."""
        try:
            picture = self.picture()
        except ThermalUnsupported:
            path = "/ISAPI/Streaming/channels/%d01/picture" % self._channel
            payload = self._http.request("GET", path, timeout=self._picture_timeout).payload
            if not payload.startswith(JPEG_MAGIC):
                raise ThermalError("thermal imager %s sent no JPEG for %s (check %s)"
                                   % (self._http.base, path, DEVICE_HINT))
            return payload
        image = cv2.imdecode(np.frombuffer(picture.jpeg, np.uint8), cv2.IMREAD_UNCHANGED)
        if image is None or image.shape[:2] != picture.matrix.shape:
            return None
        return picture.jpeg

    def auto_focus(self):
        self._http.put("/ISAPI/PTZCtrl/channels/%d/onepushfoucs/start" % self._channel, "")

    def probe(self):
        try:
            self._http.get_xml(self._thermal("basicParam"))
        except ThermalUnsupported as err:
            raise ThermalError("%s: no thermometry on channel %d (check %s)" % (err, self._channel, CHANNEL_HINT))
