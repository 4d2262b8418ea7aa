"""When the bridge calls a ROS service again, and what it tells the client when a call fails.

The bridge keeps idle persistent connections to the services its clients call (bridge/ros_backend.py).
When the node behind one restarts, the connection is dead; rospy's ServiceProxy only finds out when
it uses it. Each way a call can fail says how far the request got, read from what rospy raises
(Noetic's rospy/impl/tcpros_service.py ServiceProxy.call and tcpros_base.TCPROSTransport):

- ``NOT_SENT``: the request cannot have reached a node: the master lookup failed (``service [/x]
  unavailable``: not registered; ``unable to contact master``), the connection could not be made
  (``unable to connect to service: [Errno 111] Connection refused``: rospy wraps its
  TransportInitError), or writing it failed (send_message raises TransportTerminated, TransportInitError
  or an OSError of the socket unwrapped). An idle connection found closed before the request is
  written never gets a request at all (the backend checks it first; it does not reach this module).
- ``MAY_HAVE_RUN``: the request was written, the answer never came (``transport error completing
  service call: unable to receive data from sender``): the node may have received and run it.
- ``REFUSED``: the node's handshake refused the connection (``unable to connect to service: remote
  error reported: ...``, e.g. another md5sum): calling again gets the same answer.
- ``ANSWERED``: the node answered with an error (``service [/x] responded with an error``) or the
  bridge is shutting down: never called again.

A call on a reused connection that failed is made once more on a fresh connection when the request
cannot have reached the node, or when the command only reads (interface.READ_ONLY_COMMANDS).
"""
from inspection_robot.interface import READ_ONLY_COMMANDS

NOT_SENT = "not_sent"
MAY_HAVE_RUN = "may_have_run"
REFUSED = "refused"
ANSWERED = "answered"

CONTROL_SERVICE_TYPE = "inspection_robot/ControlService"
# exception classes (by name: this module imports no rospy) raised by a failed write of the request
_SEND_FAILURES = ("TransportTerminated", "TransportInitError")
_NOT_SENT_TEXTS = ("unable to connect to service:", "unable to contact master")
_NOT_REGISTERED = "unavailable"


def failure_stage(exc_name, text, is_os_error=False):
    """How far a failed call's request got: NOT_SENT, MAY_HAVE_RUN, REFUSED or ANSWERED.

    ``exc_name`` is the exception's class name, ``text`` its message, ``is_os_error`` whether it is an
    OSError (a socket error rospy lets through from the request's write)."""
    if exc_name == "ROSInterruptException":
        return ANSWERED     # this node is shutting down: nothing to call again
    if is_os_error or exc_name in _SEND_FAILURES:
        return NOT_SENT
    if text.startswith("unable to connect to service: remote error reported"):
        return REFUSED
    if text.startswith(_NOT_SENT_TEXTS) or (text.startswith("service [") and text.endswith("] " + _NOT_REGISTERED)):
        return NOT_SENT
    if text.startswith("transport error completing service call"):
        return MAY_HAVE_RUN
    return ANSWERED


def is_read_only(service, type_name, cmd):
    """True when calling ``service`` (any namespace) with ``cmd`` changes nothing on the robot."""
    if type_name != CONTROL_SERVICE_TYPE or not isinstance(cmd, str):
        return False
    return cmd in READ_ONLY_COMMANDS.get(service.rstrip("/").rsplit("/", 1)[-1], ())


def may_call_again(stage, read_only):
    """Whether a call that failed at ``stage`` on a reused connection is made once more on a fresh one."""
    return stage == NOT_SENT or (stage == MAY_HAVE_RUN and read_only)


def failure_text(service, stage, reason):
    """What the client is told (``values`` of its failed service_response)."""
    if stage == NOT_SENT:
        return "service %s is not available: its node is restarting or down (%s)" % (service, reason)
    if stage == MAY_HAVE_RUN:
        return ("service %s failed: its node closed the connection before answering, the request may have run (%s)"
                % (service, reason))
    return "service %s failed: %s" % (service, reason)
