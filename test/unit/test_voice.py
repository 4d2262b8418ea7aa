"""VoiceCmd markup readings in both languages, and the file output with real espeak-ng."""
import os
import shutil
import wave

import pytest

from inspection_robot.voice.phrases import Clip, Speech, VoiceError, parse_command, parse_item, zh_integer
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
