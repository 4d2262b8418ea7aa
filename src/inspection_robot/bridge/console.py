"""The operator console's static files, served on the bridge's own HTTP port.

The page (web/console/) talks to the robot only through the websocket on the same port, like any
backend; these routes hand out files and nothing else (no robot data, no secrets), so they need no
authentication. Front-end libraries (roslib.js) come from the npm registry at setup time and are
served from ``vendor_dir``: the page needs no internet.
"""
import json
import os

import tornado.web

CONSOLE_PATH = "/console/"
VENDOR_FILES = ("roslib.min.js",)
# The page's scripts are ES modules: a browser runs one only with a JavaScript MIME type (and nosniff
# forbids guessing), so it is named here rather than left to the host's mime.types.
JAVASCRIPT = "text/javascript"


class _StaticFiles(tornado.web.StaticFileHandler):
    def get_content_type(self):
        if self.absolute_path.endswith((".js", ".mjs")):
            return JAVASCRIPT
        return super().get_content_type()

    def set_extra_headers(self, path):
        # Revalidate on every load: after an update the operator gets the new page, not a stale mix.
        self.set_header("Cache-Control", "no-cache")
        self.set_header("X-Content-Type-Options", "nosniff")


class _ConsoleConfig(tornado.web.RequestHandler):
    """What the page must know before it connects: whether to ask for the access token."""

    def initialize(self, config):
        self._body = json.dumps(config, sort_keys=True)

    def get(self):
        self.set_header("Content-Type", "application/json")
        self.set_header("Cache-Control", "no-store")
        self.write(self._body)


def missing_files(console_dir, vendor_dir):
    """Paths the console needs that are not there (empty when it can be served)."""
    wanted = [os.path.join(console_dir, "index.html")] + [os.path.join(vendor_dir, name) for name in VENDOR_FILES]
    return [path for path in wanted if not os.path.isfile(path)]


def console_routes(console_dir, vendor_dir, auth_required):
    """Tornado rules: /console -> /console/, config.json, /console/vendor/<lib> from vendor_dir, the rest
    from console_dir."""
    vendor = "|".join(name.replace(".", r"\.") for name in VENDOR_FILES)
    return [
        (r"/console", tornado.web.RedirectHandler, {"url": CONSOLE_PATH}),
        (r"/console/config\.json", _ConsoleConfig, {"config": {"auth_required": bool(auth_required)}}),
        (r"/console/vendor/(%s)" % vendor, _StaticFiles, {"path": vendor_dir}),
        (r"/console/(.*)", _StaticFiles, {"path": console_dir, "default_filename": "index.html"}),
    ]
