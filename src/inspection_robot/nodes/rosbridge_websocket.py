"""rosbridge_websocket: the backend link, a rosbridge-v2-compatible websocket server.

Speaks the rosbridge v2 protocol (JSON text frames, CBOR binary frames) to unmodified
roslibjs/roslibpy clients and answers /rosapi/* calls in-process (see docs/interface.md,
"Backend link").

Publishes:   client_count (std_msgs/Int32, latched): connected websocket clients
             diagnostics (diagnostic_msgs/DiagnosticArray, diagnostic_updater, 1 Hz): hardware_id
             backend_link, status "rosbridge_websocket: clients": send queues, drop counters
             the topics a backend publishes (interface.BACKEND_TOPIC_TYPES: server_status, every *_cmd, ...),
             advertised at start; plus every other topic a client advertises (any type). These go out
             through the bridge's own TCPROS publisher, node name ``<this node>/tcpros`` in rosnode
             and rostopic info (bridge/ros_tcpros.py)
Subscribes:  every topic a client subscribes to (one ROS subscriber per topic, shared); the answers to
             a backend's commands (interface.BACKEND_ACK_TYPES: every *_ack) from the start, kept
Services:    every service a client advertises; calls any ROS service for clients
Parameters:  config/rosbridge_websocket.yaml: every setting, its default and meaning (read through
             ros.node.NodeSettings); ~address (command line only, bridge.launch's address argument: "127.0.0.1" when
             none; "" = all), ~actual_port (int, written: the bound port). The security settings
             (fixed_settings.FIXED_KEYS) come from that file, the site file and the command line only, never the
             parameter server
Environment: INSPECTION_BRIDGE_TRACE (a topic: time its echoes' stages, bridge/trace.py),
             INSPECTION_BRIDGE_TRACE_FILE (str, /tmp/bridge_trace.json: written at shutdown)
"""
import asyncio
import concurrent.futures
import gc
import os
import ssl
import sys
import threading
import time

import diagnostic_updater
import rospy
import tornado.ioloop
from diagnostic_msgs.msg import DiagnosticStatus
from std_msgs.msg import Int32

from inspection_robot.bridge.access import Authenticator, FailureLimiter, check_fixed, listen_check, read_token_file
from inspection_robot.bridge import compat_tornado, trace
from inspection_robot.bridge.codec import Codec
from inspection_robot.bridge.console import CONSOLE_PATH, console_routes, missing_files
from inspection_robot.bridge.protocol import Session, SessionConfig
from inspection_robot.ros import compat_rospy
from inspection_robot.bridge.ros_backend import RosBackend, RosGraph, start_tcpros_publisher
from inspection_robot.bridge.ros_message_types import GenpyTypes
from inspection_robot.bridge.rosapi import RosApi
from inspection_robot.bridge.server import BridgeServer, LoopPoster, make_ssl_context
from inspection_robot.bridge.surface import CONSOLE_LINK_PATH, Surface, role_of_path
from inspection_robot.fixed_settings import FIXED_KEYS, fixed_settings, overridden
from inspection_robot.interface import BACKEND_ACK_TYPES, BACKEND_TOPIC_TYPES
from inspection_robot.ros.language import site_language
from inspection_robot.ros.node import NodeSettings, init_node, renice

NODE = "rosbridge_websocket"
LOOPBACK = "127.0.0.1"   # ~address when the command line gives none (bridge.launch passes its address argument)
INSECURE_WARNING_PERIOD = 60.0  # s between warnings while insecure:=true leaves the link open

# A client repeating one bad request must not flood the log: identical lines once a second.
LOGGERS = {"info": rospy.loginfo,
           "warning": lambda text: rospy.logwarn_throttle_identical(1.0, text),
           "error": lambda text: rospy.logerr_throttle_identical(1.0, text)}


def log(level, text):
    LOGGERS.get(level, rospy.loginfo)("bridge: " + text)


def read_fixed(settings):
    """The security settings (fixed_settings.FIXED_KEYS): from the defaults file, the site file and the
    command line only; a parameter-server value that differs is ignored and named in a warning."""
    fixed = fixed_settings(NODE, sys.argv[1:], settings.defaults.files[0], os.environ)
    current = {key: rospy.get_param("~" + key) for key in FIXED_KEYS[NODE] if rospy.has_param("~" + key)}
    changed = overridden(fixed, current)
    if changed:
        rospy.logwarn("bridge: ignoring the parameter server's %s: security settings come only from %s, the site "
                      "file (%s) and the command line (docs/deployment.md, Backend link security)",
                      ", ".join("~" + k for k in changed), "config/%s.yaml" % NODE, fixed["site_file"] or "not given")
    return fixed


def read_params(settings):
    fixed = read_fixed(settings)
    params = {
        "port": int(settings.get("~port")),
        "address": str(fixed.get("address", LOOPBACK)),   # the launch's address argument
        "certfile": str(fixed["certfile"]),
        "keyfile": str(fixed["keyfile"]),
        "auth_token": str(fixed["auth_token"]),
        "auth_token_file": str(fixed["auth_token_file"]),
        "client_ca": str(fixed["client_ca"]),
        "insecure": fixed["insecure"],
        "surface": fixed["surface"],
        "auth_window": float(settings.get("~auth_window")),
        "auth_max_failures": int(settings.get("~auth_max_failures")),
        "auth_timeout": float(settings.get("~auth_timeout")),
        "handshake_timeout": float(settings.get("~handshake_timeout")),
        "allowed_origins": fixed["allowed_origins"],
        "max_message_size": int(settings.get("~max_message_size")),
        "preauth_bytes": int(settings.get("~preauth_bytes")),
        "max_clients_per_address": int(settings.get("~max_clients_per_address")),
        "ping_interval": float(settings.get("~ping_interval")),
        "ping_timeout": float(settings.get("~ping_timeout")),
        "client_budget": int(settings.get("~client_budget")),
        "budget_grace": float(settings.get("~budget_grace")),
        "fragment_timeout": float(settings.get("~fragment_timeout")),
        "service_timeout": float(settings.get("~service_timeout")),
        "subscriber_queue_size": int(settings.get("~subscriber_queue_size")),
        "service_threads": int(settings.get("~service_threads")),
        "console": bool(settings.get("~console")),
        "console_dir": str(settings.get("~console_dir")),
        "console_vendor_dir": str(settings.get("~console_vendor_dir")),
        "nice": int(settings.get("~nice")),
    }
    check_fixed(params)
    if not -20 <= params["nice"] <= 19:
        raise ValueError("~nice must be -20..19, not %d" % params["nice"])
    if not 0 <= params["port"] <= 65535:
        raise ValueError("~port must be 0..65535, not %d" % params["port"])
    for name in ("max_message_size", "client_budget", "service_threads", "auth_max_failures", "preauth_bytes",
                 "max_clients_per_address"):
        if params[name] < 1:
            raise ValueError("~%s must be positive" % name)
    for name in ("auth_timeout", "handshake_timeout"):
        if not params[name] > 0:
            raise ValueError("~%s must be positive" % name)
    for name in ("subscriber_queue_size", "budget_grace"):
        if params[name] < 0:
            raise ValueError("~%s must not be negative" % name)
    if params["auth_token_file"]:
        params["auth_token"] = read_token_file(params["auth_token_file"])
    params["insecure_warning"] = listen_check(params["address"], bool(params["auth_token"]),
                                              bool(params["client_ca"]), params["insecure"])
    return params


class EventLoopThread(object):
    """Runs the tornado IOLoop (the websocket server) in its own thread; rospy keeps the main thread."""

    def __init__(self):
        self.loop = None
        self._ready = threading.Event()
        self._thread = threading.Thread(target=self._run, name="bridge_ioloop")
        self._thread.daemon = True

    def start(self):
        self._thread.start()
        self._ready.wait()
        return self.loop

    def _run(self):
        asyncio.set_event_loop(asyncio.new_event_loop())
        self.loop = tornado.ioloop.IOLoop.current()
        self._ready.set()
        self.loop.start()

    def run_sync(self, fn, timeout=10.0):
        """Run ``fn`` on the loop thread and return its result."""
        result = concurrent.futures.Future()

        def call():
            try:
                result.set_result(fn())
            except Exception as exc:  # boundary: re-raised in the calling thread
                result.set_exception(exc)
        self.loop.add_callback(call)
        return result.result(timeout)

    def stop(self, cleanup, timeout=3.0):
        def stop():
            cleanup()
            self.loop.stop()
        self.loop.add_callback(stop)
        self._thread.join(timeout)


class LinkDiagnostics(diagnostic_updater.DiagnosticTask):
    """Send queues and drop counters of the bridge's clients; WARN while any client drops or is over budget.

    ``stats()`` returns BridgeServer.stats() (read on the event-loop thread by the caller).
    """

    def __init__(self, stats):
        diagnostic_updater.DiagnosticTask.__init__(self, "rosbridge_websocket: clients")
        self._stats = stats
        self._last_dropped = 0

    def run(self, stat):
        try:
            stats = self._stats()
        except Exception as exc:  # boundary: a diagnostics tick must not die (loop busy or stopping)
            stat.summary(DiagnosticStatus.WARN, "no figures from the event loop: %r" % exc)
            return stat
        dropped = sum(stats["dropped_by_topic"].values())
        over = [c["client"] for c in stats["clients"] if c["over_budget"]]
        if over or dropped > self._last_dropped:
            stat.summary(DiagnosticStatus.WARN, "%d messages dropped in all, clients over budget: %s"
                         % (dropped, ", ".join(str(c) for c in over) or "none"))
        else:
            stat.summary(DiagnosticStatus.OK, "%d clients, nothing dropped since the last report"
                         % len(stats["clients"]))
        self._last_dropped = dropped
        stat.add("clients", str(len(stats["clients"])))
        stat.add("budget_bytes", str(stats["budget"]))
        stat.add("dropped", str(dropped))
        stat.add("closed_over_budget", str(stats["closed_over_budget"]))
        stat.add("origins_refused", str(stats["origins_refused"]))
        stat.add("address_refused", str(stats["address_refused"]))
        stat.add("accept_refused", str(stats["accept_refused"]))
        for topic, count in sorted(stats["dropped_by_topic"].items()):
            stat.add("dropped %s" % topic, str(count))
        for client in stats["clients"]:
            stat.add("client %s" % client["client"],
                     "%d bytes held, %d messages, %d dropped, %d replaced (queue_length)%s"
                     % (client["held_bytes"], client["messages"], client["dropped"], client["queue_length_dropped"],
                        ", over budget" if client["over_budget"] else ""))
        return stat


def update_diagnostics(updater):
    try:
        updater.update()
    except Exception as exc:  # boundary: a timer tick must not die (e.g. the master went away)
        rospy.logwarn_throttle(10.0, "bridge: diagnostics update failed: %r" % exc)


def main():
    tracer = trace.from_environment(os.environ)
    tracer.start()   # GC pauses from start-up on, as when the hook was installed at import
    init_node("rosbridge_websocket")
    settings = NodeSettings("rosbridge_websocket")
    params = read_params(settings)
    if params["nice"]:
        # an echo's time in the bridge on a busy CPU is mostly its threads waiting to be scheduled
        # (docs/development.md, "Niceness and autogroup scheduling"): a lower niceness shortens those waits
        failed = renice(params["nice"])
        if failed:
            rospy.logwarn("bridge: ~nice %d not applied (%s): the link's latency tail stays the machine's",
                          params["nice"], failed)
    io_thread = EventLoopThread()
    loop = io_thread.start()
    executor = concurrent.futures.ThreadPoolExecutor(max_workers=params["service_threads"],
                                                     thread_name_prefix="bridge_call")
    types = GenpyTypes()
    codec = Codec(types)
    tcpros = start_tcpros_publisher(log)
    backend = RosBackend(types, codec, LoopPoster(loop, log).post, executor, params["service_timeout"],
                         params["subscriber_queue_size"], log, tcpros, trace=tracer)
    backend.advertise_for_the_robot(BACKEND_TOPIC_TYPES)
    backend.subscribe_for_the_robot(BACKEND_ACK_TYPES)
    rosapi = RosApi(RosGraph(backend), types)
    authenticator = None
    if params["auth_token"]:
        # The client's auth time stamp is its wall clock: compare with ours, not with ROS time, which
        # is the bag's time during a replay (use_sim_time) and would refuse every client.
        authenticator = Authenticator(params["auth_token"], time.time, params["auth_window"],
                                      FailureLimiter(time.monotonic, params["auth_max_failures"]))
    config = SessionConfig(authenticator, params["fragment_timeout"], params["max_message_size"],
                           params["service_timeout"], params["auth_timeout"])
    count_pub = rospy.Publisher("client_count", Int32, queue_size=1, latch=True)

    surfaces = {role: Surface(role, params["surface"], rospy.resolve_name) for role in ("backend", "console")}

    def make_session(client_id, send, call_later, close, peer):
        return Session(client_id, backend, send, time.monotonic, call_later, close, config, rosapi, log, peer,
                       surfaces[role_of_path(peer.path)])

    http_routes = []
    if params["console"]:
        missing = missing_files(params["console_dir"], params["console_vendor_dir"])
        if missing:
            rospy.logerr("bridge: console not served, missing %s (run scripts/setup)", ", ".join(missing))
        else:
            http_routes = console_routes(params["console_dir"], params["console_vendor_dir"], bool(authenticator),
                                         site_language())
    ssl_context = make_ssl_context(params["certfile"], params["keyfile"]) if params["certfile"] else None
    if params["client_ca"]:
        ssl_context.verify_mode = ssl.CERT_REQUIRED
        ssl_context.load_verify_locations(params["client_ca"])
    server = BridgeServer(make_session, params["address"], params["port"], ssl_context,
                          params["ping_interval"], params["ping_timeout"], params["max_message_size"],
                          params["client_budget"], params["budget_grace"], lambda n: count_pub.publish(Int32(n)),
                          log, extra_routes=http_routes, allowed_origins=params["allowed_origins"],
                          handshake_timeout=params["handshake_timeout"], preauth_bytes=params["preauth_bytes"],
                          max_clients_per_address=params["max_clients_per_address"],
                          websocket_paths=(CONSOLE_LINK_PATH,), trace=tracer)
    port = io_thread.run_sync(server.start)
    updater = diagnostic_updater.Updater()
    updater.setHardwareID("backend_link")
    updater.add(LinkDiagnostics(lambda: io_thread.run_sync(server.stats, timeout=0.5)))
    rospy.Timer(rospy.Duration(1.0), lambda event: update_diagnostics(updater))
    rospy.set_param("~actual_port", port)
    rospy.loginfo("bridge: rosbridge v2 websocket on %s://%s:%d%s", "wss" if ssl_context else "ws",
                  params["address"] or "0.0.0.0", port, " (auth required)" if authenticator else "")
    if http_routes:
        rospy.loginfo("bridge: operator console on %s://%s:%d%s", "https" if ssl_context else "http",
                      params["address"] or "0.0.0.0", port, CONSOLE_PATH)
    for compat in (compat_rospy, compat_tornado):   # a library upgrade that slows the bridge says so
        (rospy.logwarn if compat.MISSING else rospy.loginfo)("bridge: " + compat.describe())
    if params["insecure_warning"]:
        rospy.logwarn("bridge: " + params["insecure_warning"])
        rospy.Timer(rospy.Duration(INSECURE_WARNING_PERIOD),
                    lambda _event: rospy.logwarn("bridge: " + params["insecure_warning"]))
    # Everything made at start-up (rospy, genpy's classes, tornado, the message types) lives as long
    # as the node: out of the collector's sight, a full collection walks only what came later (in
    # the running sim a full collection took 59 ms, and an echo caught in it waited that long).
    gc.collect()
    gc.freeze()
    if tracer.on:
        rospy.loginfo("bridge: tracing the echo path of %s into %s", tracer.topic, tracer.file)
        rospy.on_shutdown(tracer.dump)
    rospy.spin()
    io_thread.stop(server.stop)
    executor.shutdown(wait=False)
    tcpros.close()
