"""One topic of the bridge's TCPROS publisher (:class:`Publication`) and one subscriber's connection
to it (:class:`Connection`): the state rospy keeps per topic (seq, latched message, early messages),
serialization into length-framed messages, and the splitting of a partly sent write into frames.

Kept apart from ros_tcpros.py, which owns the sockets, the I/O thread, handshakes and the master:
this is the per-topic state they share, with no ROS import (messages arrive as genpy objects and
only their serialize() is called).
"""
import collections
import io
import threading
import time

from inspection_robot.bridge.tcpros_header import LENGTH

EARLY_WINDOW_S = 1.0         # a new topic's messages replayed to subscribers that connect this soon
EARLY_WAIT_MAX_S = 10.0      # ... kept open this long at most for the subscribers the master listed at advertise
EARLY_MAX_MESSAGES = 100


class Connection(object):
    """One subscriber's socket and what it has not taken yet (whole frames; the first maybe in part)."""

    __slots__ = ("sock", "callerid", "number", "frames", "offset", "bytes_sent", "messages_sent", "dropped",
                 "closed", "writing", "drop_logged")

    def __init__(self, sock, callerid, number):
        self.sock = sock
        self.callerid = callerid
        self.number = number
        self.frames = collections.deque()
        self.offset = 0         # bytes of frames[0] already sent
        self.bytes_sent = 0
        self.messages_sent = 0
        self.dropped = 0
        self.closed = False
        self.writing = False    # the I/O thread watches it for writability
        self.drop_logged = None  # monotonic time of the last drop warning (one per DROP_LOG_PERIOD_S)


class Publication(object):
    """One advertised topic: its type, latch, queue bound, connections and the state rospy keeps per topic."""

    def __init__(self, owner, topic, data_class, latch, queue_size):
        self.topic = topic
        self.data_class = data_class
        self.latch = bool(latch)
        self.queue_size = int(queue_size)  # per connection, in messages; 0 or less: unbounded
        self.lock = threading.RLock()   # _drop runs with it held (a failed send) and without
        self.connections = []
        self.closed = False
        self.refs = 1
        self._owner = owner
        self._has_header = bool(getattr(data_class, "_has_header", False))
        self.seq = 0
        self.latched = None    # the last frame, for a latched topic
        self._created = time.monotonic()
        self.early = []        # frames of the first EARLY_WINDOW_S, for subscribers that connect in it
        self.awaited = 0       # subscribers the master listed when the topic was registered
        self.joined = set()    # caller ids of the subscribers that have connected since
        self.bytes_sent = 0

    def publish(self, messages):
        """Send ``messages`` in order to every subscriber, one write per connection (see the module)."""
        self._owner.publish(self, messages)

    def queue_depth(self):
        """Messages waiting in the fullest connection queue of the topic (0 when none wait)."""
        with self.lock:
            return max([len(c.frames) for c in self.connections] or [0])

    def num_connections(self):
        with self.lock:
            return len(self.connections)

    def early_open(self):
        """Early messages are still kept: within EARLY_WINDOW_S of the advertise, or (at most
        EARLY_WAIT_MAX_S) while fewer subscribers have connected than the master listed then."""
        age = time.monotonic() - self._created
        return age < EARLY_WINDOW_S or (age < EARLY_WAIT_MAX_S and len(self.joined) < self.awaited)

    def await_subscribers(self, uris):
        """The master's answer to registerPublisher: the subscribers (slave URIs) it knows of now."""
        with self.lock:
            self.awaited = len(set(uris or ()))

    def serialize(self, messages):
        """(bytes, frame ends): each message framed with its length, header.seq set as rospy does."""
        buff = io.BytesIO()
        ends = []
        seq = self.seq
        for msg in messages:
            seq += 1
            if self._has_header:
                msg.header.seq = seq
                if msg.header.frame_id is None:
                    msg.header.frame_id = "0"
            start = buff.tell()
            buff.seek(start + 4)
            msg.serialize(buff)
            end = buff.tell()
            buff.seek(start)
            buff.write(LENGTH.pack(end - start - 4))
            buff.seek(end)
            ends.append(end)
        self.seq = seq  # only once all serialized: a message that fails leaves nothing half-published
        return buff.getvalue(), ends


def split_frames(data, ends, skip):
    """The whole frames of ``data`` (ending at ``ends``), the first ones' ``skip`` bytes already sent:
    (frames left, bytes of the first one already sent, frames fully sent)."""
    frames = []
    start = 0
    offset = 0
    done = 0
    for end in ends:
        if end <= skip:
            done += 1
        else:
            if not frames:
                offset = max(0, skip - start)
            frames.append(data[start:end])
        start = end
    return frames, offset, done
