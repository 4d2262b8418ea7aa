"""joy_control: joystick teleoperation (motion.joystick.JoyTeleop).

Subscribes:  joy (sensor_msgs/Joy) from the ROS joy package or joystick_reader
Publishes:   mode_cmd (GeneralCmd) acquire joy / release; control_cmd (GeneralCmd) enable_stop /
             disable_stop; move_cmd (MoveCmd) at ~rate while the dead-man is held, one zero on release
             or when joy is silent for ~joy_timeout; terrace_cmd (GeneralCmd) pan/tilt on stick change.
             Every message has sender "joy_control" and an increasing trans_id.
Parameters:  config/joy_control.yaml: every setting, its default and meaning (read through ros.node.NodeSettings)
"""
import threading
import time

import rospy
from sensor_msgs.msg import Joy

from inspection_robot.interface import SENDER_JOY
from inspection_robot.motion.joystick import JoyTeleop
from inspection_robot.msg import GeneralCmd, MoveCmd
from inspection_robot.ros.node import NodeSettings, init_node


class JoyControl(object):
    def __init__(self, teleop, rate_hz):
        self._teleop = teleop
        self._lock = threading.Lock()
        self._trans_id = 0
        self._pubs = {
            "mode": rospy.Publisher("mode_cmd", GeneralCmd, queue_size=10),
            "control": rospy.Publisher("control_cmd", GeneralCmd, queue_size=10),
            "terrace": rospy.Publisher("terrace_cmd", GeneralCmd, queue_size=10),
            "move": rospy.Publisher("move_cmd", MoveCmd, queue_size=10),
        }
        rospy.Subscriber("joy", Joy, self._on_joy, queue_size=10)
        self._timer = rospy.Timer(rospy.Duration(1.0 / rate_hz), self._on_tick)

    def _on_joy(self, msg):
        with self._lock:
            self._publish(self._teleop.on_joy(msg.axes, msg.buttons, time.monotonic()))

    def _on_tick(self, _event):
        with self._lock:
            self._publish(self._teleop.tick(time.monotonic()))

    def _publish(self, actions):
        """Called under self._lock: the joy callback and the timer run on different threads, and
        trans_id must increase and the messages leave in the order the teleop decided them."""
        for action in actions:
            self._trans_id += 1
            kind = action[0]
            if kind == "move":
                msg = MoveCmd(velocity_x=action[1], velocity_yaw=action[2], wheel_control=action[3])
            elif kind == "mode":
                msg = GeneralCmd(cmd=action[1], data=action[2])
            elif kind == "terrace":
                msg = GeneralCmd(cmd=action[1], data=action[2], receiver="cloud_terrace")
            else:
                msg = GeneralCmd(cmd=action[1], data="")
            msg.sender = SENDER_JOY
            msg.trans_id = self._trans_id
            msg.header.stamp = rospy.Time.now()
            self._pubs[kind].publish(msg)

    def shutdown(self):
        self._timer.shutdown()
        with self._lock:
            self._publish(self._teleop.tick(float("inf")))  # as if the stream went silent: one stop


def main():
    init_node("joy_control")
    settings = NodeSettings("joy_control")
    rate_hz = float(settings.get("~rate"))
    if rate_hz <= 0:
        raise ValueError("~rate must be positive")
    teleop = JoyTeleop(settings.get("~axes"), settings.get("~buttons"),
                       float(settings.get("~max_velocity_x")), float(settings.get("~max_velocity_yaw")),
                       float(settings.get("~deadzone")), float(settings.get("~joy_timeout")),
                       str(settings.get("~terrace_speed")))
    node = JoyControl(teleop, rate_hz)
    rospy.on_shutdown(node.shutdown)
    rospy.spin()
