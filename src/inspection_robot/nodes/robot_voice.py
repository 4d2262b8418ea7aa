"""robot_voice: speaks VoiceCmd requests (INTERFACE.md section 4, "Voice").

Subscribes:  voice_cmd (VoiceCmd)
Publishes:   voice_ack (GeneralAck): success with the spoken text, or failed with the reason;
             trans_id echoed (a project addition: the spec defines no reply)
Parameters:  config/robot_voice.yaml: every setting, its default and meaning (read through ros.node.NodeSettings);
             data_root (namespace: ~out_dir lies under it unless absolute)
Requests are played one after another by a worker thread; a full queue drops the new request
with a failed ack rather than delaying every later prompt.
"""
import os

import rospy

from inspection_robot.interface import ACK_FAILED, ACK_SUCCESS
from inspection_robot.msg import GeneralAck, VoiceCmd
from inspection_robot.ros.node import NodeSettings, init_node
from inspection_robot.ros.worker import RequestWorker
from inspection_robot.voice.phrases import Speech, VoiceError, parse_command
from inspection_robot.voice.player import FileOutput, SpeakerOutput
from inspection_robot.ros.data_root import data_root


class RobotVoice(object):
    def __init__(self, output, queue_size):
        self._output = output
        self._ack = rospy.Publisher("voice_ack", GeneralAck, queue_size=20)
        self._worker = RequestWorker("robot_voice", self._speak, self._refuse, queue_size)
        rospy.Subscriber("voice_cmd", VoiceCmd, self._worker.submit, queue_size=20)

    def _refuse(self, msg):
        self._reply(msg, ACK_FAILED, "busy: voice queue full")

    def _speak(self, msg):
        try:
            parts = self._output.resolve(parse_command(list(msg.data), msg.language), msg.language)
            self._output.play(parts, msg.language)
        except VoiceError as err:
            rospy.logwarn("robot_voice: %s (from %s)" % (err, msg.sender))
            self._reply(msg, ACK_FAILED, str(err))
            return
        spoken = " ".join(p.text if isinstance(p, Speech) else "<%s.wav>" % p.name for p in parts)
        self._reply(msg, ACK_SUCCESS, spoken)

    def _reply(self, request, ack, data):
        msg = GeneralAck(sender="robot_voice", receiver=request.sender, trans_id=request.trans_id,
                         ack=ack, data=data)
        msg.header.stamp = rospy.Time.now()
        self._ack.publish(msg)


def main():
    init_node("robot_voice")
    settings = NodeSettings("robot_voice")
    kind = settings.get("~output")
    clip_dir = os.path.expanduser(settings.get("~clip_dir"))
    queue_size = int(settings.get("~queue_size"))
    if queue_size < 1:  # 0 would make the worker's queue unbounded: nothing ever refused
        raise ValueError("~queue_size must be >= 1, got %d" % queue_size)
    if kind == "file":
        out_dir = settings.path("~out_dir", data_root())
        output = FileOutput(clip_dir, out_dir)
    elif kind == "speaker":
        output = SpeakerOutput(clip_dir)
    else:
        raise ValueError("~output must be speaker or file, got %r" % (kind,))
    RobotVoice(output, queue_size)
    rospy.spin()
