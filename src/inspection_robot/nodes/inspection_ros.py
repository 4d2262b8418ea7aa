"""ROS side of the inspection head: terrace_control, camera_control and infrared_control calls,
and the robot's heading from nav_status. Shared by preset_scale and find_scale (not a node).
"""
import itertools
import threading

import cv2
import rospy

from inspection_robot.inspection.finder import FindError
from inspection_robot.interface import ACK_SUCCESS, ANGLE_CENTI_DEG
from inspection_robot.msg import NavStatus
from inspection_robot.srv import ControlService


class DeviceClient(object):
    """Calls one ControlService; a failure or a missing service raises FindError with the reason."""

    def __init__(self, name, sender, timeout):
        self.name = name
        self._sender = sender
        self._timeout = timeout
        self._proxy = rospy.ServiceProxy(name, ControlService)
        self._ids = itertools.count(1)

    def call(self, cmd, data=""):
        try:
            self._proxy.wait_for_service(self._timeout)
            reply = self._proxy(sender=self._sender, receiver="", trans_id=next(self._ids), cmd=cmd, data=data)
        except (rospy.ROSException, rospy.ServiceException) as err:
            raise FindError("%s %s failed: %s" % (self.name, cmd, err))
        if reply.ack != ACK_SUCCESS:
            raise FindError("%s %s(%s) failed: %s" % (self.name, cmd, data, reply.data))
        return reply.data


class RosHead(object):
    """inspection.finder.Head over the device services."""

    def __init__(self, sender, timeout=10.0):
        self.terrace = DeviceClient("terrace_control", sender, timeout)
        self.camera = DeviceClient("camera_control", sender, timeout)
        self.infrared = DeviceClient("infrared_control", sender, timeout)

    def set_angles(self, pan_deg, tilt_deg):
        self.terrace.call("set_angle", "%d,%d" % (int(round(pan_deg * ANGLE_CENTI_DEG)),
                                                  int(round(tilt_deg * ANGLE_CENTI_DEG))))

    def get_angles(self):
        text = self.terrace.call("get_angle")
        try:
            pan, tilt = (int(v) / float(ANGLE_CENTI_DEG) for v in text.split(","))
        except ValueError:
            raise FindError("terrace_control get_angle answered '%s'" % text)
        return pan, tilt

    def set_zoom(self, zoom):
        self.camera.call("set_zoom_level", "%.2f" % zoom)

    def get_zoom(self):
        text = self.camera.call("get_zoom_level")
        try:
            return float(text)
        except ValueError:
            raise FindError("camera_control get_zoom_level answered '%s'" % text)

    def get_focus(self):
        text = self.camera.call("get_focus_position")
        try:
            return int(text, 0)
        except ValueError:
            raise FindError("camera_control get_focus_position answered '%s'" % text)

    def hide_osd(self):
        """Pictures for matching carry no on-screen text; a camera without OSD control is fine."""
        try:
            self.camera.call("set_osd_mode", "0")
        except FindError as err:
            rospy.logwarn_throttle(30.0, "inspection: cannot turn the OSD off: %s" % err)

    def capture(self, path):
        self.camera.call("capture_picture", path)
        image = cv2.imread(path, cv2.IMREAD_COLOR)
        if image is None:
            raise FindError("camera_control wrote no readable picture at %s" % path)
        return image

    def capture_thermal(self, picture_path, frame_path):
        self.infrared.call("capture_picture", picture_path)
        self.infrared.call("save_temperature", frame_path)


class HeadingWatcher(object):
    """The robot's latest map pose from nav_status."""

    def __init__(self):
        self._lock = threading.Lock()
        self.pose = None
        self._sub = rospy.Subscriber("nav_status", NavStatus, self._on_nav, queue_size=1)

    def _on_nav(self, msg):
        if len(msg.position) >= 2:
            with self._lock:
                self.pose = (float(msg.position[0]), float(msg.position[1]), float(msg.orientation))

    def latest(self):
        with self._lock:
            return self.pose
