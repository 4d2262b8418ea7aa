"""The service/topic twin every device node offers (INTERFACE.md section 3).

``X_control`` (ControlService) and ``X_cmd``/``X_ack`` (GeneralCmd/GeneralAck) reach the same
CommandTable. Service calls run in rospy's per-call thread; topic commands go to one
RequestWorker so the subscriber callback returns at once and commands run in arrival order.
A node with only the topic pair (move_base's virtual obstacles) passes ``service=None``.
While the joystick holds the robot (mode 2) every request from another sender is answered
``failed``/``busy`` without reaching the table. Failure reasons leave with the data root's location
taken out (files.hide_root): a client learns the path it sent, never where the robot keeps files.
"""
import threading
import traceback

import rospy

from inspection_robot.command import Reply, echoed, failed
from inspection_robot.files import hide_root
from inspection_robot.interface import ACK_SUCCESS, BUSY, MODE_JOY, SENDER_JOY
from inspection_robot.msg import ControlStatus, GeneralAck, GeneralCmd
from inspection_robot.ros.worker import RequestWorker
from inspection_robot.srv import ControlService, ControlServiceResponse


def control_response(request, reply):
    """The ControlService response carrying ``reply`` (a command.Reply), trans_id echoed."""
    return ControlServiceResponse(trans_id=request.trans_id, ack=reply.ack, data=reply.data)


def serve_table(name, table):
    """A ControlService ``name`` answering each call with ``table.dispatch(cmd, data)`` (simulator controls)."""
    return rospy.Service(name, ControlService, lambda req: control_response(req, table.dispatch(req.cmd, req.data)))


class ModeWatcher(object):
    """Tracks robot_control's current mode from control_status."""

    def __init__(self, topic="control_status"):
        self.mode = None
        self._sub = rospy.Subscriber(topic, ControlStatus, self._on_status, queue_size=1)

    def _on_status(self, msg):
        self.mode = msg.mode

    def joystick_holds(self):
        return self.mode == MODE_JOY


class CommandTwin(object):
    """Serves ``table`` on a ControlService and on a cmd/ack topic pair.

    ``node_name`` is written into the ack's sender field. ``busy_when_joystick`` applies the
    joystick-busy rule. ``unprompted`` acks (e.g. a failure during arm playback) go through
    :meth:`publish_ack`. ``data_root``: the node's data root (ros/data_root.data_root(), read once in
    its main()), taken out of failure reasons.
    """

    def __init__(self, table, service, cmd_topic, ack_topic, node_name, data_root,
                 busy_when_joystick=True, queue_size=50, staging=None):
        self._table = table
        self._node_name = node_name
        self._modes = ModeWatcher() if busy_when_joystick else None
        self._lock = threading.Lock()  # one command at a time reaches the device
        self._data_root = data_root
        self._ack_pub = rospy.Publisher(ack_topic, GeneralAck, queue_size=50)
        self._worker = RequestWorker(node_name + ": " + cmd_topic, self._run_topic_command, self._refuse,
                                     queue_size)
        self._cmd_sub = rospy.Subscriber(cmd_topic, GeneralCmd, self._worker.submit, queue_size=50)
        self._service = rospy.Service(service, ControlService, self._on_service) if service else None
        # (table, service name): the device's staging service for the robot's own nodes, same lock
        self._staging = None
        if staging is not None:
            self._staging_table = staging[0]
            self._staging = rospy.Service(staging[1], ControlService, self._on_staging)

    def busy_for(self, sender):
        """True while the joystick holds the robot and ``sender`` is not the joystick."""
        return self._modes is not None and self._modes.joystick_holds() and sender != SENDER_JOY

    def handle(self, sender, cmd, data, table=None):
        """Run one command and return its Reply; the single entry point of both twins (and of the
        staging service, with its ``table``)."""
        if self.busy_for(sender):
            return failed(BUSY)
        try:
            with self._lock:
                reply = (table or self._table).dispatch(cmd, data)
        except Exception as err:  # boundary: a bug in one command must not kill the node
            rospy.logerr("%s: command %s(%r) raised: %s\n%s", self._node_name, cmd, data, err,
                         traceback.format_exc())
            return failed(hide_root("internal error: %s" % (err,), self._data_root))
        if reply.ack != ACK_SUCCESS:
            reply = Reply(reply.ack, hide_root(reply.data, self._data_root))
            # identical failures (a sender repeating one bad command) are logged once a second
            rospy.logwarn_throttle_identical(1.0, "%s: %s(%r) from %r failed: %s"
                                             % (self._node_name, echoed(cmd), data[:80], sender, reply.data))
        return reply

    def _on_service(self, req):
        return control_response(req, self.handle(req.sender, req.cmd, req.data))

    def _on_staging(self, req):
        return control_response(req, self.handle(req.sender, req.cmd, req.data, self._staging_table))

    def _run_topic_command(self, msg):
        self.publish_ack(self.handle(msg.sender, msg.cmd, msg.data), msg)

    def _refuse(self, msg):
        self.publish_ack(failed("busy: command queue full"), msg)

    def publish_ack(self, reply, request=None):
        """Publish ``reply`` on the ack topic, echoing ``request``'s trans_id and sender."""
        ack = GeneralAck(ack=reply.ack, data=reply.data, sender=self._node_name)
        ack.header.stamp = rospy.Time.now()
        if request is not None:
            ack.trans_id = request.trans_id
            ack.receiver = request.sender
        self._ack_pub.publish(ack)
