"""The bridge's own TCPROS publisher: what websocket clients publish reaches ROS on public APIs only.

rospy.Publisher hands every write to a per-connection thread (a lock, a notify and a thread switch
per message) and hides its queues; making it fast meant reading rospy's private state. This
publisher serves the bridge's topics itself, as the ROS wiki specifies TCPROS
(wiki.ros.org/ROS/TCPROS, ROS/Connection Header) and the master's and slave APIs
(wiki.ros.org/ROS/Master_API, ROS/Slave_API):

- its own XML-RPC slave API and TCP listening socket, registered under its own caller_id (the
  node passes ``<node>/tcpros``: rosmaster shuts down a caller_id's old URI when it registers
  again with another), so rosnode/rostopic show the bridge's publications under that name;
- :meth:`TcprosPublisher.publish` serializes a burst once and writes it once per connection from
  the caller's thread, never blocking: what a socket does not take is queued for this object's
  I/O thread, in order, bounded by the topic's queue_size in messages (the oldest dropped, as
  rospy does, and counted); :meth:`Publication.queue_depth` lets the bridge pause a client first;
- a subscriber's handshake runs on a thread of its own with a bounded read, so a silent client
  never holds up others; a peer that closes is seen at once (the I/O thread watches every socket);
- latched topics send their last message after the handshake; messages published in a topic's
  first EARLY_WINDOW_S go to subscribers that connect within that window (clients advertise and
  publish at once, before any subscriber has connected; rosbridge_library does the same), and the
  window stays open, at most EARLY_WAIT_MAX_S, until as many subscribers have connected as the
  master listed when the topic was registered (on a loaded machine a subscriber may take longer
  than EARLY_WINDOW_S to connect: bench/bench_early_messages.py).

No rospy API here (ros/node.py only lends its handshake bound): the node passes caller_id, the
master and the addresses, so the unit tests run it on 127.0.0.1 without a roscore. Its parts that
need no ROS sit beside it: tcpros_header.py (the connection header codec), tcpros_publication.py
(a topic's and a connection's state, framing) and tcpros_slave.py (the slave API's answers).
"""
import collections
import selectors
import socket
import threading
import time
import traceback

import rosgraph
import rosgraph.network

from inspection_robot.bridge.tcpros_header import HeaderError, encode_header, read_header
from inspection_robot.bridge.tcpros_publication import EARLY_MAX_MESSAGES, Connection, Publication, split_frames
from inspection_robot.bridge.tcpros_slave import SlaveApi, SlaveServer, SlaveServer6
from inspection_robot.ros.node import HANDSHAKE_TIMEOUT_S

ANYTYPE = "*"                # md5sum (or type) a subscriber sends when it takes any type (rostopic echo, rosbag)
DROP_LOG_PERIOD_S = 5.0
SEND_BYTES = 1 << 18         # the I/O thread's largest single send of queued frames


class TcprosPublisher(SlaveApi):
    """Publishes topics over TCPROS under ``caller_id`` with its own slave API (see the module).

    ``master``: a rosgraph.Master-like object (registerPublisher, unregisterPublisher, getUri).
    ``log(level, text)``: warnings about subscribers. ``on_shutdown_request``: what the slave API's
    shutdown does (default: close()).
    """

    def __init__(self, caller_id, master, host=None, bind_address=None, log=None,
                 handshake_timeout=HANDSHAKE_TIMEOUT_S, on_shutdown_request=None):
        self.caller_id = caller_id
        self._master = master
        self._host = host or rosgraph.network.get_host_name()
        bind_address = bind_address or rosgraph.network.get_bind_address()
        self._log = log or (lambda level, text: None)
        self._handshake_timeout = float(handshake_timeout)
        self._on_shutdown_request = on_shutdown_request or (lambda reason: self.close())
        self._topics = {}           # resolved name -> Publication
        self._topics_lock = threading.Lock()
        self._numbers = iter(range(1, 1 << 62))
        self._closed = False
        family = socket.AF_INET6 if ":" in bind_address else socket.AF_INET
        self._listener = socket.socket(family, socket.SOCK_STREAM)
        self._listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self._listener.bind((bind_address, 0))
        self._listener.listen(128)
        self._listener.setblocking(False)
        self.port = self._listener.getsockname()[1]
        server_class = SlaveServer6 if family == socket.AF_INET6 else SlaveServer
        self._xmlrpc = server_class((bind_address, 0), logRequests=False, allow_none=True)
        for name, function in (("requestTopic", self._request_topic), ("getBusInfo", self._bus_info),
                               ("getBusStats", self._bus_stats), ("getPid", self._pid),
                               ("getMasterUri", self._master_uri), ("getPublications", self._publications),
                               ("getSubscriptions", self._subscriptions), ("publisherUpdate", self._ignored),
                               ("paramUpdate", self._ignored), ("shutdown", self._shutdown)):
            self._xmlrpc.register_function(function, name)
        self.uri = "http://%s:%d/" % (self._host, self._xmlrpc.server_address[1])
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._wake_w.setblocking(False)
        self._ops = collections.deque()  # (op, connection) for the I/O thread: "add", "write", "remove"
        self._selector = selectors.DefaultSelector()
        self._selector.register(self._listener, selectors.EVENT_READ, None)
        self._selector.register(self._wake_r, selectors.EVENT_READ, None)
        self._io_thread = threading.Thread(target=self._io_loop, name="tcpros_io", daemon=True)
        self._xmlrpc_thread = threading.Thread(target=self._xmlrpc.serve_forever, name="tcpros_xmlrpc",
                                               daemon=True)
        self._io_thread.start()
        self._xmlrpc_thread.start()

    # ------------------------------------------------------------------ topics
    def advertise(self, topic, data_class, latch=False, queue_size=100):
        """Publish ``topic`` (a resolved name) and register it with the master; the Publication.
        A topic advertised again (same type) shares the first one's Publication until the last unadvertise."""
        with self._topics_lock:
            if self._closed:
                raise RuntimeError("the TCPROS publisher %s is closed" % self.caller_id)
            publication = self._topics.get(topic)
            if publication is not None:
                if publication.data_class._type != data_class._type:
                    raise ValueError("%s is already published with type %s, not %s"
                                     % (topic, publication.data_class._type, data_class._type))
                publication.refs += 1
                return publication
            publication = Publication(self, topic, data_class, latch, queue_size)
            self._topics[topic] = publication
        try:
            subscribers = self._master.registerPublisher(topic, data_class._type, self.uri)
        except Exception:   # the master refused or is gone: the topic is not published
            with self._topics_lock:
                self._topics.pop(topic, None)
            raise
        publication.await_subscribers(subscribers if isinstance(subscribers, list) else ())
        return publication

    def unadvertise(self, publication):
        """Drop one advertise of the Publication; the last one closes its connections and unregisters it."""
        with self._topics_lock:
            publication.refs -= 1
            if publication.refs > 0 or self._topics.get(publication.topic) is not publication:
                return
            del self._topics[publication.topic]
        self._close_publication(publication)
        try:
            self._master.unregisterPublisher(publication.topic, self.uri)
        except Exception as exc:  # boundary: the master may be gone at shutdown; nothing else to undo
            self._log("warning", "tcpros: could not unregister %s from the master: %r" % (publication.topic, exc))

    def _close_publication(self, publication):
        with publication.lock:
            publication.closed = True
            connections, publication.connections = publication.connections, []
        for connection in connections:
            self._drop(publication, connection, None)

    def publish(self, publication, messages):
        """Serialize ``messages`` once; write them to each connection from this thread (never blocking)."""
        if not messages:
            return
        with publication.lock:
            if publication.closed:
                raise RuntimeError("publish() to the unadvertised topic %s" % publication.topic)
            early_open = publication.early_open()
            if not early_open and publication.early:
                publication.early = []  # the window is over: its messages are not needed any more
            early = early_open and len(publication.early) < EARLY_MAX_MESSAGES
            if not publication.connections and not publication.latch and not early:
                return
            data, ends = publication.serialize(messages)
            if publication.latch:
                publication.latched = data[ends[-2] if len(ends) > 1 else 0:]
            if early:
                start = 0
                for end in ends[:EARLY_MAX_MESSAGES - len(publication.early)]:
                    publication.early.append(data[start:end])
                    start = end
            for connection in list(publication.connections):
                self._write(publication, connection, data, ends)

    def _write(self, publication, connection, data, ends):
        """Send now what the socket takes, queue the rest (publication.lock held)."""
        if connection.frames:
            frames, offset, done = split_frames(data, ends, 0)
        else:
            try:
                sent = connection.sock.send(data)
            except (BlockingIOError, InterruptedError):
                sent = 0
            except OSError as exc:
                self._drop(publication, connection, exc)
                return
            connection.bytes_sent += sent
            publication.bytes_sent += sent
            frames, offset, done = split_frames(data, ends, sent)
            connection.messages_sent += done
            connection.offset = offset
            if not frames:
                return
        connection.frames.extend(frames)
        bound = publication.queue_size
        if bound > 0 and len(connection.frames) > bound:
            dropped = 0
            keep = 1 if connection.offset else 0  # a frame begun on the socket must end there
            while len(connection.frames) > bound:
                del connection.frames[keep]
                dropped += 1
            connection.dropped += dropped
            now = time.monotonic()
            if connection.drop_logged is None or now - connection.drop_logged >= DROP_LOG_PERIOD_S:
                connection.drop_logged = now
                self._log("warning", "tcpros: %s's subscriber %s does not keep up: dropped its %d oldest messages "
                          "(queue_size %d; %d in all)" % (publication.topic, connection.callerid, dropped, bound,
                                                          connection.dropped))
        if not connection.writing:
            connection.writing = True
            self._request("write", publication, connection)

    def _drop(self, publication, connection, error):
        with publication.lock:
            if connection.closed:
                return
            connection.closed = True
            if connection in publication.connections:
                publication.connections.remove(connection)
        if error is not None:
            self._log("info", "tcpros: %s: subscriber %s left (%s)" % (publication.topic, connection.callerid, error))
        self._request("remove", publication, connection)

    # ------------------------------------------------------------------ the I/O thread
    def _request(self, op, publication, connection):
        self._ops.append((op, publication, connection))
        try:
            self._wake_w.send(b"x")
        except (BlockingIOError, InterruptedError):
            pass                        # a wake-up is pending already
        except OSError:
            pass                        # closed: the I/O thread is gone

    def _io_loop(self):
        while True:
            for key, events in self._selector.select():
                try:
                    if not self._io_event(key, events):
                        return
                except Exception:  # boundary: one connection's surprise must not stop every topic's writes
                    self._log("error", "tcpros: I/O thread: %s" % traceback.format_exc())

    def _io_event(self, key, events):
        """Handle one ready socket; False when the thread is to stop."""
        if key.fileobj is self._listener:
            self._accept()
        elif key.fileobj is self._wake_r:
            try:
                while self._wake_r.recv(4096):
                    pass
            except (BlockingIOError, InterruptedError):
                pass
            return self._run_ops()
        else:
            publication, connection = key.data
            if events & selectors.EVENT_READ:
                self._readable(publication, connection)
            if events & selectors.EVENT_WRITE and not connection.closed:
                self._flush(publication, connection)
        return True

    def _run_ops(self):
        while self._ops:
            op, publication, connection = self._ops.popleft()
            if op == "stop":
                return False
            if op == "add" and not connection.closed:
                self._selector.register(connection.sock, selectors.EVENT_READ, (publication, connection))
            elif op == "write" and not connection.closed:
                self._selector.modify(connection.sock, selectors.EVENT_READ | selectors.EVENT_WRITE,
                                      (publication, connection))
            elif op == "remove":
                try:
                    self._selector.unregister(connection.sock)
                except (KeyError, ValueError):
                    pass                # never registered (closed during its handshake)
                connection.sock.close()
        return True

    def _readable(self, publication, connection):
        """A subscriber sends nothing after its header: readable means it closed (or sent junk, ignored)."""
        try:
            data = connection.sock.recv(4096)
        except (BlockingIOError, InterruptedError):
            return
        except OSError as exc:
            self._drop(publication, connection, exc)
            return
        if not data:
            self._drop(publication, connection, "closed by the subscriber")

    def _flush(self, publication, connection):
        with publication.lock:
            if connection.closed:
                return
            chunk = []
            size = 0
            for frame in connection.frames:
                chunk.append(frame)
                size += len(frame)
                if size >= SEND_BYTES:
                    break
            data = b"".join(chunk)[connection.offset:]
            try:
                sent = connection.sock.send(data)
            except (BlockingIOError, InterruptedError):
                return
            except OSError as exc:
                self._drop(publication, connection, exc)
                return
            connection.bytes_sent += sent
            publication.bytes_sent += sent
            sent += connection.offset
            while connection.frames and sent >= len(connection.frames[0]):
                sent -= len(connection.frames.popleft())
                connection.messages_sent += 1
            connection.offset = sent
            if not connection.frames:
                connection.writing = False
                self._selector.modify(connection.sock, selectors.EVENT_READ, (publication, connection))

    # ------------------------------------------------------------------ subscribers' handshakes
    def _accept(self):
        while True:
            try:
                sock, address = self._listener.accept()
            except (BlockingIOError, InterruptedError):
                return
            except OSError as exc:
                self._log("warning", "tcpros: accept failed on port %d: %r" % (self.port, exc))
                return
            threading.Thread(target=self._handshake, args=(sock, address), name="tcpros_handshake",
                             daemon=True).start()

    def _handshake(self, sock, address):
        sock.settimeout(self._handshake_timeout)
        try:
            header = read_header(sock)
        except (HeaderError, OSError) as exc:
            self._log("warning", "tcpros: refused the subscriber at %s:%s: %s" % (address[0], address[1], exc))
            sock.close()
            return
        publication, error = self._check(header)
        if error:
            self._log("warning", "tcpros: refused %s: %s" % (header.get("callerid", address[0]), error))
            try:
                sock.sendall(encode_header({"error": error}))
            except OSError:
                pass
            sock.close()
            return
        nodelay = header.get("tcp_nodelay", "0").strip() == "1"
        try:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1 if nodelay else 0)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE, 1)
            data_class = publication.data_class
            sock.sendall(encode_header({"callerid": self.caller_id, "md5sum": data_class._md5sum,
                                        "type": data_class._type, "latching": "1" if publication.latch else "0",
                                        "message_definition": data_class._full_text, "topic": publication.topic}))
            sock.setblocking(False)
        except OSError as exc:
            self._log("warning", "tcpros: lost %s during its handshake: %s" % (header["callerid"], exc))
            sock.close()
            return
        connection = Connection(sock, header["callerid"], next(self._numbers))
        with publication.lock:
            if publication.closed:
                sock.close()
                return
            self._request("add", publication, connection)
            publication.connections.append(connection)
            initial = list(publication.early) if publication.early_open() else []
            publication.joined.add(header["callerid"])
            if publication.latched is not None and (not initial or initial[-1] is not publication.latched):
                initial.append(publication.latched)
            if initial:
                connection.frames.extend(initial)
                connection.writing = True
                self._request("write", publication, connection)

    def _check(self, header):
        """(publication, None) for an acceptable subscriber header, else (None, error text as rospy words it)."""
        for required in ("topic", "md5sum", "callerid"):
            if required not in header:
                return None, "Missing required '%s' field" % required
        with self._topics_lock:
            publication = self._topics.get(header["topic"])
            topics = sorted(self._topics)
        if publication is None or publication.closed:
            return None, "[%s] is not a publisher of [%s]. Topics are %s" % (self.caller_id, header["topic"], topics)
        data_class = publication.data_class
        if header["md5sum"] not in (ANYTYPE, data_class._md5sum):
            requested = header.get("type", data_class._type)
            if requested not in (ANYTYPE, data_class._type):
                return None, "topic types do not match: [%s] vs. [%s]" % (requested, data_class._type)
            return None, ("Client [%s] wants topic [%s] to have datatype/md5sum [%s/%s], but our version has "
                          "[%s/%s] Dropping connection." % (header["callerid"], header["topic"], requested,
                                                            header["md5sum"], data_class._type, data_class._md5sum))
        return publication, None

    # ------------------------------------------------------------------ closing
    def close(self):
        """Unregister every topic, close every connection and both servers (idempotent)."""
        with self._topics_lock:
            if self._closed:
                return
            self._closed = True
            publications = list(self._topics.values())
            for publication in publications:
                publication.refs = 1
        for publication in publications:
            self.unadvertise(publication)
        self._xmlrpc.shutdown()
        self._xmlrpc.server_close()
        self._request("stop", None, None)
        self._io_thread.join(5.0)
        self._listener.close()
        self._wake_r.close()
        self._wake_w.close()
        self._selector.close()
