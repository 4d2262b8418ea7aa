"""A local stand-in for a Hikvision camera's ISAPI web service, for testing the real drivers.

A bi-spectrum camera: the visible channel (``channel``, 1) serves the documents camera.isapi reads
and writes; the thermal channel (``thermal_channel``, 2) serves what thermal.isapi reads, bytes as
the camera sends them: ThermometryBasicParam, the thermal picture, and jpegPicWithAppendData as a
multipart body (JSON description, thermal JPEG, little-endian temperature matrix of
``temperature_data_length`` 4 = float32 degC or 2 = uint16 Kelvin x ``scale``, visible JPEG).
``radiometric=False`` answers jpegPicWithAppendData, ``thermal_focus=False`` (a fixed lens, the
default) answers onepushfoucs/start with ResponseStatus notSupport (HTTP 403), as a camera without
the function. Requests are served with with HTTP digest authentication (MD5,
qop=auth) exactly as the camera does: a request without valid credentials gets ``401`` and a
``WWW-Authenticate: Digest`` challenge. PUTs answer an ISAPI ResponseStatus. The picture
endpoint can be switched off (``picture_endpoint=False``) to exercise the snapshot fallback.
Binds 127.0.0.1, port 0 by default (any free port); ``stop()`` makes the camera unreachable and
``start()`` on the same port brings it back. ``set_fault("401")`` makes it refuse every request
(even with the right credentials, as a camera whose password was changed), ``set_fault("timeout")``
makes it accept connections and never answer until ``set_fault(None)``, ``set_fault("garbage")``
answers every request at once with HTTP 200 and bytes that are neither XML, JSON nor a picture (a
device at that address that is no camera).
"""
import hashlib
import json
import os
import re
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from urllib.parse import urlsplit

import cv2
import numpy as np

NS = "http://www.hikvision.com/ver20/XMLSchema"
REALM = "IP Camera(C00000001)"
FAULTS = (None, "401", "timeout", "garbage")
GARBAGE = b"\x00\x17<<garbage\xff\xfe not a camera \x89PNG\r\n"
BOUNDARY = "boundary"


def _md5(text):
    return hashlib.md5(text.encode("utf-8")).hexdigest()


def default_documents(channel=1):
    c = channel
    docs = {
        "/ISAPI/System/deviceInfo": "<DeviceInfo><deviceName>fake</deviceName><model>DS-2DF8230</model></DeviceInfo>",
        "/ISAPI/PTZCtrl/channels/%d/status" % c: "<PTZStatus><AbsoluteHigh><elevation>0</elevation>"
                                                 "<azimuth>0</azimuth><absoluteZoom>10</absoluteZoom>"
                                                 "</AbsoluteHigh></PTZStatus>",
        "/ISAPI/PTZCtrl/channels/%d/absoluteEx" % c: "<PTZAbsoluteEx><elevation>0</elevation><azimuth>0</azimuth>"
                                                     "<absoluteZoom>1.0</absoluteZoom><focus>24576</focus>"
                                                     "</PTZAbsoluteEx>",
        "/ISAPI/Image/channels/%d/focusConfiguration" % c: "<FocusConfiguration><focusStyle>AUTO</focusStyle>"
                                                           "<focusLimited>150</focusLimited></FocusConfiguration>",
        "/ISAPI/Image/channels/%d/WDR" % c: "<WDR><mode>close</mode><WDRLevel>50</WDRLevel></WDR>",
        "/ISAPI/Image/channels/%d/exposure" % c: "<Exposure><ExposureType>auto</ExposureType>"
                                                 "<OverexposeSuppress><enabled>false</enabled></OverexposeSuppress>"
                                                 "</Exposure>",
        "/ISAPI/Image/channels/%d/Iris" % c: "<Iris><IrisLevel>400</IrisLevel></Iris>",
        "/ISAPI/System/Video/inputs/channels/%d/overlays" % c: "<VideoOverlay><channelNameOverlay><enabled>true"
                                                               "</enabled><name>Camera 01</name></channelNameOverlay>"
                                                               "<DateTimeOverlay><enabled>true</enabled>"
                                                               "</DateTimeOverlay></VideoOverlay>",
    }
    return {path: '<?xml version="1.0" encoding="UTF-8"?>\n' + xml.replace(">", ' version="2.0" xmlns="%s">' % NS, 1)
            for path, xml in docs.items()}


def thermal_documents(channel=2):
    basic = ("<ThermometryBasicParam><id>%d</id><enabled>true</enabled><streamOverlay>true</streamOverlay>"
             "<pictureOverlay>false</pictureOverlay><temperatureRange>-20-150</temperatureRange>"
             "<temperatureUnit>degreeCentigrade</temperatureUnit><distanceUnit>meter</distanceUnit>"
             "</ThermometryBasicParam>" % channel)
    return {"/ISAPI/Thermal/channels/%d/thermometry/basicParam" % channel:
            '<?xml version="1.0" encoding="UTF-8"?>\n' + basic.replace(">", ' version="2.0" xmlns="%s">' % NS, 1)}


def sample_thermal_frame(width=384, height=288):
    """A radiometric scene: 18..24 degC left to right, a 95.25 degC hot spot centred on (200, 100)."""
    frame = np.tile(np.linspace(18.0, 24.0, width, dtype=np.float32), (height, 1))
    cv2.circle(frame, (200, 100), 6, 95.25, -1)
    return frame


def thermal_picture(frame):
    scaled = np.clip((frame - frame.min()) * (255.0 / max(float(np.ptp(frame)), 1e-6)), 0, 255).astype(np.uint8)
    return cv2.imencode(".jpg", cv2.applyColorMap(scaled, cv2.COLORMAP_JET))[1].tobytes()


def temperature_matrix_bytes(frame, data_length=4, scale=10.0, offset=0.0):
    """The matrix as jpegPicWithAppendData carries it (little-endian, row by row)."""
    if data_length == 4:
        return frame.astype("<f4").tobytes()
    return np.round((frame.astype(np.float64) + 273.15 - offset) * scale).astype("<u2").tobytes()


def picture_with_append_data(frame, jpeg, visible_jpeg, channel, data_length=4, scale=10.0, offset=0.0):
    """(body, Content-Type) of a jpegPicWithAppendData answer."""
    height, width = frame.shape
    matrix = temperature_matrix_bytes(frame, data_length, scale, offset)
    meta = {"channel": channel, "jpegPicLen": len(jpeg), "jpegPicWidth": width, "jpegPicHeight": height,
            "p2pDataLen": len(matrix), "isFreezedata": False, "temperatureDataLength": data_length}
    if data_length == 2:
        meta.update(scale=scale, offset=offset)
    description = json.dumps({"JpegPictureWithAppendData": meta}).encode("utf-8")
    body = b""
    for kind, part in (("application/json", description), ("image/jpeg", jpeg),
                       ("application/octet-stream", matrix), ("image/jpeg", visible_jpeg)):
        body += (("--%s\r\nContent-Type: %s\r\nContent-Length: %d\r\n\r\n" % (BOUNDARY, kind, len(part)))
                 .encode("latin-1") + part + b"\r\n")
    return body + ("--%s--\r\n" % BOUNDARY).encode("latin-1"), "multipart/form-data; boundary=%s" % BOUNDARY


def test_picture(width=320, height=180):
    img = np.full((height, width, 3), 90, np.uint8)
    cv2.circle(img, (width // 2, height // 2), min(width, height) // 3, (240, 240, 240), -1)
    cv2.line(img, (width // 2, height // 2), (width // 2 + height // 4, height // 4), (10, 10, 10), 3)
    return cv2.imencode(".jpg", img)[1].tobytes()


class FakeIsapiCamera(object):
    def __init__(self, user="admin", password="secret12", port=0, channel=1, picture=None, picture_endpoint=True,
                 thermal_channel=2, thermal_frame=None, temperature_data_length=4, radiometric=True,
                 thermal_focus=False):
        self.user, self.password = user, password
        self.channel = channel
        self.port = int(port)
        self.picture = picture if picture is not None else test_picture()
        self.picture_endpoint = picture_endpoint
        self.documents = default_documents(channel)
        self.thermal_channel = thermal_channel
        self.documents.update(thermal_documents(thermal_channel))
        self.thermal_frame = thermal_frame if thermal_frame is not None else sample_thermal_frame()
        self.thermal_picture = thermal_picture(self.thermal_frame)
        self.temperature_data_length = temperature_data_length
        self.radiometric = radiometric
        self.thermal_focus = thermal_focus
        self.focus_pushes = 0
        self.lock = threading.Lock()
        self.challenges = 0
        self.requests = []          # (method, path, body) of every authenticated request
        self.continuous = {"zoom": 0, "focus": 0}
        self._nonces = set()
        self.fault = None
        self._answering = threading.Event()   # set unless the "timeout" fault holds requests
        self._answering.set()
        self._server = None
        self._thread = None

    @property
    def url(self):
        return "http://127.0.0.1:%d" % self.port

    def start(self):
        camera = self

        class Handler(_Handler):
            fake = camera
        self._server = ThreadingHTTPServer(("127.0.0.1", self.port), Handler)
        self._server.daemon_threads = True
        self.port = self._server.server_address[1]
        self._thread = threading.Thread(target=self._server.serve_forever, kwargs={"poll_interval": 0.05})
        self._thread.daemon = True
        self._thread.start()
        return self

    def set_fault(self, fault):
        """None: answer normally; "401": refuse every request; "timeout": accept and never answer;
        "garbage": answer every request with bytes that mean nothing."""
        if fault not in FAULTS:
            raise ValueError("fault must be one of %s, got %r" % (FAULTS, fault))
        self.fault = fault
        if fault == "timeout":
            self._answering.clear()
        else:
            self._answering.set()

    def hold(self, limit=60.0):
        """A request under the "timeout" fault: wait until the fault clears (at most ``limit`` s)."""
        self._answering.wait(limit)

    def stop(self):
        self._answering.set()
        if self._server is not None:
            self._server.shutdown()
            self._server.server_close()
            self._thread.join(2.0)
            self._server = None

    def new_nonce(self):
        nonce = os.urandom(12).hex()
        with self.lock:
            self._nonces.add(nonce)
        return nonce

    def authorized(self, method, header):
        if not header or not header.startswith("Digest "):
            return False
        fields = {m.group(1): m.group(2) if m.group(2) is not None else m.group(3)
                  for m in re.finditer(r'(\w+)=(?:"([^"]*)"|([^,\s]*))', header[7:])}
        with self.lock:
            known = fields.get("nonce") in self._nonces
        if not known or fields.get("username") != self.user or fields.get("realm") != REALM:
            return False
        ha1 = _md5("%s:%s:%s" % (self.user, REALM, self.password))
        ha2 = _md5("%s:%s" % (method, fields.get("uri", "")))
        if fields.get("qop"):
            expected = _md5(":".join([ha1, fields["nonce"], fields.get("nc", ""), fields.get("cnonce", ""),
                                      fields["qop"], ha2]))
        else:
            expected = _md5("%s:%s:%s" % (ha1, fields["nonce"], ha2))
        return fields.get("response") == expected


class _Handler(BaseHTTPRequestHandler):
    fake = None
    protocol_version = "HTTP/1.1"

    def log_message(self, *_args):
        pass

    def _send(self, code, body=b"", content_type="application/xml", extra=None):
        self.send_response(code)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        for key, value in (extra or {}).items():
            self.send_header(key, value)
        self.end_headers()
        self.wfile.write(body)

    def _status(self, path, code=1, text="OK", sub_status=None):
        body = ('<?xml version="1.0" encoding="UTF-8"?>\n<ResponseStatus version="2.0" xmlns="%s">'
                "<requestURL>%s</requestURL><statusCode>%d</statusCode><statusString>%s</statusString>"
                "%s</ResponseStatus>" % (NS, path, code, text,
                                         "<subStatusCode>%s</subStatusCode>" % sub_status if sub_status else ""))
        self._send(200 if code == 1 else 403 if sub_status == "notSupport" else 400, body.encode("utf-8"))

    def _not_supported(self, path):
        self._status(path, 4, "Invalid Operation", "notSupport")

    def _authenticate(self):
        fake = self.fake
        if fake.fault == "timeout":
            fake.hold()              # the client times out; then this connection is closed unanswered
            self.close_connection = True
            return False
        if fake.fault == "garbage":
            self._send(200, GARBAGE, "text/html")
            return False
        if fake.fault != "401" and fake.authorized(self.command, self.headers.get("Authorization")):
            return True
        with fake.lock:
            fake.challenges += 1
        challenge = 'Digest realm="%s", qop="auth", nonce="%s", algorithm="MD5"' % (REALM, fake.new_nonce())
        self._send(401, b"<html>401 Unauthorized</html>", "text/html", {"WWW-Authenticate": challenge})
        return False

    def _body(self):
        length = int(self.headers.get("Content-Length") or 0)
        return self.rfile.read(length).decode("utf-8", "replace") if length else ""

    def do_GET(self):
        body = self._body()
        if not self._authenticate():
            return
        fake = self.fake
        path = urlsplit(self.path).path
        with fake.lock:
            fake.requests.append(("GET", self.path, body))
            doc = fake.documents.get(path)
        thermal = "/ISAPI/Thermal/channels/%d/thermometry/" % fake.thermal_channel
        if path == thermal + "jpegPicWithAppendData":
            if not fake.radiometric:
                return self._not_supported(path)
            body, content_type = picture_with_append_data(fake.thermal_frame, fake.thermal_picture, fake.picture,
                                                          fake.thermal_channel, fake.temperature_data_length)
            self._send(200, body, content_type)
        elif path == "/ISAPI/Streaming/channels/%d01/picture" % fake.thermal_channel:
            self._send(200, fake.thermal_picture, "image/jpeg")
        elif path == "/ISAPI/Streaming/channels/%d01/picture" % fake.channel:
            if fake.picture_endpoint:
                self._send(200, fake.picture, "image/jpeg")
            else:
                self._status(path, 4, "Invalid Operation")
        elif path == "/onvif-http/snapshot":
            self._send(200, fake.picture, "image/jpeg")
        elif doc is not None:
            self._send(200, doc.encode("utf-8"))
        else:
            self._send(404, b"<html>404</html>", "text/html")

    def do_PUT(self):
        body = self._body()
        if not self._authenticate():
            return
        fake = self.fake
        path = urlsplit(self.path).path
        prefix = "/ISAPI/PTZCtrl/channels/%d/" % fake.channel
        with fake.lock:
            fake.requests.append(("PUT", self.path, body))
            if path == "/ISAPI/PTZCtrl/channels/%d/onepushfoucs/start" % fake.thermal_channel:
                if not fake.thermal_focus:
                    return self._not_supported(path)
                fake.focus_pushes += 1
            elif path == prefix + "absolute":
                match = re.search(r"<absoluteZoom>(\d+)</absoluteZoom>", body)
                if not match:
                    return self._status(path, 4, "Invalid XML Content")
                status = prefix + "status"
                fake.documents[status] = re.sub(r"<absoluteZoom>\d+</absoluteZoom>",
                                                "<absoluteZoom>%s</absoluteZoom>" % match.group(1),
                                                fake.documents[status])
            elif path in (prefix + "continuous", "/ISAPI/System/Video/inputs/channels/%d/focus" % fake.channel):
                match = re.search(r"<(zoom|focus)>(-?\d+)</(?:zoom|focus)>", body)
                if not match:
                    return self._status(path, 4, "Invalid XML Content")
                fake.continuous[match.group(1)] = int(match.group(2))
            elif path in fake.documents and "/status" not in path and "deviceInfo" not in path:
                fake.documents[path] = body
            else:
                return self._send(404, b"<html>404</html>", "text/html")
        self._status(path)
