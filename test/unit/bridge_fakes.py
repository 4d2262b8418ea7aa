"""Test doubles for the bridge's protocol tests: a ROS backend in memory and a recording transport."""
import json

import genpy

from inspection_robot.bridge import cbor
from inspection_robot.bridge.codec import Codec
from inspection_robot.bridge.ops import BridgeError
from inspection_robot.bridge.protocol import Session, SessionConfig
from inspection_robot.bridge.ros_message_types import GenpyTypes


class FakeBackend(object):
    """Keeps topics and services in dicts; publishes are decoded with the real codec."""

    def __init__(self):
        self.types = GenpyTypes(now=lambda: genpy.Time(100, 5))
        self.codec = Codec(self.types)
        self.topic_types = {"/known": "std_msgs/String"}
        self.published = []
        self.publishers = {}
        self.subscribers = {}
        self.services = {}
        self.calls = []
        self.pending = []
        self.full_topics = set()  # topics whose (pretend) rospy publisher queue is full

    def topic_type(self, topic):
        return self.topic_types.get(topic)

    def check_type(self, topic, type_name):
        known = self.topic_types.get(topic)
        if known and type_name and known != type_name:
            raise BridgeError("Tried to register topic %s with type %s but it is already established with type %s"
                              % (topic, type_name, known))

    def advertise(self, session, topic, type_name, latch, queue_size):
        self.check_type(topic, type_name)
        self.types.message_class(type_name)
        self.topic_types[topic] = type_name
        self.publishers.setdefault(topic, set()).add(session)

    def unadvertise(self, session, topic):
        self.publishers.get(topic, set()).discard(session)
        if not self.publishers.get(topic):
            self.publishers.pop(topic, None)

    def publish(self, topic, values):
        cls = self.types.message_class(self.topic_types[topic])
        self.published.append((topic, self.codec.from_json(cls, values)))

    def publisher_full(self, topic):
        return topic in self.full_topics

    def subscribe(self, session, topic, type_name):
        self.check_type(topic, type_name)
        type_name = type_name or self.topic_types.get(topic)
        if not type_name:
            raise BridgeError("Cannot infer topic type for topic %s as it is not yet advertised" % topic)
        self.types.message_class(type_name)
        self.topic_types[topic] = type_name
        self.subscribers.setdefault(topic, set()).add(session)

    def unsubscribe(self, session, topic):
        self.subscribers.get(topic, set()).discard(session)
        if not self.subscribers.get(topic):
            self.subscribers.pop(topic, None)

    def run_blocking(self, fn, done):
        try:
            result = fn()
        except Exception as exc:
            done(False, str(exc))
            return
        done(True, result)

    def call_service(self, service, args, type_name, timeout, done):
        self.calls.append((service, args))
        if service == "/slow":  # answered later by the test through self.pending
            self.pending.append(done)
            return
        if service == "/echo":
            done(True, {"echo": args})
        else:
            done(False, "Service %s does not exist" % service)

    def advertise_service(self, session, service, type_name):
        self.types.service_class(type_name)
        self.services[service] = session

    def unadvertise_service(self, session, service):
        self.services.pop(service, None)


class Timer(object):
    def __init__(self, due, fn):
        self.due, self.fn, self.cancelled = due, fn, False

    def cancel(self):
        self.cancelled = True


class Harness(object):
    """A Session wired to FakeBackend, a fake clock/timers and a list of sent frames."""

    def __init__(self, backend=None, config=None, rosapi=None, peer=None, surface=None):
        self.backend = backend or FakeBackend()
        self.logged = []
        self.now = 0.0
        self.timers = []
        self.sent = []
        self.closed = False
        self.session = Session(1, self.backend, self._send, lambda: self.now, self._call_later, self._close,
                               config or SessionConfig(), rosapi, lambda level, text: self.logged.append(text), peer,
                               surface)

    def _send(self, frames, key=None, limit=None, droppable=True):
        self.sent.append(frames)

    def _call_later(self, delay, fn):
        timer = Timer(self.now + delay, fn)
        self.timers.append(timer)
        return timer

    def _close(self):
        self.closed = True

    def advance(self, seconds):
        self.now += seconds
        while True:
            due = [t for t in self.timers if not t.cancelled and t.due <= self.now]
            if not due:
                return
            timer = min(due, key=lambda t: t.due)
            self.timers.remove(timer)
            timer.fn()

    def send(self, message):
        self.session.on_frame(message if isinstance(message, (str, bytes)) else json.dumps(message))

    def messages(self):
        out = []
        for frames in self.sent:
            for frame in frames:
                out.append(cbor.loads(frame) if isinstance(frame, bytes) else json.loads(frame))
        del self.sent[:]
        return out
