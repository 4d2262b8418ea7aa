"""ROS side of the inspection head: terrace_control, camera_control and infrared_control calls,
and the robot's heading from nav_status. Shared by preset_scale and find_scale (not a node).

The camera and the imager write only new files inside their own capture roots; a picture for a
preset or a find result is taken there under a fresh hidden name (files.staged_name, in
``.staging/``, not listed by file_control; the only hidden name a capture command creates) and
moved by its owner, this process, to where it belongs (files.move_file).
"""
import itertools
import math
import os
import threading
import time

import rospy

from inspection_robot.files import FileError, move_file, staged_name
from inspection_robot.lazy import lazy_import
from inspection_robot.inspection.finder import FindError
from inspection_robot.interface import ACK_SUCCESS, ANGLE_CENTI_DEG, CAMERA_STAGING_SERVICE, INFRARED_STAGING_SERVICE
from inspection_robot.msg import NavStatus
from inspection_robot.srv import ControlService
from sensor_msgs.msg import JointState

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load

SETTLE_TIMEOUT_S = 2.0
SETTLE_TOLERANCE_DEG = 0.05


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
        # the pictures this head takes go through the devices' staging services (hidden staged names)
        self.camera_staging = DeviceClient(CAMERA_STAGING_SERVICE, sender, timeout)
        self.infrared_staging = DeviceClient(INFRARED_STAGING_SERVICE, sender, timeout)
        self._state = threading.Condition()
        self._joints = None
        self._state_sub = rospy.Subscriber("terrace_state", JointState, self._on_state, queue_size=1)

    def _on_state(self, msg):
        try:
            pan = math.degrees(msg.position[list(msg.name).index("pan")])
            tilt = math.degrees(msg.position[list(msg.name).index("tilt")])
        except (ValueError, IndexError):
            return
        with self._state:
            self._joints = (pan, tilt)
            self._state.notify_all()

    def set_angles(self, pan_deg, tilt_deg):
        pan_c, tilt_c = int(round(pan_deg * ANGLE_CENTI_DEG)), int(round(tilt_deg * ANGLE_CENTI_DEG))
        self.terrace.call("set_angle", "%d,%d" % (pan_c, tilt_c))
        # set_angle returns when the head reports the angle; wait until terrace_state (what the
        # camera's picture metadata and the simulator follow) says so too, so the next picture is
        # taken from the new view
        target = (pan_c / float(ANGLE_CENTI_DEG), tilt_c / float(ANGLE_CENTI_DEG))
        deadline = time.monotonic() + SETTLE_TIMEOUT_S
        with self._state:
            while not self._settled(target) and time.monotonic() < deadline and not rospy.is_shutdown():
                self._state.wait(0.05)

    def _settled(self, target):
        if self._joints is None:
            return True  # no terrace_state at all (e.g. a head without it): rely on set_angle
        d_pan = abs((self._joints[0] - target[0] + 180.0) % 360.0 - 180.0)
        return d_pan <= SETTLE_TOLERANCE_DEG and abs(self._joints[1] - target[1]) <= SETTLE_TOLERANCE_DEG

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
        _take(self.camera_staging, "capture_picture", path)
        image = cv2.imread(path, cv2.IMREAD_COLOR)
        if image is None:
            raise FindError("camera_control wrote no readable picture at %s" % path)
        return image

    def capture_thermal(self, picture_path, frame_path):
        _take(self.infrared_staging, "capture_picture", picture_path)
        _take(self.infrared_staging, "save_temperature", frame_path)


def _take(device, cmd, path):
    """``device`` writes a new file in its first root (the name keeps ``path``'s extension, which
    chooses save_temperature's format); it is then moved to ``path``."""
    staged = device.call(cmd, staged_name(os.path.splitext(path)[1]))
    try:
        move_file(staged, path)
    except FileError as err:
        try:
            os.unlink(staged)   # useless without its owner; do not leave it in the capture root
        except OSError:
            pass
        raise FindError("%s %s: %s" % (device.name, cmd, err))


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
