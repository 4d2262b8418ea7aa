"""What a websocket client may reach: the backend surface, by allowlist, one table per role.

rosbridge_server's convention is three lists of fnmatch globs (``topics_glob``, ``services_glob``,
``params_glob``; empty = everything); a name that matches none is refused ("No match found for
topic, cancelling publish to: ..."). This module keeps that convention and is stricter where a
robot needs it: what a client may *publish* is a separate, shorter list than what it may
*subscribe* to (a backend reads ``obstacle_status`` but never writes it), no client advertises a
service, and parameters are read-only over the link (``/rosapi/set_param`` and ``delete_param``
are in no role) with the security settings never readable (:data:`SECRET_PARAMS`).

Roles (docs/interface.md, "Backend surface", prints :func:`markdown_table`):

- ``backend``: every connection but the console's; the spec's command topics, the action goals,
  the robot's ``*_control`` services and rosapi's read-only services;
- ``console``: the operator console served by the bridge (it connects on :data:`CONSOLE_LINK_PATH`):
  only what its panels use, a subset of the backend's;
- ``surface: sim`` adds the simulator's services and topics (fault injection, world values) to
  every role; ``surface: open`` applies no table (protocol tests of a bare bridge only; check_site
  refuses it on a robot).

Names are matched after resolving them in the bridge's namespace, so a robot under ``/robot_3``
allows ``/robot_3/mode_cmd`` whether the client wrote ``mode_cmd`` or ``/robot_3/mode_cmd``.
Pure module: the node passes rospy's resolver in.
"""
import fnmatch
from collections import OrderedDict

from inspection_robot.interface import (ACTION_NAMES, BACKEND_ACK_TYPES, BACKEND_TOPIC_TYPES, CAMERA_STAGING_SERVICE,
                                        INFRARED_STAGING_SERVICE, INTERFACE_TOPICS)

SURFACES = ("robot", "sim", "open")
NO_PARAMETER = "/no_parameter_is_readable"  # upstream reads an empty glob list as "everything": match nothing
CONSOLE_LINK_PATH = "/console/link"
KINDS = ("publish", "subscribe", "call", "params")
# What each kind covers, for the error text and the docs.
KIND_OPS = {"publish": "advertise, publish", "subscribe": "subscribe", "call": "call_service",
            "params": "/rosapi/get_param, has_param, search_param, get_param_names"}

ROBOT_SERVICES = ("arm_control", "calibration_control", "camera_control", "charge_control", "file_control",
                  "imu_control", "infrared_control", "task_control", "terrace_control")
# The robot's own services no role offers (test_bridge_surface places every service of the running robot).
ROBOT_ONLY_SERVICES = (CAMERA_STAGING_SERVICE, INFRARED_STAGING_SERVICE)
ROSAPI_READ_ONLY = tuple("/rosapi/" + name for name in (
    "topics", "topics_for_type", "topic_type", "services", "services_for_type", "service_type", "nodes",
    "node_details", "publishers", "subscribers", "service_providers", "service_node", "message_details",
    "service_request_details", "service_response_details", "get_param", "has_param", "search_param",
    "get_param_names", "get_time", "action_servers"))
ROSAPI_PARAM_SERVICES = ("/rosapi/get_param", "/rosapi/has_param", "/rosapi/search_param")
# Never readable by any role: secrets, and where they live.
SECRET_PARAMS = ("*/auth_token", "*/auth_token_file", "*/keyfile", "*/certfile", "*/client_ca")

BACKEND = OrderedDict([
    ("publish", tuple(sorted(BACKEND_TOPIC_TYPES))
     + tuple("%s/%s" % (a, t) for a in ACTION_NAMES for t in ("goal", "cancel"))),
    ("subscribe", tuple(sorted(set(INTERFACE_TOPICS) | set(BACKEND_ACK_TYPES)))
     + ("camera/*", "thermal/*")),
    ("call", ROBOT_SERVICES + ROSAPI_READ_ONLY),
    ("params", ("*",)),
])
# The console's panels (web/console/*.js; test_bridge_surface checks every name they use is here).
CONSOLE = OrderedDict([
    ("publish", ("server_status", "mode_cmd", "move_cmd", "control_cmd", "terrace_cmd", "camera_cmd",
                 "virtual_obstacle_cmd", "preset_scale_cmd", "preset_rotate", "move_action/goal",
                 "move_action/cancel")),
    ("subscribe", ("robot_status", "task_status", "map", "plan", "virtual_obstacle_map", "terrace_state",
                   "preset_scale_ack", "camera/image_raw/compressed", "thermal/image_raw/compressed",
                   "thermal/hottest", "move_action/status", "move_action/feedback", "move_action/result")
     + tuple("%s_ack" % n for n in ("control", "terrace", "camera", "infrared", "virtual_obstacle", "voice",
                                    "mode"))),
    ("call", ("task_control", "calibration_control", "file_control")),
    ("params", ()),
])
ROLES = OrderedDict([("backend", BACKEND), ("console", CONSOLE)])
# surface: sim adds these to every role (the simulated yard's test and demo clients use them).
SIM_EXTRA = OrderedDict([("publish", ()), ("subscribe", ("sim/*",)),
                         ("call", ("sim/*", "sim_obstacle_control", "*/sim_control")), ("params", ())])


class SurfaceError(ValueError):
    """A name outside the client's role; the text names the role and the rule."""


def role_of_path(path):
    """The role of a websocket connection opened on ``path`` (the console's link, or any other)."""
    return "console" if (path or "").rstrip("/") == CONSOLE_LINK_PATH else "backend"


class Surface(object):
    """One role's allowlist, resolved in the bridge's namespace; ``check(kind, name)`` raises SurfaceError.

    ``surface``: one of :data:`SURFACES`; ``resolve(name)``: the bridge's name resolution (rospy's).
    """

    def __init__(self, role, surface="robot", resolve=None):
        if surface not in SURFACES:
            raise ValueError("surface must be one of %s, not %r" % (", ".join(SURFACES), surface))
        if role not in ROLES:
            raise ValueError("role must be one of %s, not %r" % (", ".join(ROLES), role))
        self.role = role
        self.surface = surface
        self._resolve = resolve or (lambda name: name if name.startswith("/") else "/" + name)
        table = ROLES[role]
        self._globs = {}
        for kind in KINDS:
            globs = list(table[kind]) + (list(SIM_EXTRA[kind]) if surface == "sim" else [])
            self._globs[kind] = [self._resolve(g) if g != "*" and not g.startswith("*") else g for g in globs]
        self._secrets = list(SECRET_PARAMS)

    @property
    def open(self):
        return self.surface == "open"

    def allows(self, kind, name):
        if self.open:
            return True
        resolved = self._resolve(name) if name else name
        if kind == "params" and any(fnmatch.fnmatchcase(resolved, g) for g in self._secrets):
            return False
        return any(fnmatch.fnmatchcase(resolved, g) for g in self._globs[kind])

    def check(self, kind, name):
        """None when this role may ``kind`` (:data:`KINDS`) ``name``, else SurfaceError naming the rule."""
        if self.allows(kind, name):
            return
        if kind == "params" and any(fnmatch.fnmatchcase(self._resolve(name), g) for g in self._secrets):
            raise SurfaceError("parameter %s is a security setting: never readable over the link (rule "
                               "secret_params)" % name)
        raise SurfaceError("%s %s refused: not in the %s surface (rule %s.%s; docs/interface.md, Backend "
                           "surface)" % (_VERB[kind], name, self.role, self.role, kind))


_VERB = {"publish": "publishing to", "subscribe": "subscribing to", "call": "calling", "params": "reading"}


def rosbridge_globs(role="backend"):
    """The role as rosbridge_server's ``topics_glob`` / ``services_glob`` / ``params_glob`` strings
    (its ``[a, b]`` form; names absolute as its fnmatch compares them). rosbridge has one topics list
    for both directions and applies params_glob to writes too, so: topics = publish + subscribe (the
    owners' checks of robot_control keep safety inputs safe there), services without any param
    service (upstream's rosapi cannot make parameters read-only), params none. Upstream compares the
    name as the client wrote it, so under a robot namespace clients must give absolute names there."""
    table = ROLES[role]

    def absolute(globs):
        return [g if g.startswith(("/", "*")) else "/" + g for g in globs]
    topics = absolute(list(table["publish"]) + [g for g in table["subscribe"] if g not in table["publish"]])
    services = absolute([s for s in table["call"] if s not in ROSAPI_PARAM_SERVICES
                         and s != "/rosapi/get_param_names"])
    return OrderedDict([("topics_glob", "[%s]" % ", ".join(topics)),
                        ("services_glob", "[%s]" % ", ".join(services)),
                        ("params_glob", "[%s]" % NO_PARAMETER)])


def markdown_table():
    """The roles as docs/interface.md prints them (checked by test_bridge_surface)."""
    lines = ["| role | kind (ops) | names (fnmatch globs, relative to the robot's namespace) |",
             "|---|---|---|"]
    for role, table in ROLES.items():
        for kind in KINDS:
            names = ", ".join("`%s`" % g for g in table[kind]) or "nothing"
            lines.append("| %s | %s (%s) | %s |" % (role, kind, KIND_OPS[kind], names))
    for kind in KINDS:
        if SIM_EXTRA[kind]:
            names = ", ".join("`%s`" % g for g in SIM_EXTRA[kind])
            lines.append("| + `surface: sim` | %s (%s) | %s |" % (kind, KIND_OPS[kind], names))
    return "\n".join(lines)
