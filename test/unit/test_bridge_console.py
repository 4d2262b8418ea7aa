"""The console's static files on the bridge's port: routes before the websocket, nothing else served."""
import json
import os
import urllib.error
import urllib.request

import pytest

from inspection_robot_testing.bridge_client import RawClient
from inspection_robot.bridge.console import VENDOR_FILES, console_routes, missing_files
from test_bridge_server import LiveServer

ROOT = os.path.join(os.path.dirname(__file__), "..", "..")
CONSOLE_DIR = os.path.join(ROOT, "web", "console")


@pytest.fixture
def site(tmp_path):
    vendor = tmp_path / "node_modules"   # laid out as npm installs the libraries
    for path in VENDOR_FILES.values():
        (vendor / path).parent.mkdir(parents=True, exist_ok=True)
        (vendor / path).write_text("/* %s */" % path)
    (vendor / "roslib" / "build" / "roslib.min.js").write_text("var ROSLIB = {};")
    (vendor / "roslib" / "build" / "secret.txt").write_text("not for the browser")
    (vendor / "roslib" / "package.json").write_text("{}")
    server = LiveServer(extra_routes=console_routes(CONSOLE_DIR, str(vendor), auth_required=True))
    yield "http://127.0.0.1:%d" % server.port, server
    server.stop()


def get(url):
    with urllib.request.urlopen(url, timeout=30) as response:
        return response.status, response.headers, response.read()


def status_of(url):
    try:
        return get(url)[0]
    except urllib.error.HTTPError as err:
        return err.code


def test_page_vendor_library_and_config_served_and_websocket_still_answers(site):
    base, server = site
    status, headers, body = get(base + "/console/")
    assert status == 200 and b'type="module" src="main.js"' in body and headers["Cache-Control"] == "no-cache"
    assert get(base + "/console")[2] == body                      # redirected to /console/
    assert get(base + "/console/vendor/roslib.min.js")[2] == b"var ROSLIB = {};"
    assert get(base + "/console/vendor/uPlot.esm.js")[2] == b"/* uplot/dist/uPlot.esm.js */"
    assert get(base + "/console/vendor/uPlot.esm.js")[1]["Content-Type"].startswith("text/javascript")
    assert get(base + "/console/vendor/uPlot.min.css")[1]["Content-Type"].startswith("text/css")
    assert json.loads(get(base + "/console/config.json")[2]) == {"auth_required": True, "language": "zh-CN"}
    for module in ("main.js", "link.js", "decode.js"):   # a module script runs only with a JavaScript MIME type
        headers = get(base + "/console/" + module)[1]
        assert headers["Content-Type"].startswith("text/javascript") and headers["X-Content-Type-Options"] == "nosniff"
    client = RawClient("ws://127.0.0.1:%d" % server.port)     # every other path is the websocket
    client.send({"op": "call_service", "id": 1, "service": "/echo", "args": {"x": 1}})
    assert client.recv_message()["values"] == {"echo": {"x": 1}}
    client.close()


def test_nothing_outside_the_console_files(site):
    base, _ = site
    assert status_of(base + "/console/vendor/secret.txt") == 404          # only the named libraries
    assert status_of(base + "/console/vendor/roslib/package.json") == 404
    assert status_of(base + "/console/vendor/roslib/build/secret.txt") == 404
    assert status_of(base + "/console/../../package.xml") in (403, 404)
    assert status_of(base + "/console/%2e%2e/%2e%2e/package.xml") in (403, 404)
    assert status_of(base + "/console/missing.js") == 404


def test_missing_files_names_what_setup_must_install(tmp_path):
    assert missing_files(CONSOLE_DIR, str(tmp_path)) == [str(tmp_path / path) for path in VENDOR_FILES.values()]
    assert all(os.path.basename(path) == name for name, path in VENDOR_FILES.items())   # served under its own name
    assert missing_files(str(tmp_path), str(tmp_path))[0] == str(tmp_path / "index.html")
