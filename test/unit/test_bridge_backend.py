"""RosBackend.publish's batching: the first message of a loop pass goes at once, the rest in one batch.
(The TCPROS publisher it writes to: test_tcpros_publisher.py.)"""
from inspection_robot.ros import bridge_backend


class Handle(object):
    """What RosBackend uses of a tcpros_publisher.Publication."""
    data_class = object

    def __init__(self):
        self.writes = []

    def publish(self, messages):
        self.writes.append(list(messages))


class Codec(object):
    def from_json(self, cls, values):
        return values["data"]


def test_a_lone_message_goes_at_once_a_burst_once_per_loop_pass():
    posted = []
    backend = bridge_backend.RosBackend(None, Codec(), lambda fn, *args: posted.append((fn, args)), None)
    entry = bridge_backend._Topic(Handle(), "std_msgs/String")
    writes = entry.handle.writes
    backend._publishers["/t"] = entry

    def next_pass():
        for fn, args in posted:
            fn(*args)
        posted.clear()
    backend.publish("/t", {"data": "alone"})
    assert writes == [["alone"]]            # an echo or a command: sent before the pass ends
    for i in range(4):                      # the rest of a burst read in the same pass
        backend.publish("/t", {"data": str(i)})
    assert writes == [["alone"]]
    next_pass()
    assert writes == [["alone"], ["0", "1", "2", "3"]]
    for i in range(4, 7):                   # the burst goes on: the whole pass in one write
        backend.publish("/t", {"data": str(i)})
    next_pass()
    assert writes[2:] == [["4", "5", "6"]]
    backend.publish("/t", {"data": "last"})  # right after a burst: waits for the end of its pass
    assert len(writes) == 3
    next_pass()
    assert writes[3:] == [["last"]]
    backend.publish("/t", {"data": "quiet"})  # after a pass with one message: at once again
    assert writes[4:] == [["quiet"]]


class Types(object):
    def message_class(self, type_name):
        return type_name


class Master(object):
    def getTopicTypes(self):
        return []


class Tcpros(object):
    """What RosBackend uses of a TcprosPublisher."""

    def __init__(self):
        self.advertised = []
        self.unadvertised = []

    def advertise(self, topic, data_class, latch, queue_size):
        handle = Handle()
        handle.depth = 0
        handle.queue_depth = lambda: handle.depth
        self.advertised.append((topic, data_class, latch, queue_size))
        return handle

    def unadvertise(self, publication):
        self.unadvertised.append(publication)


def test_clients_share_the_tcpros_publication_and_the_last_to_leave_unadvertises_it():
    tcpros = Tcpros()
    posted = []
    backend = bridge_backend.RosBackend(Types(), Codec(), lambda fn, *args: posted.append((fn, args)), None,
                                        tcpros=tcpros)
    backend._master = Master()
    backend.advertise("a", "/t", "std_msgs/String", True, 20)
    backend.advertise("b", "/t", "std_msgs/String", False, 100)
    assert tcpros.advertised == [("/t", "std_msgs/String", True, 20)]
    handle = backend._publishers["/t"].handle
    assert not backend.publisher_full("/t")
    handle.depth = 9
    assert not backend.publisher_full("/t")
    handle.depth = 10  # half its queue_size: the client is paused before the publisher would drop
    assert backend.publisher_full("/t")
    backend.publish("/t", {"data": "x"})
    backend.publish("/t", {"data": "pending"})  # waits for the end of the loop pass
    backend.unadvertise("a", "/t")
    assert tcpros.unadvertised == []
    backend.unadvertise("b", "/t")
    assert handle.writes == [["x"], ["pending"]]  # what the client published before leaving still goes out
    assert tcpros.unadvertised == [handle]
