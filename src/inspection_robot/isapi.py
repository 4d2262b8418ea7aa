"""Hikvision ISAPI transport shared by the visible camera (camera.isapi) and the thermal imager
(thermal.isapi): HTTP with digest authentication, a timeout on every request, ISAPI XML documents,
ResponseStatus answers and multipart bodies. Pure module (no rospy).

Every request opens a new connection, so a camera that restarted or came back on the network is
simply used again on the next request: reconnection needs no state. The client raises the error
classes of the device it serves (``IsapiErrors``), with messages that name the setting to check
(``hints``): the node's answer then tells the operator what to fix.
"""
import http.client
import json
import urllib.error
import urllib.request
import xml.etree.ElementTree as ElementTree
from collections import namedtuple

NS = "http://www.hikvision.com/ver20/XMLSchema"
JPEG_MAGIC = b"\xff\xd8"
#: ResponseStatus statusCode 1 = OK; 4 = Invalid Operation, with subStatusCode notSupport for a
#: function the device does not have (ISAPI core protocol, "ResponseStatus")
STATUS_OK = "1"
NOT_SUPPORTED = "notSupport"

IsapiErrors = namedtuple("IsapiErrors", "error unreachable refused unsupported")
"""The device's exception classes: any failure, no HTTP exchange, credentials refused (401),
function the device does not have (HTTP 404 or ResponseStatus subStatusCode notSupport)."""

IsapiHints = namedtuple("IsapiHints", "device address credentials")
"""Words for messages: the device ("thermal imager"), the settings of its address and of its
credentials ("~isapi/host, ~isapi/port"), so that every error names what to check."""

Response = namedtuple("Response", "payload content_type")


def local(tag):
    return tag.rsplit("}", 1)[-1]


def find_all(root, name):
    """Every element called ``name`` (namespace ignored), in document order."""
    return [el for el in root.iter() if local(el.tag) == name]


def response_status(payload):
    """(statusCode, subStatusCode, statusString) of an ISAPI ResponseStatus, XML or JSON (the answer
    to a ``?format=json`` request), as strings; None if ``payload`` is not one."""
    stripped = payload.lstrip()
    if stripped.startswith(b"{"):
        try:
            doc = json.loads(stripped.decode("utf-8"))
        except ValueError:
            return None
        if not isinstance(doc, dict) or "statusCode" not in doc:
            return None
        return tuple(str(doc.get(key, "")) for key in ("statusCode", "subStatusCode", "statusString"))
    try:
        root = ElementTree.fromstring(payload)
    except ElementTree.ParseError:
        return None
    if local(root.tag) != "ResponseStatus":
        return None

    def text(name):
        found = find_all(root, name)
        return (found[0].text or "").strip() if found else ""
    return text("statusCode"), text("subStatusCode"), text("statusString")


class IsapiClient(object):
    """Digest-authenticated HTTP to one ISAPI device at ``url`` (scheme://host:port)."""

    def __init__(self, url, user, password, timeout, errors, hints, extra_urls=()):
        self.base = url.rstrip("/")
        self.timeout = float(timeout)
        self.errors = errors
        self.hints = hints
        passwords = urllib.request.HTTPPasswordMgrWithDefaultRealm()
        for prefix in (self.base,) + tuple(extra_urls):
            passwords.add_password(None, prefix, user, password)
        self._digest = urllib.request.HTTPDigestAuthHandler(passwords)
        self._opener = urllib.request.build_opener(self._digest)

    def _where(self, url):
        return url[len(self.base):] if url.startswith(self.base) else url

    def request(self, method, path_or_url, body=None, timeout=None, content_type="application/xml; charset=UTF-8"):
        """The device's answer (Response); raises the device's errors (see IsapiErrors)."""
        url = path_or_url if path_or_url.startswith("http") else self.base + path_or_url
        data = body.encode("utf-8") if isinstance(body, str) else body
        request = urllib.request.Request(url, data=data, method=method)
        if data is not None:
            request.add_header("Content-Type", content_type)
        # urllib counts digest retries per handler and resets the count only after a success: once
        # the device refused the credentials, every later challenge would fail at once ("digest auth
        # failed") even after the device accepts them again. Each request gets its own count.
        self._digest.reset_retry_count()
        hints = self.hints
        try:
            with self._opener.open(request, timeout=self.timeout if timeout is None else timeout) as response:
                return Response(response.read(), response.headers.get("Content-Type", ""))
        except urllib.error.HTTPError as err:
            if err.code == 401:
                raise self.errors.refused("%s %s refused the credentials (HTTP 401, digest): check %s"
                                          % (hints.device, self.base, hints.credentials))
            try:
                status = response_status(err.read())
            except OSError:
                status = None
            where = self._where(url)
            if err.code == 404 or (status is not None and status[1] == NOT_SUPPORTED):
                raise self.errors.unsupported("%s %s does not support %s %s (HTTP %d%s)"
                                              % (hints.device, self.base, method, where, err.code,
                                                 ", %s" % status[1] if status and status[1] else ""))
            raise self.errors.error("%s %s answered HTTP %d to %s %s%s"
                                    % (hints.device, self.base, err.code, method, where,
                                       ": %s" % (status[2] or status[1]) if status else ""))
        except (urllib.error.URLError, OSError, http.client.HTTPException) as err:
            # HTTPException: a status line that is no HTTP at all, a body cut short
            reason = getattr(err, "reason", err)
            raise self.errors.unreachable("%s unreachable at %s: %s (check %s)"
                                          % (hints.device, self.base, reason, hints.address))

    def get_xml(self, path):
        """The XML document at ``path``, namespace prefixes removed (kept as a plain xmlns attribute)."""
        payload = self.request("GET", path).payload
        try:
            root = ElementTree.fromstring(payload)
        except ElementTree.ParseError as err:
            raise self.errors.error("%s %s sent malformed XML for %s: %s (is %s an ISAPI device?)"
                                    % (self.hints.device, self.base, path, err, self.hints.address))
        namespace = root.tag[1:].split("}", 1)[0] if root.tag.startswith("{") else None
        for element in root.iter():
            element.tag = local(element.tag)
        if namespace:
            root.set("xmlns", namespace)
        return root

    def check_status(self, payload, path):
        """ISAPI answers PUTs with a ResponseStatus; statusCode 1 is OK."""
        status = response_status(payload)
        if status is None or status[0] in (STATUS_OK, ""):
            return
        if status[1] == NOT_SUPPORTED:
            raise self.errors.unsupported("%s %s does not support %s (%s)"
                                          % (self.hints.device, self.base, path, status[1]))
        raise self.errors.error("%s %s refused %s: %s" % (self.hints.device, self.base, path, status[2] or status[0]))

    def put(self, path, body):
        self.check_status(self.request("PUT", path, body).payload, path)

    def put_xml(self, path, root):
        self.put(path, ElementTree.tostring(root, encoding="unicode"))

    def read(self, path, name):
        """Text of the first element ``name`` of the document at ``path``."""
        elements = find_all(self.get_xml(path), name)
        if not elements or elements[0].text is None:
            raise self.errors.error("%s %s does not report %s in %s" % (self.hints.device, self.base, name, path))
        return elements[0].text.strip()

    def update(self, path, values):
        """Read ``path``, set each element named in ``values`` (all occurrences), write it back."""
        root = self.get_xml(path)
        for name, value in values.items():
            elements = find_all(root, name)
            if not elements:
                raise self.errors.error("%s %s does not support %s in %s" % (self.hints.device, self.base, name, path))
            for element in elements:
                element.text = str(value)
        self.put_xml(path, root)


def multipart_parts(payload, content_type):
    """The parts of a multipart body as [(headers {lower-case name: value}, body bytes)].

    A part's Content-Length, when given, is taken as its exact size (binary parts such as a
    temperature matrix may contain anything, even the boundary); otherwise the part ends at the
    next delimiter. Raises ValueError with the reason for anything else.
    """
    boundary = None
    for field in content_type.split(";")[1:]:
        key, _, value = field.strip().partition("=")
        if key.lower() == "boundary":
            boundary = value.strip().strip('"')
    if not content_type.lower().startswith("multipart/") or not boundary:
        raise ValueError("not a multipart answer (Content-Type %r)" % content_type[:80])
    delimiter = b"--" + boundary.encode("latin-1")
    position = payload.find(delimiter)
    if position < 0:
        raise ValueError("no multipart boundary %r in the body" % boundary)
    parts = []
    while True:
        position += len(delimiter)
        if payload[position:position + 2] == b"--":
            return parts
        header_end = payload.find(b"\r\n\r\n", position)
        if header_end < 0:
            raise ValueError("multipart part %d has no end of headers" % (len(parts) + 1))
        headers = {}
        for line in payload[position:header_end].decode("latin-1").split("\r\n"):
            name, sep, value = line.partition(":")
            if sep:
                headers[name.strip().lower()] = value.strip()
        start = header_end + 4
        if "content-length" in headers:
            try:
                length = int(headers["content-length"])
            except ValueError:
                raise ValueError("multipart part %d has Content-Length %r"
                                 % (len(parts) + 1, headers["content-length"]))
            end = start + length
            if length < 0 or end > len(payload):
                raise ValueError("multipart part %d is cut short (%d of %d bytes)"
                                 % (len(parts) + 1, max(0, len(payload) - start), length))
            position = payload.find(delimiter, end)
        else:
            position = payload.find(b"\r\n" + delimiter, start)
            end = position
            position = -1 if position < 0 else position + 2
        parts.append((headers, payload[start:end]))
        if position < 0:
            return parts   # no closing delimiter: devices often end the body after the last part
