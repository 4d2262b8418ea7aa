"""The backend surface (bridge/surface.py): what each role may reach, enforced by the protocol Session,
the same table in docs/interface.md, in bridge.launch's upstream globs and in the console's code."""
import glob
import json
import os
import re

import pytest

from bridge_fakes import FakeBackend, Harness
from inspection_robot.bridge import surface as surface_module
from inspection_robot.bridge.rosapi import RosApi
from inspection_robot.bridge.surface import (CONSOLE_LINK_PATH, ROLES, Surface, SurfaceError, markdown_table,
                                             role_of_path, rosbridge_globs)

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def in_ns(ns):
    return lambda name: name if name.startswith("/") else ns + name


def test_a_backend_commands_the_robot_but_never_writes_a_safety_input():
    backend = Surface("backend")
    for topic in ("mode_cmd", "/move_cmd", "server_status", "task_action/goal", "move_action/cancel"):
        backend.check("publish", topic)
    for topic in ("obstacle_status", "robot_status", "control_status", "joy", "rosout", "tf", "cmd_vel",
                  "sim/true_pose", "task_action/result"):
        with pytest.raises(SurfaceError, match=r"not in the backend surface \(rule backend.publish"):
            backend.check("publish", topic)
    for topic in ("obstacle_status", "robot_status", "camera/image_raw/compressed", "mode_ack", "tf"):
        backend.check("subscribe", topic)
    with pytest.raises(SurfaceError, match="rule backend.subscribe"):
        backend.check("subscribe", "rosout")


def test_parameters_are_read_only_and_the_secrets_unreadable():
    backend = Surface("backend")
    backend.check("call", "/rosapi/get_param")
    for service in ("/rosapi/set_param", "/rosapi/delete_param", "/rosout/set_logger_level",
                    "/rosbridge_websocket/set_logger_level", "sim/inject_fault"):
        with pytest.raises(SurfaceError, match="rule backend.call"):
            backend.check("call", service)
    backend.check("params", "/task_manager/server_timeout_s")
    for name in ("/rosbridge_websocket/auth_token", "/secured/rosbridge_websocket/auth_token_file",
                 "/rosbridge_websocket/keyfile"):
        with pytest.raises(SurfaceError, match="secret_params"):
            backend.check("params", name)


def test_the_simulator_is_reachable_in_simulation_only():
    with pytest.raises(SurfaceError):
        Surface("backend", "robot").check("call", "sim/inject_fault")
    Surface("backend", "sim").check("call", "sim/inject_fault")
    Surface("backend", "sim").check("call", "/sim_pelco_head/sim_control")
    with pytest.raises(SurfaceError):
        Surface("backend", "sim").check("publish", "obstacle_status")   # sim adds no safety input
    assert Surface("backend", "open").allows("publish", "obstacle_status")
    with pytest.raises(ValueError):
        Surface("backend", "wide")


def test_names_resolve_in_the_robots_namespace():
    robot = Surface("backend", "robot", in_ns("/robot_3/"))
    robot.check("publish", "mode_cmd")
    robot.check("publish", "/robot_3/mode_cmd")
    with pytest.raises(SurfaceError):
        robot.check("publish", "/robot_4/mode_cmd")   # another robot's topics are not this bridge's


def test_the_console_has_its_own_role_inside_the_backends():
    assert role_of_path(CONSOLE_LINK_PATH) == "console"
    assert role_of_path("/") == "backend" and role_of_path("/console/linkx") == "backend"
    console, backend = Surface("console"), Surface("backend")
    for kind in ("publish", "subscribe", "call"):
        for name in ROLES["console"][kind]:
            assert backend.allows(kind, name), (kind, name)
    with pytest.raises(SurfaceError, match="rule console.call"):
        console.check("call", "/rosapi/get_param")
    with pytest.raises(SurfaceError, match="rule console.publish"):
        console.check("publish", "task_cmd")


def console_names():
    """(kind, name) of every topic and service the console's code names."""
    patterns = {"publish": r"(?:command|publish)\('([\w/]+)'", "subscribe": r"subscribe\('([\w/]+)'",
                "call": r"control\('([\w/]+)'"}
    found = set()
    for path in glob.glob(os.path.join(ROOT, "web", "console", "*.js")):
        with open(path) as f:
            text = f.read()
        for kind, pattern in patterns.items():
            found.update((kind, n) for n in re.findall(pattern, text))
        acks = re.search(r"const ACKS = \[([^\]]*)\]", text)
        if acks:
            found.update(("subscribe", n) for n in re.findall(r"'(\w+)'", acks.group(1)))
        for server in re.findall(r"actionClient\([^,]+, '([\w/]+)'", text):
            found.update([("publish", server + "/goal"), ("publish", server + "/cancel"),
                          ("subscribe", server + "/status"), ("subscribe", server + "/result"),
                          ("subscribe", server + "/feedback")])
    return found


def test_every_name_the_console_uses_is_in_its_role():
    names = console_names()
    assert ("call", "task_control") in names and ("publish", "move_cmd") in names   # the scan sees the code
    console = Surface("console")
    missing = sorted((kind, name) for kind, name in names if not console.allows(kind, name))
    assert not missing, "the console uses names its role refuses: %s" % missing


def test_docs_print_the_table():
    with open(os.path.join(ROOT, "docs", "interface.md")) as f:
        assert markdown_table() in f.read(), "docs/interface.md's Backend surface table is not the code's"


def test_bridge_launch_gives_upstream_the_same_table():
    with open(os.path.join(ROOT, "launch", "include", "bridge.launch")) as f:
        text = f.read()
    for name, value in rosbridge_globs().items():
        assert '<arg name="%s" value="%s"/>' % (name, value) in text, name
    assert "/rosapi/set_param" not in rosbridge_globs()["services_glob"]
    assert "/rosapi/get_param" not in rosbridge_globs()["services_glob"]


def test_every_service_of_the_running_robot_is_placed():
    """A new service is either for backends (ROBOT_SERVICES) or the simulator's: never unknowingly open."""
    with open(os.path.join(ROOT, "docs", "runtime.dot")) as f:
        services = re.findall(r'"service:([\w/]+)"', f.read())
    assert services
    sim = Surface("backend", "sim")
    robot = Surface("backend", "robot")
    for service in services:
        if service.lstrip("/") in surface_module.ROBOT_ONLY_SERVICES:
            assert not sim.allows("call", service) and not robot.allows("call", service), service
            continue
        assert sim.allows("call", service), service
        assert robot.allows("call", service) == (service.lstrip("/") in surface_module.ROBOT_SERVICES), service
    assert set(surface_module.ROBOT_ONLY_SERVICES) <= {s.lstrip("/") for s in services}


class Graph(object):
    params = {"/rosbridge_websocket/auth_token": "secret", "/task_manager/server_timeout_s": 60}

    def get_param(self, name, default=None):
        return self.params.get(name, default)

    def has_param(self, name):
        return name in self.params

    def param_names(self):
        return list(self.params)

    def set_param(self, name, value):
        self.params[name] = value

    def resolve(self, name):
        return name


def harness(role="backend", surface="robot"):
    backend = FakeBackend()
    backend.topic_types.update({"/obstacle_status": "inspection_robot/ObstacleStatus",
                                "/mode_cmd": "inspection_robot/GeneralCmd"})
    return Harness(backend, rosapi=RosApi(Graph(), backend.types), surface=Surface(role, surface))


def test_the_session_refuses_with_the_rule_and_allows_beside_it():
    h = harness()
    h.send({"op": "publish", "id": "spoof", "topic": "/obstacle_status", "msg": {"obstacle": False}})
    h.send({"op": "advertise", "id": "a", "topic": "/obstacle_status", "type": "inspection_robot/ObstacleStatus"})
    h.send({"op": "publish", "id": "ok", "topic": "/mode_cmd", "msg": {"cmd": "acquire", "data": "server"}})
    h.send({"op": "advertise_service", "id": "s", "service": "/mode_cmd_srv", "type": "std_srvs/Empty"})
    replies = h.messages()
    assert [m["id"] for m in replies] == ["spoof", "a", "s"]
    assert all(m["level"] == "error" for m in replies)
    assert "rule backend.publish" in replies[0]["msg"] and "rule backend.advertise_service" in replies[2]["msg"]
    assert [topic for topic, _msg in h.backend.published] == ["/mode_cmd"]   # the allowed one went through
    assert not h.backend.services


def call(h, service, args):
    h.send({"op": "call_service", "id": "c", "service": service, "args": args})
    return [m for m in h.messages() if m["op"] == "service_response"][-1]


def test_rosapi_reads_parameters_but_never_writes_or_shows_a_secret():
    h = harness()
    assert json.loads(call(h, "/rosapi/get_param", {"name": "/task_manager/server_timeout_s"})["values"]["value"]) \
        == 60
    refused = call(h, "/rosapi/set_param", {"name": "/rosbridge_websocket/insecure", "value": "true"})
    assert refused["result"] is False and "rule backend.call" in refused["values"]
    assert not call(h, "/rosapi/delete_param", {"name": "/task_manager/server_timeout_s"})["result"]
    secret = call(h, "/rosapi/get_param", {"name": "/rosbridge_websocket/auth_token"})
    assert secret["result"] is False and "secret_params" in secret["values"]
    names = call(h, "/rosapi/get_param_names", {})["values"]["names"]
    assert names == ["/task_manager/server_timeout_s"]
    assert Graph.params["/task_manager/server_timeout_s"] == 60 and "/rosbridge_websocket/insecure" not in Graph.params


def test_an_open_bridge_applies_no_table():
    h = harness(surface="open")
    h.send({"op": "publish", "id": "p", "topic": "/obstacle_status", "msg": {"obstacle": False}})
    assert not h.messages() and h.backend.published


def test_a_command_with_nan_infinity_or_null_is_refused_where_the_backend_hears_it():
    h = harness()
    h.backend.topic_types["/move_cmd"] = "inspection_robot/MoveCmd"
    for mid, msg in (("nan", '{"velocity_x": NaN, "velocity_yaw": 0}'),
                     ("inf", '{"velocity_x": 1, "velocity_yaw": -Infinity}'), ("null", '{"velocity_x": null}')):
        h.send('{"op": "publish", "id": "%s", "topic": "/move_cmd", "msg": %s}' % (mid, msg))
    replies = h.messages()
    assert [m["id"] for m in replies] == ["nan", "inf", "null"]
    assert replies[0]["msg"] == ("publish: /move_cmd refused: field velocity_x is NaN; commands take finite numbers "
                                 "(nothing published)")
    assert "field velocity_yaw is -Infinity" in replies[1]["msg"] and "field velocity_x is null" in replies[2]["msg"]
    assert not h.backend.published
    h.send({"op": "publish", "id": "ok", "topic": "/move_cmd", "msg": {"velocity_x": 300.0}})   # positive control
    assert not h.messages() and [t for t, _m in h.backend.published] == ["/move_cmd"]
