"""The service/topic twin every device node offers (INTERFACE.md section 3).

``X_control`` (ControlService) and ``X_cmd``/``X_ack`` (GeneralCmd/GeneralAck) reach the same
CommandTable. Service calls run in rospy's per-call thread; topic commands are queued to one
worker thread so the subscriber callback returns at once and commands run in arrival order.
While the joystick holds the robot (mode 2) every request from another sender is answered
``failed``/``busy`` without reaching the table.
"""
import queue
import threading
import traceback

import rospy

from inspection_robot.command import failed
from inspection_robot.interface import BUSY, MODE_JOY, SENDER_JOY
from inspection_robot.msg import ControlStatus, GeneralAck, GeneralCmd
from inspection_robot.srv import ControlService, ControlServiceResponse


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
    :meth:`publish_ack`.
    """

    def __init__(self, table, service, cmd_topic, ack_topic, node_name,
                 busy_when_joystick=True, queue_size=50):
        self._table = table
        self._node_name = node_name
        self._modes = ModeWatcher() if busy_when_joystick else None
        self._lock = threading.Lock()  # one command at a time reaches the device
        self._queue = queue.Queue(maxsize=queue_size)
        self._ack_pub = rospy.Publisher(ack_topic, GeneralAck, queue_size=50)
        self._worker = threading.Thread(target=self._work, name=cmd_topic + "_worker")
        self._worker.daemon = True
        self._worker.start()
        self._cmd_sub = rospy.Subscriber(cmd_topic, GeneralCmd, self._on_cmd, queue_size=50)
        self._service = rospy.Service(service, ControlService, self._on_service)

    def handle(self, sender, cmd, data):
        """Run one command and return its Reply; the single entry point of both twins."""
        if self._modes is not None and self._modes.joystick_holds() and sender != SENDER_JOY:
            return failed(BUSY)
        try:
            with self._lock:
                return self._table.dispatch(cmd, data)
        except Exception as err:  # boundary: a bug in one command must not kill the node
            rospy.logerr("%s: command %s(%r) raised: %s\n%s", self._node_name, cmd, data, err,
                         traceback.format_exc())
            return failed("internal error: %s" % (err,))

    def _on_service(self, req):
        reply = self.handle(req.sender, req.cmd, req.data)
        return ControlServiceResponse(trans_id=req.trans_id, ack=reply.ack, data=reply.data)

    def _on_cmd(self, msg):
        try:
            self._queue.put_nowait(msg)
        except queue.Full:
            rospy.logwarn_throttle(1.0, "%s: command queue full, dropping %s" % (self._node_name, msg.cmd))
            self.publish_ack(failed("busy: command queue full"), msg)

    def _work(self):
        while not rospy.is_shutdown():
            try:
                msg = self._queue.get(timeout=0.2)
            except queue.Empty:
                continue
            self.publish_ack(self.handle(msg.sender, msg.cmd, msg.data), msg)

    def publish_ack(self, reply, request=None):
        """Publish ``reply`` on the ack topic, echoing ``request``'s trans_id and sender."""
        ack = GeneralAck(ack=reply.ack, data=reply.data, sender=self._node_name)
        ack.header.stamp = rospy.Time.now()
        if request is not None:
            ack.trans_id = request.trans_id
            ack.receiver = request.sender
        self._ack_pub.publish(ack)
