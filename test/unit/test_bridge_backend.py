"""RosBackend.publish's batching: the first message of a loop pass goes at once, the rest in one batch.
(The TCPROS publisher it writes to: test_tcpros_publisher.py.)"""
import pytest

from inspection_robot.bridge import ros_backend


class Handle(object):
    """What RosBackend uses of a tcpros_publication.Publication."""
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
    backend = ros_backend.RosBackend(None, Codec(), lambda fn, *args: posted.append((fn, args)), None)
    entry = ros_backend._Topic(Handle(), "std_msgs/String")
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
    backend = ros_backend.RosBackend(Types(), Codec(), lambda fn, *args: posted.append((fn, args)), None,
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


# ---------------------------------------------------------------- service calls across a node's restart
class Proxy(object):
    """A persistent rospy.ServiceProxy: answers, or raises the next of ``failures``."""
    made = []

    def __init__(self, service, srv, persistent=False):
        self.service, self.calls, self.closed, self.dead = service, [], False, False
        self.failures = list(Proxy.next_failures)
        self.uri = Proxy.uri
        Proxy.made.append(self)

    def call(self, request):
        self.calls.append(request.cmd)
        if self.failures:
            raise self.failures.pop(0)
        return "answer to %s" % request.cmd

    def close(self):
        self.closed = True


class ServiceTypes(object):
    def service_class(self, type_name):
        from inspection_robot.srv import ControlService
        return ControlService


class JsonCodec(object):
    def from_json(self, cls, values):
        return cls(**values)

    def to_json(self, response):
        return response


@pytest.fixture
def backend(monkeypatch):
    import rospy
    monkeypatch.setattr(rospy, "ServiceProxy", Proxy)
    monkeypatch.setattr(ros_backend, "idle_service_connection_closed", lambda proxy: proxy.dead)
    monkeypatch.setattr(ros_backend, "service_proxy_uri", lambda proxy: proxy.uri)
    Proxy.made, Proxy.next_failures, Proxy.uri = [], [], "rosrpc://host:1"
    made = ros_backend.RosBackend(ServiceTypes(), JsonCodec(), None, None)
    made._service_uri = lambda service: Proxy.uri   # the master's word, without a master
    return made


def call(backend, service, cmd):
    return backend._call(service, {"cmd": cmd, "data": ""}, "inspection_robot/ControlService")


def transport_error():
    import rospy
    return rospy.ServiceException("transport error completing service call: unable to receive data from sender, "
                                  "check sender's logs for details")


def test_an_idle_connection_its_node_closed_gets_no_request(backend):
    assert call(backend, "/file_control", "stat") == "answer to stat"
    Proxy.made[0].dead = True                 # file_server restarted: its end of the connection closed
    assert call(backend, "/calibration_control", "get") == "answer to get"
    assert call(backend, "/file_control", "stat") == "answer to stat"
    assert Proxy.made[0].calls == ["stat"] and Proxy.made[0].closed
    assert Proxy.made[2].calls == ["stat"]


def test_a_read_only_call_whose_answer_never_came_is_made_again_once_on_a_fresh_connection(backend):
    call(backend, "/file_control", "stat")
    Proxy.made[0].failures = [transport_error()]
    assert call(backend, "/file_control", "read") == "answer to read"
    assert [p.calls for p in Proxy.made] == [["stat", "read"], ["read"]]


def test_a_call_that_may_have_changed_something_is_not_made_again(backend):
    call(backend, "/calibration_control", "get")
    Proxy.made[0].failures = [transport_error()]
    with pytest.raises(ros_backend.BridgeError) as failed:
        call(backend, "/calibration_control", "mark_box")
    assert "its node closed the connection before answering, the request may have run" in str(failed.value)
    assert len(Proxy.made) == 1


def test_a_request_whose_write_failed_is_made_again_whatever_the_command(backend):
    from rospy.exceptions import TransportTerminated
    call(backend, "/calibration_control", "get")
    Proxy.made[0].failures = [TransportTerminated("32Broken pipe")]
    assert call(backend, "/calibration_control", "apply") == "answer to apply"
    assert [p.calls for p in Proxy.made] == [["get", "apply"], ["apply"]]


def test_while_the_node_is_away_the_call_fails_once_with_the_clear_reason(backend):
    import rospy
    call(backend, "/file_control", "stat")
    Proxy.made[0].failures = [transport_error()]
    Proxy.next_failures = [rospy.ServiceException("unable to connect to service: [Errno 111] Connection refused")]
    with pytest.raises(ros_backend.BridgeError) as failed:
        call(backend, "/file_control", "stat")
    assert str(failed.value).startswith("service /file_control is not available: its node is restarting or down (")
    assert len(Proxy.made) == 2                 # one fresh connection, not a loop
    Proxy.next_failures = [rospy.ServiceException("service [/file_control] unavailable")]
    with pytest.raises(ros_backend.BridgeError) as failed:
        call(backend, "/file_control", "stat")  # a fresh connection fails: not called again
    assert "is not available: its node is restarting or down" in str(failed.value)
    assert len(Proxy.made) == 3


def test_an_idle_connection_to_where_the_service_was_is_dropped(backend):
    call(backend, "/file_control", "stat")
    Proxy.uri = "rosrpc://host:2"               # another node serves it now (the old one still up)
    call(backend, "/file_control", "stat")
    assert Proxy.made[0].calls == ["stat"] and Proxy.made[0].closed
    assert Proxy.made[1].calls == ["stat"]
