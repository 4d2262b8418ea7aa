"""The one place that touches rospy's internals.

Two repairs and one convenience need what rospy keeps private; each is checked once, at import, by reading the
names rospy's own constructors assign (no object is built, no thread started), and falls back to
the public API when those names differ (another rospy than Noetic's frozen 1.15):

- :func:`guard_inbound_handshakes`: patches TCPROSServer._tcp_server_callback so one silent
  client cannot block rospy's accept thread (ros/node.py says why). Fallback: rospy unguarded.
- :func:`merge_publisher_updates`: a subscription that never connects, from a startup race in
  rospy's RegManager (the function says how). Fallback: rospy as it is.
- :func:`replay_latched`: a new callback on an existing Subscriber gets the latched messages
  rospy holds. Fallback: nothing replayed.
- :func:`caller_id`: the node that published a received message (rospy stores the TCPROS
  connection header on it as ``_connection_header``), for the safety inputs' owner check
  (motion/owners.py). Fallback: None, a caller nobody owns, so those inputs are refused (fail closed).
- :func:`idle_service_connection_closed` and :func:`service_proxy_uri`: whether a persistent
  ServiceProxy's idle connection was closed by its node (its ``transport``'s socket is readable: an
  idle service connection never is, but at end of file), and the service URI it connected to
  (``uri``), for the bridge's service calls across a node's restart (bridge/service_calls.py).
  Fallback: not known to be closed (the call finds out, as before), no URI (no URI check).

``MISSING`` lists what was not found; test_compat_rospy fails loudly, naming rospy's version,
when it is not empty. :func:`describe` is for a node's start-up log.

The bridge's publishing no longer reads rospy's publisher internals: it has a TCPROS publisher of
its own on public APIs (bridge/ros_tcpros.py).
"""
import select

import rospy.topics
from rospy.impl import registration, tcpros_base, tcpros_service, transport


def _assigned(function):
    """Attribute names a function's code uses (what a constructor assigns appears here)."""
    return set(getattr(getattr(function, "__code__", None), "co_names", ()))


def _missing(what, names, available):
    return ["%s.%s" % (what, name) for name in names if name not in available]


def _check():
    """Per repair, the internals it relies on that this rospy does not have."""
    manager = registration.RegManager
    return {
        "merge_updates": (_missing("RegManager", ["updates", "cond"], _assigned(manager.__init__))
                          + _missing("RegManager.run", ["updates", "cond", "pop"], _assigned(manager.run))
                          + _missing("RegManager", ["publisher_update"], set(dir(manager)))),
        "handshake_guard": _missing("TCPROSServer", ["_tcp_server_callback"], set(dir(tcpros_base.TCPROSServer))),
        "replay_latched": _missing("_SubscriberImpl", ["add_callback", "remove_callback"],
                                   set(dir(rospy.topics._SubscriberImpl))),
        "caller_id": _missing("TCPROSTransport.receive_once", ["_connection_header"],
                              _assigned(tcpros_base.TCPROSTransport.receive_once)),
        "idle_connection": (_missing("ServiceProxy", ["transport", "uri"],
                                     _assigned(tcpros_service.ServiceProxy.__init__))
                            + _missing("TCPROSTransport", ["socket"], _assigned(tcpros_base.TCPROSTransport.__init__))
                            + _missing("Transport", ["done"], _assigned(transport.Transport.__init__))),
    }


_CHECKED = _check()
MISSING = sorted(name for names in _CHECKED.values() for name in names)
UPDATE_MERGE = not _CHECKED["merge_updates"]
HANDSHAKE_GUARD = not _CHECKED["handshake_guard"]
LATCHED_REPLAY = not _CHECKED["replay_latched"]
CALLER_ID = not _CHECKED["caller_id"]
IDLE_CONNECTION = not _CHECKED["idle_connection"]


def describe():
    """One line for a node's log: which repairs run, and what is missing for the others."""
    if not MISSING:
        return "rospy internals as expected: every repair on"
    return "rospy internals differ (missing %s): public-API fallbacks in use" % ", ".join(MISSING)


def guard_inbound_handshakes(timeout_s):
    """Bound every inbound TCPROS handshake of this process to ``timeout_s`` (idempotent; before
    init_node). Returns False (rospy left unguarded) when rospy's accept callback is not there."""
    if not HANDSHAKE_GUARD:
        return False
    server_class = tcpros_base.TCPROSServer
    unguarded = getattr(server_class._tcp_server_callback, "unguarded", server_class._tcp_server_callback)

    def guarded_callback(self, sock, client_addr):
        sock.settimeout(timeout_s)
        try:
            unguarded(self, sock, client_addr)
        finally:
            try:
                sock.settimeout(None)   # the connection's transport reads and writes blocking
            except OSError:
                pass                    # already closed by the refused handshake
    guarded_callback.unguarded = unguarded
    guarded_callback.timeout_s = timeout_s
    server_class._tcp_server_callback = guarded_callback
    return True


def merge_publisher_updates():
    """Make rospy keep every publisher it is told of for a topic until it has connected to them
    (idempotent; before the node's first Subscriber). Returns False (rospy left as it is) when
    RegManager is not the expected one.

    rospy queues each publisher list it learns for a topic (registerSubscriber's reply, in the
    thread that makes the Subscriber; the master's publisherUpdate calls, in an XML-RPC thread),
    and RegManager's thread connects to the *last queued* list, dropping the earlier ones for that
    topic as stale. Nothing orders the two sources: when a publisher registers while the
    subscriber registers (every launch: an action server and its clients), the master may send
    publisherUpdate [pub] before the subscriber's thread has queued registerSubscriber's older
    reply []. If RegManager's thread is busy meanwhile (connecting the previous topic, on a
    loaded machine), it finds [pub] then [] pending, keeps [], and the subscription never
    connects: the master does not tell it again until that topic's publishers change.
    patrol_sim caught charge_control's /move_action/result so (actionlib then never sees the
    server). Here a newly queued list is merged with the ones still pending for its topic
    instead. RegManager only ever connects with these lists (a publisher that left refuses or
    denies requestTopic, and rospy gives up on it), so keeping an older URI costs at most that.
    """
    if not UPDATE_MERGE:
        return False

    def publisher_update(self, resolved_name, uris):
        with self.cond:
            merged = list(uris)
            for topic, pending in self.updates:
                if topic == resolved_name:
                    merged.extend(uri for uri in pending if uri not in merged)
            self.updates[:] = [update for update in self.updates if update[0] != resolved_name]
            self.updates.append((resolved_name, merged))
            self.cond.notify_all()
    publisher_update.merges = True
    if not getattr(registration.RegManager.publisher_update, "merges", False):
        registration.RegManager.publisher_update = publisher_update
    return True


def replay_latched(subscriber, callback):
    """Call ``callback(msg, None)`` with the latched messages a rospy.Subscriber holds (rospy calls a
    newly added callback at once with them); nothing when this rospy cannot add one."""
    if not LATCHED_REPLAY:
        return
    impl = subscriber.impl
    impl.add_callback(callback, None)
    impl.remove_callback(callback, None)


def caller_id(msg):
    """The caller id (node name, e.g. ``/robot_7/obstacle_detector``) of the node that published
    ``msg``, as its TCPROS connection header says; None when it is not known (a message built in this
    process, or a rospy that does not keep the header on received messages)."""
    if not CALLER_ID:
        return None
    header = getattr(msg, "_connection_header", None)
    if not isinstance(header, dict):
        return None
    return header.get("callerid")


def idle_service_connection_closed(proxy):
    """True when a persistent rospy.ServiceProxy holds a connection its node has closed (or reset):
    a request written to it would be lost. A service never writes on an idle connection, so anything
    to read on it is its end. False when it holds none (the next call connects), when it looks open,
    or when this rospy does not show it (the call then finds out, as rospy does)."""
    if not IDLE_CONNECTION:
        return False
    link = proxy.transport
    if link is None:
        return False
    sock = link.socket
    if link.done or sock is None:
        return True
    poller = select.poll()
    try:
        poller.register(sock, select.POLLIN | select.POLLPRI)
        return bool(poller.poll(0))
    except (OSError, ValueError):   # a socket closed under it: no file descriptor any more
        return True


def service_proxy_uri(proxy):
    """The ``rosrpc://`` URI a rospy.ServiceProxy last looked up (where its connection goes); None
    when it has not connected or this rospy does not show it."""
    return proxy.uri if IDLE_CONNECTION else None
