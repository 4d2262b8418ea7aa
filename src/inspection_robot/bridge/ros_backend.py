"""The ROS side of the bridge: shared publishers/subscribers, service calls and servers, graph.

:class:`RosBackend` implements what protocol.Session needs. One rospy.Subscriber per topic
serves every client; each ROS message is encoded once per compression its clients use, in
rospy's thread, and handed to the event loop (``post``) for fan-out. Messages clients publish
reach ROS at once, in a burst once per event-loop pass in one batch, through the bridge's own
TCPROS publisher (ros_tcpros.py: written from the event loop itself, never blocking; public
APIs only).
Service calls and rosapi requests run on a thread pool; their results come back through ``post``.
A service call reuses an idle persistent connection unless its node closed it or the service moved
(another URI at the master, asked at most every URI_CHECK_S); one that fails is made once more on a
fresh connection when bridge/service_calls.py says it may (the request cannot have reached the node,
or the command only reads).
Services a client advertises are rospy.Services whose handler forwards the request to that client
and waits (bounded) for its service_response.
With ros_message_types.py and ros_tcpros.py, the bridge's ROS side.
"""
import concurrent.futures
import threading
import time

import rosgraph
import rospy
import rosservice

from inspection_robot.bridge import service_calls
from inspection_robot.bridge.ops import BridgeError
from inspection_robot.bridge.session_topics import Outgoing
from inspection_robot.bridge.trace import NoTrace
from inspection_robot.ros.compat_rospy import idle_service_connection_closed, replay_latched, service_proxy_uri
from inspection_robot.bridge.ros_tcpros import TcprosPublisher


MAX_BATCH = 256  # messages converted for one topic before the client's socket waits for a flush
MAX_IDLE_PROXIES = 4  # idle persistent connections kept per (service, type)
# s the master's word on where a service is may be old before an idle connection to it is reused: a
# lookupService costs ~1 ms (bench_service_restart), so at most one a second per service, not one a call
URI_CHECK_S = 1.0
_ROBOT = "robot"  # the owner of the topics the bridge advertises itself (advertise_for_the_robot): never leaves


def type_conflict(topic, wanted, established):
    return BridgeError("Tried to register topic %s with type %s but it is already established with type %s"
                       % (topic, wanted, established))


class _Topic(object):
    __slots__ = ("handle", "type_name", "sessions", "high_water", "pending", "in_pass", "bursting")

    def __init__(self, handle, type_name, high_water=None):
        self.handle = handle    # a tcpros_publication.Publication, or a rospy.Subscriber
        self.type_name = type_name
        self.sessions = set()
        self.high_water = high_water
        self.pending = []  # messages converted, not yet handed to rospy (flushed once per loop pass)
        self.in_pass = 0  # messages published in this event-loop pass (the ones after the first wait for its end)
        self.bursting = False  # the last pass had more than one: this pass's first message waits too


def known_topic_types(master):
    """The master's (topic, type) pairs without the ones of type ``*``: a topic that only a
    type-agnostic subscriber wants (bag_recorder subscribes to every interface topic by name before
    anyone publishes it) has no type yet, and a client may advertise it with its own."""
    return [(name, type_name) for name, type_name in master.getTopicTypes() if type_name != rosgraph.names.ANYTYPE]


def start_tcpros_publisher(log):
    """The bridge's TCPROS publisher, as ``<node>/tcpros`` (its own caller_id: rosmaster shuts down a
    caller_id's old URI when it registers again with another), closed (its topics unregistered) on
    rospy shutdown. Its slave API's shutdown (rosnode kill) stops the bridge: it is a part of it."""
    caller_id = rospy.get_name() + "/tcpros"
    publisher = TcprosPublisher(caller_id, rosgraph.Master(caller_id), log=log,
                                on_shutdown_request=rospy.signal_shutdown)
    rospy.on_shutdown(publisher.close)
    return publisher


class RosBackend(object):
    """ROS operations for the sessions. ``post(fn, *args)`` runs fn on the event-loop thread.

    ``trace``: a bridge/trace.py tracer stamping its topic's echoes as they pass (None: off).
    """

    def __init__(self, types, codec, post, executor, service_timeout=10.0, subscriber_queue_size=100,
                 log=None, tcpros=None, trace=None):
        self._types = types
        self._trace = trace or NoTrace()
        self._tcpros = tcpros   # TcprosPublisher: every topic clients publish
        self._codec = codec
        self._post = post
        self._executor = executor
        self._service_timeout = float(service_timeout)
        self._sub_queue = int(subscriber_queue_size)
        self._log = log or (lambda level, text: None)
        self._publishers = {}   # topic -> _Topic(tcpros_publication.Publication)
        self._subscribers = {}  # topic -> _Topic(rospy.Subscriber)
        self._kept = set()      # topics subscribed for the robot: kept when their last client leaves
        self._services = {}     # service -> (rospy.Service, session, type)
        self._service_types = {}  # cache: service -> type of ROS services called
        self._proxies = {}      # (service, type) -> idle [(persistent ServiceProxy, the URI it connected to)]
        self._proxy_lock = threading.Lock()
        self._uris = {}         # service -> (its URI as the master last said, None: not registered; monotonic s)
        self._uri_master = rosgraph.Master(rospy.get_name())   # used under _uri_lock (xmlrpc is not thread-safe)
        self._uri_lock = threading.Lock()
        self._master = rosgraph.Master(rospy.get_name())

    # ---------------------------------------------------------------- graph queries
    def topic_type(self, topic):
        for table in (self._publishers, self._subscribers):
            if topic in table:
                return table[topic].type_name
        resolved = rospy.resolve_name(topic)
        for name, type_name in known_topic_types(self._master):
            if name == resolved:
                return type_name
        return None

    def check_type(self, topic, type_name):
        established = self.topic_type(topic)
        if established and type_name and established != type_name:
            raise type_conflict(topic, type_name, established)

    def local_service_type(self, service):
        entry = self._services.get(service) or self._services.get(rospy.resolve_name(service))
        return entry[2] if entry else None

    # ---------------------------------------------------------------- publishing
    def advertise(self, session, topic, type_name, latch, queue_size):
        entry = self._publishers.get(topic)
        if entry is None:
            self.check_type(topic, type_name)
            cls = self._types.message_class(type_name)
            publication = self._tcpros.advertise(rospy.resolve_name(topic), cls, latch, queue_size)
            entry = _Topic(publication, type_name, max(1, queue_size // 2))
            self._publishers[topic] = entry
        elif entry.type_name != type_name:
            raise type_conflict(topic, type_name, entry.type_name)
        entry.sessions.add(session)

    def advertise_for_the_robot(self, topics, queue_size=100):
        """Advertise ``topics`` ({name: type}) for as long as the bridge runs, before any client: the
        robot's subscribers connect at once, so a client's first message on them is not lost while
        they would connect to a publisher made at its request. Clients advertising them share it."""
        for topic, type_name in sorted(topics.items()):
            self.advertise(_ROBOT, rospy.resolve_name(topic), type_name, False, queue_size)

    def unadvertise(self, session, topic):
        entry = self._publishers.get(topic)
        if entry is None:
            return
        entry.sessions.discard(session)
        if not entry.sessions:
            self._flush(topic, entry)  # what the client published before unadvertising still goes out
            del self._publishers[topic]
            self._tcpros.unadvertise(entry.handle)

    def publish(self, topic, values):
        """Convert now (errors go to the client) and hand to the TCPROS publisher.

        A message alone in its event-loop pass (an echo, a teleop command) goes out at once.
        In a burst (tornado handles up to READ_SLICE frames it already holds before it returns to
        the loop) the messages of a pass go out in one write at the end of the pass: after a
        pass that had more than one message of the topic, the next pass's first one waits too; the
        first message after a quiet pass never waits. No buffered-byte count is needed.
        """
        traced = self._trace.on and topic == self._trace.topic
        if traced:
            self._trace.mark("decoded")
        entry = self._publishers[topic]
        msg = self._codec.from_json(entry.handle.data_class, values)
        if entry.in_pass or entry.bursting:
            entry.pending.append(msg)
        else:
            entry.handle.publish([msg])
        entry.in_pass += 1
        if entry.in_pass == 1:
            self._post(self._end_pass, topic, entry)
        if traced:
            self._trace.mark("published")

    def _end_pass(self, topic, entry):
        entry.bursting = entry.in_pass > 1
        entry.in_pass = 0
        self._flush(topic, entry)

    def _flush(self, topic, entry):
        messages, entry.pending = entry.pending, []
        if messages and self._publishers.get(topic) is entry:
            entry.handle.publish(messages)

    def publisher_full(self, topic):
        """True while a subscriber connection's queue of the topic is at half its queue_size or more
        (the publisher would drop its oldest messages when full)."""
        entry = self._publishers.get(topic)
        return entry is not None and (entry.handle.queue_depth() >= entry.high_water
                                      or len(entry.pending) >= MAX_BATCH)

    # ---------------------------------------------------------------- subscribing
    def subscribe(self, session, topic, type_name):
        entry = self._subscribers.get(topic)
        if entry is not None:
            if type_name and type_name != entry.type_name:
                raise type_conflict(topic, type_name, entry.type_name)
            entry.sessions.add(session)
            self._replay_latched(entry, session)
            return
        established = self.topic_type(topic)
        if type_name and established and established != type_name:
            raise type_conflict(topic, type_name, established)
        type_name = type_name or established
        if not type_name:
            raise BridgeError("Cannot infer topic type for topic %s as it is not yet advertised" % topic)
        cls = self._types.message_class(type_name)
        entry = _Topic(None, type_name)
        entry.sessions.add(session)
        self._subscribers[topic] = entry
        # queue_size None (the default, as rosbridge): rospy drops nothing; its reader thread runs
        # the callback, so a slow bridge slows the TCPROS connection instead
        entry.handle = rospy.Subscriber(topic, cls, self._on_message, callback_args=topic,
                                        queue_size=self._sub_queue or None)

    def subscribe_for_the_robot(self, topics):
        """Subscribe ``topics`` ({name: type}) for as long as the bridge runs, before any client: a
        client's subscribe then joins a subscriber already connected, so the first message after it
        (the ack of the command the client sends next) is not lost to a connection still being made."""
        for topic, type_name in sorted(topics.items()):
            topic = rospy.resolve_name(topic)
            if topic in self._subscribers:
                continue
            entry = _Topic(None, type_name)
            self._subscribers[topic] = entry
            self._kept.add(topic)
            entry.handle = rospy.Subscriber(topic, self._types.message_class(type_name), self._on_message,
                                            callback_args=topic, queue_size=self._sub_queue or None)

    def _replay_latched(self, entry, session):
        # rospy calls a newly added callback at once with the latched messages it holds.
        def replay(msg, _args):
            outgoing = Outgoing(entry_topic, msg, self._codec, self._stamp())
            outgoing.json_text()
            self._post(self._deliver_one, session, outgoing)
        entry_topic = next(t for t, e in self._subscribers.items() if e is entry)
        replay_latched(entry.handle, replay)

    @staticmethod
    def _stamp():
        now = rospy.get_rostime()
        return now.secs, now.nsecs

    def _on_message(self, msg, topic):
        traced = self._trace.on and topic == self._trace.topic
        if traced:
            self._trace.mark("callback")
        entry = self._subscribers.get(topic)
        if entry is None or not entry.sessions:
            return   # a topic the bridge keeps for the robot (subscribe_for_the_robot) with no client on it now
        # the encodings the topic's clients use, computed once each here, in rospy's thread, so the
        # event loop only writes (a 1080p image's PNG takes tens of ms; zlib runs without the GIL)
        compressions = set(session.compression(topic) for session in list(entry.sessions))
        compressions.discard(None)
        try:
            outgoing = Outgoing(topic, msg, self._codec, self._stamp())
            for compression in sorted(compressions) or ["none"]:
                outgoing.encoded(compression)
        except Exception as exc:  # boundary: a message we cannot convert is logged and skipped
            rospy.logwarn_throttle(5.0, "bridge: cannot convert a message on %s: %r" % (topic, exc))
            return
        if traced:
            self._trace.mark("posted")
        self._post(self._deliver, topic, outgoing)

    def _deliver(self, topic, outgoing):
        if self._trace.on and topic == self._trace.topic:
            self._trace.mark("delivered")
        entry = self._subscribers.get(topic)
        if entry is not None:
            for session in list(entry.sessions):
                session.deliver(outgoing)

    def _deliver_one(self, session, outgoing):
        entry = self._subscribers.get(outgoing.topic)
        if entry is not None and session in entry.sessions:
            session.deliver(outgoing)

    def unsubscribe(self, session, topic):
        entry = self._subscribers.get(topic)
        if entry is None:
            return
        entry.sessions.discard(session)
        if not entry.sessions and topic not in self._kept:
            del self._subscribers[topic]
            entry.handle.unregister()

    # ---------------------------------------------------------------- calling services
    def run_blocking(self, fn, done):
        """Run ``fn()`` on the pool; ``done(True, result)`` or ``done(False, text)`` on the loop."""
        def job():
            try:
                result = fn()
            except Exception as exc:  # boundary: the error goes back to the client
                self._post(done, False, str(exc) or type(exc).__name__)
                return
            self._post(done, True, result)
        self._executor.submit(job)

    def call_service(self, service, args, type_name, timeout, done):
        self.run_blocking(lambda: self._call(service, args, type_name), done)

    def service_type(self, service):
        local = self.local_service_type(service)
        if local:
            return local
        resolved = rospy.resolve_name(service)
        try:
            return rosservice.get_service_type(resolved)
        except rosservice.ROSServiceIOException:
            return None

    def _call(self, service, args, type_name):
        type_name = type_name or self._service_types.get(service) or self.service_type(service)
        if not type_name:
            raise BridgeError("Service %s does not exist" % service)
        srv = self._types.service_class(type_name)
        if isinstance(args, list):
            slots = srv._request_class.__slots__
            if len(args) > len(slots):
                raise BridgeError("%s takes %d arguments, got %d" % (type_name, len(slots), len(args)))
            args = dict(zip(slots, args))
        request = self._codec.from_json(srv._request_class, args)
        key = (service, type_name)
        read_only = service_calls.is_read_only(rospy.resolve_name(service), type_name, getattr(request, "cmd", None))
        proxy = self._take_idle(key)
        reused = proxy is not None
        while True:
            if proxy is None:
                proxy = rospy.ServiceProxy(service, srv, persistent=True)
            try:
                response = proxy.call(request)
                break
            # a failed write of the request raises rospy's TransportTerminated / TransportInitError
            # unwrapped: ROSInternalException, not ROSException
            except (rospy.ServiceException, rospy.ROSException, rospy.exceptions.ROSInternalException, OSError) as exc:
                proxy.close()
                reason = str(exc) or type(exc).__name__
                stage = service_calls.failure_stage(type(exc).__name__, reason, isinstance(exc, OSError))
                if reused and service_calls.may_call_again(stage, read_only):
                    rospy.logdebug("bridge: %s failed on a kept connection (%s), calling it again" % (service, reason))
                    proxy, reused = None, False
                    continue
                if stage != service_calls.NOT_SENT:
                    self._service_types.pop(service, None)   # kept while the node restarts: the reason stays clear
                raise BridgeError(service_calls.failure_text(service, stage, reason))
        self._service_types[service] = type_name
        uri = service_proxy_uri(proxy)
        if not reused and uri is not None:
            self._uris[service] = (uri, time.monotonic())   # rospy looked it up to connect
        with self._proxy_lock:
            idle = self._proxies.setdefault(key, [])
            if len(idle) < MAX_IDLE_PROXIES:
                idle.append((proxy, uri))
            else:
                proxy.close()
        return self._codec.to_json(response)

    def _take_idle(self, key):
        """An idle connection of ``key`` (service, type) still open and going where the master says the
        service is; None when there is none. The others are closed: their node closed them (it
        restarted or left) or the service moved to another node."""
        while True:
            with self._proxy_lock:
                idle = self._proxies.get(key)
                if not idle:
                    return None
                proxy, uri = idle.pop()
            if idle_service_connection_closed(proxy):
                proxy.close()
                continue
            current = self._service_uri(key[0])
            if uri is not None and current is not None and uri != current:
                proxy.close()
                continue
            return proxy

    def _service_uri(self, service):
        """The service's URI as the master says, asked at most every URI_CHECK_S; None if not registered."""
        now = time.monotonic()
        known = self._uris.get(service)
        if known is not None and now - known[1] < URI_CHECK_S:
            return known[0]
        with self._uri_lock:
            try:
                uri = self._uri_master.lookupService(rospy.resolve_name(service))
            except (rosgraph.MasterException, OSError):   # not registered (MasterError), or no master
                uri = None
        self._uris[service] = (uri, now)
        return uri

    # ---------------------------------------------------------------- serving services
    def advertise_service(self, session, service, type_name):
        entry = self._services.get(service)
        if entry is not None and entry[1] is not session:
            raise BridgeError("Service %s is already advertised by another client" % service)
        srv = self._types.service_class(type_name)
        handle = rospy.Service(service, srv, lambda request: self._serve(session, service, srv, request))
        self._services[service] = (handle, session, type_name)

    def unadvertise_service(self, session, service):
        entry = self._services.get(service)
        if entry is not None and entry[1] is session:
            del self._services[service]
            entry[0].shutdown("unadvertised by the bridge client")

    def _serve(self, session, service, srv, request):
        """rospy's service thread: forward to the client, wait for its service_response."""
        answer = concurrent.futures.Future()
        request_id = []

        def done(ok, values):
            if not answer.done():
                answer.set_result((ok, values))

        def start():
            request_id.append(session.request(service, self._codec.to_json(request), done))
        self._post(start)
        try:
            ok, values = answer.result(timeout=self._service_timeout)
        except concurrent.futures.TimeoutError:
            self._post(lambda: request_id and session.cancel_request(request_id[0]))
            raise rospy.ServiceException("the bridge client did not answer %s within %.1f s"
                                         % (service, self._service_timeout))
        if not ok:
            raise rospy.ServiceException("the bridge client failed %s: %s" % (service, values))
        try:
            return self._codec.from_json(srv._response_class, values)
        except ValueError as exc:
            raise rospy.ServiceException("bad response from the bridge client: %s" % exc)


class RosGraph(object):
    """Master, parameter server and clock queries for rosapi."""

    def __init__(self, backend):
        self._backend = backend
        self._master = rosgraph.Master(rospy.get_name())

    def resolve(self, name):
        return rospy.resolve_name(name) if name else name

    def topic_types(self):
        return known_topic_types(self._master)

    def system_state(self):
        return self._master.getSystemState()

    def service_type(self, service):
        return self._backend.service_type(service)

    def get_param(self, name, default):
        return rospy.get_param(name, default)

    def set_param(self, name, value):
        rospy.set_param(name, value)

    def has_param(self, name):
        return rospy.has_param(name)

    def delete_param(self, name):
        rospy.delete_param(name)

    def search_param(self, name):
        return rospy.search_param(name)

    def param_names(self):
        return rospy.get_param_names()

    def now(self):
        now = rospy.get_rostime()
        return now.secs, now.nsecs
