"""The XML-RPC slave API of the bridge's TCPROS publisher (wiki.ros.org/ROS/Slave_API): requestTopic,
the bus information rosnode and rostopic show, shutdown.

Kept apart from ros_tcpros.py, which publishes: these are the answers to the master's and the
tools' questions about it, in plain XML-RPC (no ROS import). :class:`SlaveApi` is a mixin of
TcprosPublisher; its methods read the publisher's ``_topics`` (under ``_topics_lock``), ``_host``,
``port``, ``_master`` and ``_on_shutdown_request``.
"""
import os
import socket
import socketserver
import threading
import xmlrpc.server


class SlaveServer(socketserver.ThreadingMixIn, xmlrpc.server.SimpleXMLRPCServer):
    """The slave API's XML-RPC server: a thread per request, none holding up the process's exit."""

    daemon_threads = True


class SlaveServer6(SlaveServer):
    address_family = socket.AF_INET6


def _xmlrpc_int(value):
    return min(value, (1 << 31) - 1)  # XML-RPC's int is 32-bit: a long-lived counter saturates


class SlaveApi(object):
    """The slave API's functions (registered by TcprosPublisher under their XML-RPC names)."""

    # ------------------------------------------------------------------ slave API (wiki.ros.org/ROS/Slave_API)
    def _snapshot(self):
        with self._topics_lock:
            return sorted(self._topics.items())

    def _request_topic(self, caller_id, topic, protocols):
        with self._topics_lock:
            published = topic in self._topics
        if not published:
            return [-1, "Not a publisher of [%s]" % topic, []]
        if not any(protocol and protocol[0] == "TCPROS" for protocol in protocols):
            return [0, "no supported protocol implementations", []]
        return [1, "ready on %s:%d" % (self._host, self.port), ["TCPROS", self._host, self.port]]

    def _bus_info(self, caller_id):
        info = []
        for topic, publication in self._snapshot():
            with publication.lock:
                for connection in publication.connections:
                    info.append([connection.number, connection.callerid, "o", "TCPROS", topic, True,
                                 "TCPROS connection on port %d to [%s]" % (self.port, connection.callerid)])
        return [1, "bus info", info]

    def _bus_stats(self, caller_id):
        stats = []
        for topic, publication in self._snapshot():
            with publication.lock:
                stats.append([topic, _xmlrpc_int(publication.bytes_sent),
                              [[c.number, _xmlrpc_int(c.bytes_sent), _xmlrpc_int(c.messages_sent), True]
                               for c in publication.connections]])
        return [1, "", [stats, [], [0, 0, 0]]]

    def _pid(self, caller_id):
        return [1, "", os.getpid()]

    def _master_uri(self, caller_id):
        return [1, "", self._master.getUri()]

    def _publications(self, caller_id):
        return [1, "publications", [[topic, p.data_class._type] for topic, p in self._snapshot()]]

    def _subscriptions(self, caller_id):
        return [1, "subscriptions", []]

    def _ignored(self, caller_id, *args):
        return [1, "", 0]

    def _shutdown(self, caller_id, message=""):
        reason = "shutdown requested by %s: %s" % (caller_id, message)
        threading.Thread(target=self._on_shutdown_request, args=(reason,), daemon=True).start()
        return [1, "shutdown", 0]
