"""Shared helpers for the rostest scripts: waiting for conditions with a deadline, never sleeping blind."""
import threading
import time

import rospy


def wait_for(condition, timeout, message="condition", period=0.01):
    """Return as soon as ``condition()`` is truthy; fail the test after ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and not rospy.is_shutdown():
        value = condition()
        if value:
            return value
        time.sleep(period)
    raise AssertionError("timed out after %.1f s waiting for %s" % (timeout, message))


class Latest(object):
    """Subscribes to a topic and keeps every message (and the latest) for assertions."""

    def __init__(self, topic, msg_type, queue_size=100):
        self.messages = []
        self._lock = threading.Lock()
        self._sub = rospy.Subscriber(topic, msg_type, self._on_msg, queue_size=queue_size)

    def _on_msg(self, msg):
        with self._lock:
            self.messages.append((time.monotonic(), msg))

    @property
    def last(self):
        with self._lock:
            return self.messages[-1][1] if self.messages else None

    def clear(self):
        with self._lock:
            del self.messages[:]

    def wait(self, predicate=lambda msg: True, timeout=5.0, what="message"):
        """Wait for a message (received from now on or already the latest) that satisfies predicate."""
        return wait_for(lambda: self.last is not None and predicate(self.last) and self.last,
                        timeout, what)

    def wait_connected(self, timeout=5.0):
        wait_for(lambda: self._sub.get_num_connections() > 0, timeout, "publisher of " + self._sub.name)


def wait_subscribed(publisher, timeout=5.0):
    wait_for(lambda: publisher.get_num_connections() > 0, timeout, "subscriber of " + publisher.name)
