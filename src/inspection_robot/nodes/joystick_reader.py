"""joystick_reader: Linux joystick device (/dev/input/jsN) -> sensor_msgs/Joy, where the ROS joy package is absent.

Publishes:   joy (sensor_msgs/Joy, axes in [-1, 1] with up/left +1 as the ROS joy package, buttons 0|1,
             header.frame_id = the device path) on every event and at ~autorepeat_rate while the device
             is open; nothing while it is missing, so joy_control's timeout stops the robot.
Parameters:  config/joystick_reader.yaml: every setting, its default and meaning (read through
             ros.node.NodeSettings) (motion.launch passes ~device)
"""
import os
import select
import threading

import rospy
from sensor_msgs.msg import Joy

from inspection_robot.motion.joystick import JsDecoder
from inspection_robot.ros.node import NodeSettings, init_node

READ_SIZE = 8 * 64


class JoystickReader(object):
    def __init__(self, device, autorepeat_hz, reconnect_max):
        self._device = device
        self._reconnect_max = reconnect_max
        self._lock = threading.Lock()
        self._decoder = None
        self._stop = threading.Event()
        self._pub = rospy.Publisher("joy", Joy, queue_size=10)
        self._thread = threading.Thread(target=self._run, name="joystick_reader")
        self._thread.daemon = True
        self._thread.start()
        self._timer = rospy.Timer(rospy.Duration(1.0 / autorepeat_hz), self._on_timer)

    def _run(self):
        backoff = 0.2
        while not self._stop.is_set():
            try:
                fd = os.open(self._device, os.O_RDONLY | os.O_NONBLOCK)
            except OSError as err:
                rospy.logwarn_throttle(30.0, "joystick_reader: cannot open %s: %s (retrying)" % (self._device, err))
                self._stop.wait(backoff)
                backoff = min(self._reconnect_max, backoff * 2)
                continue
            rospy.loginfo("joystick_reader: %s open" % self._device)
            with self._lock:
                self._decoder = JsDecoder()
            try:
                self._read(fd)
            except OSError as err:
                rospy.logwarn_throttle(30.0, "joystick_reader: %s lost: %s" % (self._device, err))
                if self._decoder.axes or self._decoder.buttons:
                    backoff = 0.2  # it worked: retry quickly
            finally:
                os.close(fd)
                with self._lock:
                    self._decoder = None
            self._stop.wait(backoff)
            backoff = min(self._reconnect_max, backoff * 2)

    def _read(self, fd):
        while not self._stop.is_set():
            readable, _, _ = select.select([fd], [], [], 0.2)
            if not readable:
                continue
            data = os.read(fd, READ_SIZE)
            if not data:
                raise OSError("end of file")
            with self._lock:
                changed = self._decoder.feed(data)
            if changed:
                self._publish()

    def _on_timer(self, _event):
        self._publish()

    def _publish(self):
        with self._lock:
            if self._decoder is None:
                return
            msg = Joy(axes=list(self._decoder.axes), buttons=list(self._decoder.buttons))
        msg.header.stamp = rospy.Time.now()
        msg.header.frame_id = self._device
        self._pub.publish(msg)

    def shutdown(self):
        self._stop.set()


def main():
    init_node("joystick_reader")
    settings = NodeSettings("joystick_reader")
    rate = float(settings.get("~autorepeat_rate"))
    reconnect_max = float(settings.get("~reconnect_max"))
    if rate <= 0 or reconnect_max <= 0:
        raise ValueError("~autorepeat_rate and ~reconnect_max must be positive")
    node = JoystickReader(str(settings.get("~device")), rate, reconnect_max)
    rospy.on_shutdown(node.shutdown)
    rospy.spin()
