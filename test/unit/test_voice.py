"""VoiceCmd markup readings in both languages, and the file output with real espeak-ng."""
import os
import shutil
import wave

import pytest

from inspection_robot.charge.states import VOICE_CLIPS as CHARGE_VOICE_CLIPS
from inspection_robot.interface import BATTERY_CHARGING, CIRCUIT_BATTERY_CRITICAL, CIRCUIT_JOY_COMM_LOST, MODE_NAMES
from inspection_robot.motion.safety import SafetyLatch
from inspection_robot.motion.voice import status_sentence
from inspection_robot.voice.phrases import (BUILTIN_PHRASES, Clip, Speech, VoiceError, parse_command, parse_item,
                                            zh_integer)
from inspection_robot.voice.player import FileOutput


@pytest.mark.parametrize("n,spoken", [
    (0, "零"), (7, "七"), (10, "十"), (12, "十二"), (20, "二十"), (110, "一百一十"), (123, "一百二十三"),
    (1005, "一千零五"), (1050, "一千零五十"), (10000, "一万"), (10010, "一万零一十"), (100000, "十万"),
    (1000000, "一百万"), (100000000, "一亿"), (100000001, "一亿零一"), (-15, "负十五"),
])
def test_chinese_integers(n, spoken):
    assert zh_integer(n) == spoken


@pytest.mark.parametrize("item,spoken", [
    ("[123]", "一百二十三"), ("{123}", "一二三"), ("(34)", "三十四摄氏度"), ("%17%", "百分之十七"),
    ("[-3.5]", "负三点五"), ("(36.8)", "三十六点八摄氏度"),
])
def test_spec_examples_chinese(item, spoken):
    assert parse_item(item, "chinese") == Speech(spoken)


@pytest.mark.parametrize("item,spoken", [
    ("[123]", "one hundred twenty-three"), ("{123}", "one two three"), ("(34)", "thirty-four degrees Celsius"),
    ("%17%", "seventeen percent"), ("[2500000]", "two million five hundred thousand"),
    ("[-0.5]", "minus zero point five"),
])
def test_english(item, spoken):
    assert parse_item(item, "english") == Speech(spoken)


def test_clips_and_errors():
    assert parse_item("battery_low", "chinese") == Clip("battery_low")
    for bad in ["../etc/passwd", "[12a]", "{1.5}", "a b", "[" + "9" * 20 + "]"]:
        with pytest.raises(VoiceError):
            parse_item(bad, "chinese")
    with pytest.raises(VoiceError):
        parse_item("[1]", "klingon")
    with pytest.raises(VoiceError):
        parse_command([], "english")


@pytest.mark.skipif(shutil.which("espeak-ng") is None, reason="espeak-ng not installed")
def test_file_output_synthesises_wav_and_rejects_missing_clip(tmp_path):
    clips = tmp_path / "clips"
    clips.mkdir()
    out = FileOutput(str(clips), str(tmp_path / "out"))
    written = out.play(parse_command(["[42]"], "english"), "english")
    with wave.open(written[0]) as wav:
        assert wav.getnframes() > wav.getframerate() * 0.2  # at least 0.2 s of speech
    with pytest.raises(VoiceError, match="missing_clip"):
        out.check(parse_command(["missing_clip"], "chinese"))
    assert len(os.listdir(str(tmp_path / "out"))) == 1


@pytest.mark.parametrize("language", ["chinese", "english"])
def test_query_status_clips_are_spoken_without_recorded_clips(tmp_path, language):
    # robot_control's query_status names clips; with no <name>.wav shipped, robot_voice used to fail
    # the whole request ("clip status_report.wav not found"), so the robot said nothing
    latch = SafetyLatch()
    for flag in ("soft_estop", "hard_estop", "bumper", "fall_left", "fall_right", "obstacle", "drive_fault"):
        setattr(latch, flag, True)
    names = set()
    for mode in MODE_NAMES:
        fields = {"mode": mode, "battery_quantity": 50, "battery_voltage": 480, "temperature": [250] * 13,
                  "circuit_status": CIRCUIT_BATTERY_CRITICAL | CIRCUIT_JOY_COMM_LOST,
                  "battery_status": BATTERY_CHARGING}
        names.update(w for w in status_sentence(fields, latch.reasons()) if isinstance(parse_item(w, language), Clip))
    names.add("status_normal")
    names.update(CHARGE_VOICE_CLIPS)
    assert len(names) == len(BUILTIN_PHRASES) and names == set(BUILTIN_PHRASES)
    out = FileOutput(str(tmp_path), str(tmp_path / "out"))
    parts = out.resolve(parse_command(sorted(names) + ["[5]"], language), language)
    assert all(isinstance(p, Speech) and p.text for p in parts)
    assert parts[sorted(names).index("volt")] == Speech("伏" if language == "chinese" else "volts")
    (tmp_path / "volt.wav").write_bytes(b"RIFF")   # a recorded clip takes precedence
    assert out.resolve([Clip("volt")], language) == [Clip("volt")]
    with pytest.raises(VoiceError, match="no_such_clip.wav not found"):
        out.resolve([Clip("no_such_clip")], language)
