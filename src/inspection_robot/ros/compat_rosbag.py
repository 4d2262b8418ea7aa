"""The one place that touches rosbag's internals: the connections (topic, type, md5, definition) of a bag.

rosbag's public API lists topics with their type (get_type_and_topic_info) but not a connection's
md5 sum or message definition, which bag_report needs to say whether a bag can be replayed with this
build's messages. ``Bag._get_connections()`` yields them; checked once, at import (the method and
the names rosbag's _ConnectionInfo assigns), with a public fallback when they differ: read_messages'
documented ``connection_filter`` is called with every connection's (topic, datatype, md5sum,
msg_def, header) before any message is read; a filter that records them and refuses all reads none.
``MISSING`` lists what was not found; test_compat_rosbag fails loudly, naming rosbag's version.
"""
import collections

import rosbag

Connection = collections.namedtuple("Connection", "topic datatype md5sum msg_def")


def _check():
    info = getattr(getattr(rosbag, "bag", None), "_ConnectionInfo", None)
    fields = set(getattr(getattr(getattr(info, "__init__", None), "__code__", None), "co_names", ()))
    missing = ["Bag._get_connections"] if not callable(getattr(rosbag.Bag, "_get_connections", None)) else []
    return missing + ["_ConnectionInfo.%s" % name for name in Connection._fields if name not in fields]


MISSING = _check()
CONNECTIONS = not MISSING


def connections(bag):
    """Every connection of an open rosbag.Bag, as :class:`Connection` tuples, in the bag's order."""
    if CONNECTIONS:
        return [Connection(conn.topic, conn.datatype, conn.md5sum, conn.msg_def) for conn in bag._get_connections()]
    found = []

    def record(topic, datatype, md5sum, msg_def, _header):
        found.append(Connection(topic, datatype, md5sum, msg_def))
        return False
    for _message in bag.read_messages(connection_filter=record):
        pass
    return found
