"""The operator console's static files, served on the bridge's own HTTP port.

The page (web/console/) talks to the robot only through the websocket on the same port, like any
backend; these routes hand out files and nothing else (no robot data, no secrets), so they need no
authentication. Front-end libraries (roslib.js, uPlot) come from the npm registry at setup time
(web/package.json) and are served from ``vendor_dir`` (web/node_modules): the page needs no internet.
"""
import json
import os
import re

import tornado.web

from inspection_robot.i18n import DEFAULT_LANGUAGE

CONSOLE_PATH = "/console/"
# /console/vendor/<name>: the library files the page loads, each from its package in vendor_dir (nothing
# else of node_modules is served)
VENDOR_FILES = {"roslib.min.js": "roslib/build/roslib.min.js", "uPlot.esm.js": "uplot/dist/uPlot.esm.js",
                "uPlot.min.css": "uplot/dist/uPlot.min.css"}
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
    wanted = [os.path.join(console_dir, "index.html")]
    wanted += [os.path.join(vendor_dir, path) for path in VENDOR_FILES.values()]
    return [path for path in wanted if not os.path.isfile(path)]


def console_routes(console_dir, vendor_dir, auth_required, language=DEFAULT_LANGUAGE):
    """Tornado rules: /console -> /console/, config.json (whether to ask for the token; the site's
    ``language``, the page's default), /console/vendor/<name> of VENDOR_FILES from vendor_dir, the rest
    from console_dir (strings.json, the words in every language, among them)."""
    vendor = [(r"/console/vendor/(%s)" % re.escape(name), _StaticFiles,
               {"path": os.path.dirname(os.path.join(vendor_dir, path))})
              for name, path in sorted(VENDOR_FILES.items())]   # each name is its file's own
    return [
        (r"/console", tornado.web.RedirectHandler, {"url": CONSOLE_PATH}),
        (r"/console/config\.json", _ConsoleConfig,
         {"config": {"auth_required": bool(auth_required), "language": language}}),
    ] + vendor + [
        (r"/console/(.*)", _StaticFiles, {"path": console_dir, "default_filename": "index.html"}),
    ]
