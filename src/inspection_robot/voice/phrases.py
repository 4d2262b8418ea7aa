"""VoiceCmd markup (INTERFACE.md section 4, "Voice") to a list of things to play.

Each string of VoiceCmd.data is one item: ``[123]`` a number read as a number (一百二十三),
``{123}`` read digit by digit (一二三), ``(34)`` a temperature (三十四摄氏度), ``%17%`` a
percentage (百分之十七), anything else the name of a clip ``<name>.wav``. Numbers may be
negative and decimal (``[-3.5]``). Both languages of the spec are supported.

``BUILTIN_PHRASES`` gives the text of the clips robot_control's query_status and charge_control use, so the robot
speaks its status out of the box; a recorded ``<name>.wav`` in the clip directory takes precedence.
"""
import re
from collections import namedtuple

Speech = namedtuple("Speech", "text")
Clip = namedtuple("Clip", "name")

_NUMBER = r"-?\d+(?:\.\d+)?"
_PATTERNS = (
    ("number", re.compile(r"^\[(%s)\]$" % _NUMBER)),
    ("digits", re.compile(r"^\{(\d+)\}$")),
    ("temperature", re.compile(r"^\((%s)\)$" % _NUMBER)),
    ("percent", re.compile(r"^%%(%s)%%$" % _NUMBER)),
)
_CLIP_NAME = re.compile(r"^[A-Za-z0-9_\-\u4e00-\u9fff]+$")
MAX_INTEGER_DIGITS = 12

ZH_DIGITS = "零一二三四五六七八九"
EN_DIGITS = ("zero", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine")
EN_TEENS = ("ten", "eleven", "twelve", "thirteen", "fourteen", "fifteen", "sixteen", "seventeen",
            "eighteen", "nineteen")
EN_TENS = ("", "", "twenty", "thirty", "forty", "fifty", "sixty", "seventy", "eighty", "ninety")


# clip name -> (chinese, english): every name motion.voice.status_sentence and charge_control can produce
BUILTIN_PHRASES = {
    "status_report": ("机器人状态报告", "robot status report"),
    "mode_task": ("任务模式", "task mode"),
    "mode_server": ("后台遥控模式", "remote control mode"),
    "mode_joy": ("手柄遥控模式", "joystick mode"),
    "battery_quantity": ("电池电量", "battery charge"),
    "battery_voltage": ("电池电压", "battery voltage"),
    "volt": ("伏", "volts"),
    "battery_temperature": ("电池温度", "battery temperature"),
    "charging": ("正在充电", "charging"),
    "status_normal": ("状态正常", "status normal"),
    "alarm_soft_estop": ("软急停已开启", "soft emergency stop engaged"),
    "alarm_hard_estop": ("急停按钮已按下", "emergency stop button pressed"),
    "alarm_front_collision": ("防撞条触发", "bumper pressed"),
    "alarm_left_fall": ("左侧防跌落报警", "left fall alarm"),
    "alarm_right_fall": ("右侧防跌落报警", "right fall alarm"),
    "alarm_obstacle": ("前方有障碍物", "obstacle ahead"),
    "alarm_drive_fault": ("驱动器故障", "drive fault"),
    "alarm_battery_critical": ("电池电量严重不足", "battery critically low"),
    "alarm_joystick_lost": ("手柄通信中断", "joystick link lost"),
    # charge_control (charge.states.VOICE_CLIPS)
    "charge_battery_low": ("电量低", "battery low"),
    "charge_going_to_dock": ("返回充电桩充电", "going to the charging dock"),
    "charge_done": ("充电完成", "charging complete"),
    "charge_alarm": ("充电故障", "charging fault"),
    "charge_task_not_paused": ("巡检任务未暂停", "patrol did not pause"),
    "charge_dock_unreachable": ("无法到达充电桩", "charging dock unreachable"),
    "charge_relay_not_confirmed": ("充电继电器未闭合", "charge relay did not close"),
    "charge_no_current": ("没有充电电流", "no charging current"),
    "charge_relay_not_released": ("充电继电器未断开", "charge relay did not open"),
    "charge_backoff_failed": ("无法离开充电桩", "could not leave the dock"),
    "charge_task_not_resumed": ("巡检任务未恢复", "patrol did not resume"),
}


def builtin_phrase(name, language):
    """Speech for a clip name without a recorded clip, or None if the name is not built in."""
    texts = BUILTIN_PHRASES.get(name)
    if texts is None:
        return None
    return Speech(texts[0] if language == "chinese" else texts[1])


class VoiceError(ValueError):
    """An item that cannot be spoken; the message says which and why."""


def _zh_below_10000(n):
    """Chinese reading of 0 < n < 10000 with the zero rules (一千零五, 一百一十)."""
    units = ("千", "百", "十", "")
    digits = "%04d" % n
    out = []
    pending_zero = False
    for digit, unit in zip(digits, units):
        d = int(digit)
        if d == 0:
            pending_zero = bool(out)
            continue
        if pending_zero:
            out.append("零")
            pending_zero = False
        out.append(ZH_DIGITS[d] + unit)
    return "".join(out)


def zh_integer(n):
    if n == 0:
        return "零"
    if n < 0:
        return "负" + zh_integer(-n)
    groups = []
    while n:
        groups.append(n % 10000)
        n //= 10000
    out = ""
    for index in reversed(range(len(groups))):
        group = groups[index]
        unit = ("", "万", "亿")[index]
        if group == 0:
            if out and not out.endswith("零"):
                out += "零"
            continue
        if out and group < 1000 and not out.endswith("零"):
            out += "零"
        out += _zh_below_10000(group) + unit
    out = out.rstrip("零")
    if out.startswith("一十"):
        out = out[1:]  # 十二, not 一十二
    return out


def _en_below_1000(n):
    hundreds, rest = divmod(n, 100)
    words = []
    if hundreds:
        words.append(EN_DIGITS[hundreds] + " hundred")
    if rest >= 20:
        words.append(EN_TENS[rest // 10] + ("-" + EN_DIGITS[rest % 10] if rest % 10 else ""))
    elif rest >= 10:
        words.append(EN_TEENS[rest - 10])
    elif rest:
        words.append(EN_DIGITS[rest])
    return " ".join(words)


def en_integer(n):
    if n == 0:
        return "zero"
    if n < 0:
        return "minus " + en_integer(-n)
    words = []
    for scale in ("billion", "million", "thousand", ""):
        size = {"billion": 10 ** 9, "million": 10 ** 6, "thousand": 10 ** 3, "": 1}[scale]
        chunk, n = divmod(n, size)
        if chunk:
            words.append(_en_below_1000(chunk) if size == 1 or chunk < 1000 else en_integer(chunk))
            if scale:
                words.append(scale)
    return " ".join(words)


def read_number(text, language):
    """Spoken form of a decimal string like ``-12.05`` in ``language``."""
    negative = text.startswith("-")
    integer, _, fraction = text.lstrip("-").partition(".")
    if len(integer) > MAX_INTEGER_DIGITS:
        raise VoiceError("number too long: %s" % text)
    if language == "chinese":
        spoken = zh_integer(int(integer))
        if fraction:
            spoken += "点" + "".join(ZH_DIGITS[int(d)] for d in fraction)
        return ("负" if negative and spoken != "零" else "") + spoken
    spoken = en_integer(int(integer))
    if fraction:
        spoken += " point " + " ".join(EN_DIGITS[int(d)] for d in fraction)
    return ("minus " if negative else "") + spoken


def parse_item(item, language):
    """One VoiceCmd data string -> Speech or Clip; raises VoiceError for what cannot be played."""
    if language not in ("chinese", "english"):
        raise VoiceError("language must be chinese or english, got %r" % (language,))
    item = item.strip()
    for kind, pattern in _PATTERNS:
        match = pattern.match(item)
        if not match:
            continue
        value = match.group(1)
        if kind == "digits":
            if language == "chinese":
                return Speech("".join(ZH_DIGITS[int(d)] for d in value))
            return Speech(" ".join(EN_DIGITS[int(d)] for d in value))
        spoken = read_number(value, language)
        if kind == "number":
            return Speech(spoken)
        if kind == "temperature":
            return Speech(spoken + "摄氏度" if language == "chinese" else spoken + " degrees Celsius")
        return Speech("百分之" + spoken if language == "chinese" else spoken + " percent")
    if not _CLIP_NAME.match(item):
        raise VoiceError("not a number markup nor a clip name: %r" % (item[:60],))
    return Clip(item)


def parse_command(items, language):
    """All items of one VoiceCmd, in order; the first bad item fails the whole command."""
    if not items:
        raise VoiceError("empty voice command")
    return [parse_item(item, language) for item in items]
