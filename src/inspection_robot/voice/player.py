"""Audio back-ends of robot_voice: speech synthesis with espeak-ng and clip playback.

``SpeakerOutput`` plays on the robot's speaker (aplay); ``FileOutput`` (simulation) writes each
utterance as a WAV file into a directory so a laptop run and the tests can hear and check it.
Both synthesise with espeak-ng (cmn voice for chinese, en for english) and resolve clips before
anything is played: a recorded ``<name>.wav`` in the clip directory, else a built-in phrase
(``phrases.BUILTIN_PHRASES``) spoken by synthesis, else the whole request fails.
"""
import os
import subprocess
import time

from inspection_robot.voice.phrases import Clip, VoiceError, builtin_phrase

VOICES = {"chinese": "cmn", "english": "en"}


class _Output(object):
    def __init__(self, clip_dir, espeak="espeak-ng", timeout=30.0):
        self.clip_dir = clip_dir
        self.espeak = espeak
        self.timeout = timeout

    def clip_path(self, name):
        path = os.path.join(self.clip_dir, name + ".wav")
        if not os.path.isfile(path):
            raise VoiceError("clip %s.wav not found in %s" % (name, self.clip_dir))
        return path

    def resolve(self, parts, language):
        """``parts`` with each clip that has no file but a built-in phrase replaced by its Speech;
        fails before anything is played if a clip is neither."""
        resolved = []
        for part in parts:
            if isinstance(part, Clip) and not os.path.isfile(os.path.join(self.clip_dir, part.name + ".wav")):
                phrase = builtin_phrase(part.name, language)
                if phrase is None:
                    self.clip_path(part.name)   # raises the "not found" reason
                part = phrase
            resolved.append(part)
        return resolved

    def check(self, parts):
        """Fail before playing anything if a clip is missing (built-in phrases not considered)."""
        for part in parts:
            if isinstance(part, Clip):
                self.clip_path(part.name)

    def _synthesise(self, text, language, wav_path):
        cmd = [self.espeak, "-v", VOICES[language], "-w", wav_path, text]
        try:
            subprocess.run(cmd, check=True, timeout=self.timeout, stdout=subprocess.DEVNULL,
                           stderr=subprocess.PIPE)
        except (OSError, subprocess.SubprocessError) as err:
            raise VoiceError("speech synthesis failed: %s" % (err,))


class FileOutput(_Output):
    """Writes ``<out_dir>/<stamp>_<n>.wav`` per part (clips are copied by path, not re-encoded)."""

    def __init__(self, clip_dir, out_dir, **kwargs):
        super(FileOutput, self).__init__(clip_dir, **kwargs)
        self.out_dir = out_dir
        os.makedirs(out_dir, exist_ok=True)

    def play(self, parts, language):
        stamp = "%.6f" % time.time()
        written = []
        for index, part in enumerate(parts):
            target = os.path.join(self.out_dir, "%s_%02d.wav" % (stamp, index))
            if isinstance(part, Clip):
                with open(self.clip_path(part.name), "rb") as src, open(target, "wb") as dst:
                    dst.write(src.read())
            else:
                self._synthesise(part.text, language, target)
            written.append(target)
        return written


class SpeakerOutput(_Output):
    """Plays through ALSA's aplay on the robot's speaker."""

    def __init__(self, clip_dir, tmp_dir="/tmp", player="aplay", **kwargs):
        super(SpeakerOutput, self).__init__(clip_dir, **kwargs)
        self.tmp_dir = tmp_dir
        self.player = player

    def play(self, parts, language):
        for part in parts:
            if isinstance(part, Clip):
                path = self.clip_path(part.name)
            else:
                path = os.path.join(self.tmp_dir, "robot_voice.wav")
                self._synthesise(part.text, language, path)
            try:
                subprocess.run([self.player, "-q", path], check=True, timeout=self.timeout)
            except (OSError, subprocess.SubprocessError) as err:
                raise VoiceError("playback failed: %s" % (err,))
        return []
