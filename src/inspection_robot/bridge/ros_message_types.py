"""Type support for the bridge from genpy/roslib: message and service classes by name, time.

The bridge's message classes from genpy (with ros_backend.py the bridge's ROS side)
(test_import_rules.py exempts it), so codec.py and protocol.py stay pure.
"""
import genpy
import roslib.message

from inspection_robot.bridge.codec import TypeSupport


class UnknownTypeError(ValueError):
    """A message or service type name that cannot be loaded."""


def _valid_name(type_name):
    return isinstance(type_name, str) and type_name.count("/") == 1 and all(type_name.split("/"))


class GenpyTypes(TypeSupport):
    """Resolves ``pkg/Type`` names to generated classes (cached); ``now`` returns the ROS time."""

    def __init__(self, now=None):
        self._now = now
        self._messages = {}
        self._services = {}

    def message_class(self, type_name):
        return _load(self._messages, roslib.message.get_message_class, "message", type_name)

    def service_class(self, type_name):
        return _load(self._services, roslib.message.get_service_class, "service", type_name)

    def time(self, secs, nsecs):
        return genpy.Time(secs, nsecs)

    def duration(self, secs, nsecs):
        return genpy.Duration(secs, nsecs)

    def now(self):
        if self._now is None:
            import rospy  # only where a node runs; unit tests inject ``now``
            return rospy.get_rostime()
        return self._now()


def _load(cache, loader, kind, type_name):
    """The generated class for ``type_name`` from ``cache`` or ``loader``; UnknownTypeError if none."""
    cls = cache.get(type_name)
    if cls is None:
        if _valid_name(type_name):
            try:
                cls = loader(type_name)
            except (ValueError, ImportError, AttributeError, TypeError):
                cls = None
        if cls is None:
            raise UnknownTypeError("Unable to load the %s class for type %r" % (kind, type_name))
        cache[type_name] = cls
    return cls
