#!/usr/bin/env python3
"""rostest: the bridge's TCPROS publisher with a real master and real rospy subscribers.

It is made as the bridge makes it (ros_backend.start_tcpros_publisher, ``<node>/tcpros``); the
subscribers are this process's own rospy Subscribers, as the bridge's echo subscriptions are.
"""
import socket
import threading
import unittest
import xmlrpc.client

import rosgraph
import rosnode
import rospy
import rostest
from std_msgs.msg import Int32, String

from inspection_robot.bridge import tcpros_publication
from inspection_robot.bridge.ros_backend import start_tcpros_publisher
from inspection_robot.bridge.tcpros_header import encode_header, read_header
from rostest_helpers import wait_for


class Collector(object):
    def __init__(self, topic):
        self.messages = []
        self.lock = threading.Lock()
        self.sub = rospy.Subscriber(topic, String, self._on_msg)

    def _on_msg(self, msg):
        with self.lock:
            self.messages.append(msg.data)

    def count(self):
        with self.lock:
            return len(self.messages)


def raw_subscriber(publisher_uri, topic, md5sum, callerid="/raw_subscriber"):
    """A subscriber that connects as rospy would (requestTopic, then a header): (socket, reply header)."""
    code, _text, (protocol, host, port) = xmlrpc.client.ServerProxy(publisher_uri).requestTopic(
        callerid, topic, [["TCPROS"]])
    assert code == 1 and protocol == "TCPROS"
    sock = socket.create_connection((host, port), timeout=10)
    sock.sendall(encode_header({"callerid": callerid, "topic": topic, "md5sum": md5sum, "type": "std_msgs/String",
                                "tcp_nodelay": "0"}))
    return sock, read_header(sock)


def publishers_of(topic):
    state = rosgraph.Master("/test_tcpros_link").getSystemState()
    return dict(state[0]).get(topic, [])


class TcprosLinkTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_tcpros_link")
        cls.log = []
        cls.publisher = start_tcpros_publisher(lambda level, text: cls.log.append((level, text)))
        cls.name = rospy.get_name() + "/tcpros"

    def advertise(self, topic, latch=False, queue_size=1000):
        publication = self.publisher.advertise(rospy.resolve_name(topic), String, latch, queue_size)
        self.addCleanup(lambda: publication.refs and self.publisher.unadvertise(publication))
        wait_for(lambda: self.name in publishers_of(publication.topic), 10.0, "the master lists the publisher")
        return publication

    def publish_paced(self, publication, texts, batch=100):
        """Publish in batches, pausing while a connection's queue is half full (as the bridge does)."""
        for start in range(0, len(texts), batch):
            wait_for(lambda: publication.queue_depth() < publication.queue_size // 2, 30.0, "the queue drained")
            publication.publish([String(text) for text in texts[start:start + batch]])

    def test_a_burst_reaches_a_rospy_subscriber_whole_and_in_order(self):
        publication = self.advertise("burst")
        received = Collector("burst")
        wait_for(lambda: publication.num_connections() == 1, 10.0, "the subscriber connected")
        texts = ["%05d" % i for i in range(10000)]
        self.publish_paced(publication, texts)
        wait_for(lambda: received.count() >= 10000, 60.0, "10,000 messages")
        self.assertEqual(received.messages, texts)
        received.sub.unregister()

    def test_a_late_subscriber_gets_the_latched_message(self):
        original = tcpros_publication.EARLY_WINDOW_S
        tcpros_publication.EARLY_WINDOW_S = 0.0   # past the early window: the latched message alone
        self.addCleanup(setattr, tcpros_publication, "EARLY_WINDOW_S", original)
        publication = self.advertise("latched", latch=True)
        publication.publish([String("first"), String("last")])
        received = Collector("latched")
        wait_for(lambda: received.count(), 10.0, "the latched message")
        self.assertEqual(received.messages, ["last"])
        received.sub.unregister()

    def test_messages_of_the_early_window_reach_a_subscriber_that_connects_in_it(self):
        original = tcpros_publication.EARLY_WINDOW_S
        tcpros_publication.EARLY_WINDOW_S = 60.0  # the window, long enough for a loaded machine
        self.addCleanup(setattr, tcpros_publication, "EARLY_WINDOW_S", original)
        publication = self.advertise("early")
        publication.publish([String("a"), String("b")])
        publication.publish([String("c")])
        received = Collector("early")
        wait_for(lambda: received.count() >= 3, 10.0, "the early messages")
        self.assertEqual(received.messages, ["a", "b", "c"])
        received.sub.unregister()

    def test_a_wrong_md5sum_is_refused_with_an_error_header(self):
        publication = self.advertise("typed")
        sock, reply = raw_subscriber(self.publisher.uri, publication.topic, Int32._md5sum)
        self.assertIn("wants topic [%s] to have datatype/md5sum" % publication.topic, reply["error"])
        self.assertEqual(sock.recv(1), b"")
        sock.close()

    def test_a_subscriber_that_never_reads_does_not_block_the_others(self):
        publication = self.advertise("stuck", queue_size=2000)
        stuck, reply = raw_subscriber(self.publisher.uri, publication.topic, String._md5sum, "/never_reads")
        self.assertEqual(reply["callerid"], self.name)
        received = Collector("stuck")
        wait_for(lambda: publication.num_connections() == 2, 10.0, "both subscribers connected")
        texts = ["%05d %s" % (i, "x" * 2000) for i in range(5000)]  # 10 MB: more than the socket buffers
        for start in range(0, len(texts), 100):
            wait_for(lambda: received.count() >= start - 500, 30.0, "the reading subscriber keeps up")
            publication.publish([String(text) for text in texts[start:start + 100]])
        wait_for(lambda: received.count() >= 5000, 60.0, "5,000 messages")
        self.assertEqual(received.messages, texts)
        self.assertEqual(publication.queue_depth(), 2000)  # the one that never reads: bounded
        stuck.close()
        wait_for(lambda: publication.num_connections() == 1, 10.0, "the closed subscriber dropped")
        received.sub.unregister()

    def test_unadvertise_unregisters_from_the_master(self):
        publication = self.advertise("leaving")
        self.publisher.unadvertise(publication)
        wait_for(lambda: self.name not in publishers_of(publication.topic), 10.0, "the master forgets it")

    def test_rosnode_sees_it_as_a_node(self):
        publication = self.advertise("listed")
        received = Collector("listed")
        wait_for(lambda: publication.num_connections() == 1, 10.0, "the subscriber connected")
        master = rosgraph.Master("/test_tcpros_link")
        self.assertIn(self.name, rosnode.get_node_names())
        api = xmlrpc.client.ServerProxy(rosnode.get_api_uri(master, self.name))
        self.assertEqual(api.getPid("/test_tcpros_link")[2], xmlrpc.client.ServerProxy(
            rosnode.get_api_uri(master, rospy.get_name())).getPid("/test_tcpros_link")[2])
        bus = api.getBusInfo("/test_tcpros_link")[2]
        self.assertIn([rospy.get_name(), "o", "TCPROS", publication.topic, True], [c[1:6] for c in bus])
        self.assertIn([publication.topic, "std_msgs/String"], api.getPublications("/test_tcpros_link")[2])
        self.assertEqual(api.getMasterUri("/test_tcpros_link")[2], rosgraph.get_master_uri())
        received.sub.unregister()


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_tcpros_link", TcprosLinkTest)
