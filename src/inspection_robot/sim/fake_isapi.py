"""A local stand-in for a Hikvision camera's ISAPI web service, for testing the real driver.

Serves the documents camera.isapi reads and writes, with HTTP digest authentication (MD5,
qop=auth) exactly as the camera does: a request without valid credentials gets ``401`` and a
``WWW-Authenticate: Digest`` challenge. PUTs answer an ISAPI ResponseStatus. The picture
endpoint can be switched off (``picture_endpoint=False``) to exercise the snapshot fallback.
Binds 127.0.0.1, port 0 by default (any free port); ``stop()`` makes the camera unreachable and
``start()`` on the same port brings it back. ``set_fault("401")`` makes it refuse every request
(even with the right credentials, as a camera whose password was changed), ``set_fault("timeout")``
makes it accept connections and never answer until ``set_fault(None)``.
"""
import hashlib
import os
import re
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from urllib.parse import urlsplit

import cv2
import numpy as np

NS = "http://www.hikvision.com/ver20/XMLSchema"
REALM = "IP Camera(C00000001)"
FAULTS = (None, "401", "timeout")


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


def test_picture(width=320, height=180):
    img = np.full((height, width, 3), 90, np.uint8)
    cv2.circle(img, (width // 2, height // 2), min(width, height) // 3, (240, 240, 240), -1)
    cv2.line(img, (width // 2, height // 2), (width // 2 + height // 4, height // 4), (10, 10, 10), 3)
    return cv2.imencode(".jpg", img)[1].tobytes()


class FakeIsapiCamera(object):
    def __init__(self, user="admin", password="secret12", port=0, channel=1, picture=None, picture_endpoint=True):
        self.user, self.password = user, password
        self.channel = channel
        self.port = int(port)
        self.picture = picture if picture is not None else test_picture()
        self.picture_endpoint = picture_endpoint
        self.documents = default_documents(channel)
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
        """None: answer normally; "401": refuse every request; "timeout": accept and never answer."""
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

    def _status(self, path, code=1, text="OK"):
        body = ('<?xml version="1.0" encoding="UTF-8"?>\n<ResponseStatus version="2.0" xmlns="%s">'
                "<requestURL>%s</requestURL><statusCode>%d</statusCode><statusString>%s</statusString>"
                "</ResponseStatus>" % (NS, path, code, text))
        self._send(200 if code == 1 else 400, body.encode("utf-8"))

    def _authenticate(self):
        fake = self.fake
        if fake.fault == "timeout":
            fake.hold()              # the client times out; then this connection is closed unanswered
            self.close_connection = True
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
        if path == "/ISAPI/Streaming/channels/%d01/picture" % fake.channel:
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
            if path == prefix + "absolute":
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
