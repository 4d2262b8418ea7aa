"""Pure logic of bag_report: what happened during a recorded run, from plain values.

tools/bag_report reads the bag (rosbag API) and feeds a RunAnalyzer with plain numbers and
strings, one call per message; ``finish()`` returns a RunSummary (series for the plots, stops,
goals, readings, alarms, faults, obstacles) and ``format_summary`` the text. No ROS, no plotting:
unit tests drive it with made-up runs.

Definitions (docs/operator.md "bag_report"):
- position: robot_status's, except while its nav_status stale bit is set (no pose yet: not drawn);
- distance: path length of robot_status positions (pose jitter under 1 mm is measured only once
  it adds up; a step over ``max_jump_m`` is a relocalisation, not distance);
- stop: the robot stood still (|velocity_x| and |velocity_yaw| under the thresholds) for at least
  ``min_stop_s``;
- alarm: the rising edge of an alarm bit of robot_status (ALARM_BITS) or of offline_warn;
- alarm also: a patrol reading whose alarm state is ``alarm`` (outside its band) or ``check`` (an
  uncertain value outside its band);
- fault: a ``*_ack`` answered ``failed``, an action result other than "0", a motor_status fault, a
  patrol reading that failed, a patrol task that ended ``failed``;
- reading: each reading of task_status ``last_result`` (a new last_result is one that differs from
  the previous task_status's: task_status is republished every second and repeated at the start of
  every split), with its target, value, unit and alarm state; and a read_scale_ack's values
  (``scale`` and ``foreign_scale``) of a reading that a backend asked for (task_manager's own
  read_scale_acks are the task readings already).
"""
import collections
import json
import math

from inspection_robot.interface import (ACK_FAILED, BATTERY_HIGH_TEMP, BATTERY_LINE_FAULT, BATTERY_LOW_TEMP,
                                        BATTERY_OVER_VOLTAGE, BATTERY_UNDER_VOLTAGE, CIRCUIT_BATTERY_CRITICAL,
                                        CIRCUIT_COLLISION_LINE, CIRCUIT_JOY_COMM_LOST, CIRCUIT_STEPPER_COMM,
                                        LIGHT_BUMPER, LIGHT_HARD_ESTOP, LIGHT_SOFT_ESTOP, MODE_NAMES,
                                        MOTOR_NAMES, NAV_LOCALIZATION_LOST, NAV_OBSTACLE_3D, NAV_OFF_TRACK,
                                        SENSOR_CAMERA_ALARM, SENSOR_THERMAL_ALARM, STOP_FRONT_COLLISION,
                                        STOP_LEFT_FALL, STOP_OBSTACLE, STOP_RIGHT_FALL)
from inspection_robot.status.merge import STALE_NAV_STATUS
from inspection_robot.task.states import (ALARM_ALARM, ALARM_CHECK, ALARM_NONE, ALARM_WARNING, STATE_FAILED,
                                          STATUS_FAILED, STATUS_READ, STATUS_UNCERTAIN)

# (robot_status field, bit, alarm name): each rising edge is one alarm.
ALARM_BITS = (
    ("light_status", LIGHT_SOFT_ESTOP, "soft e-stop"),
    ("light_status", LIGHT_HARD_ESTOP, "hard e-stop"),
    ("light_status", LIGHT_BUMPER, "bumper"),
    ("stop_status", STOP_FRONT_COLLISION, "front collision"),
    ("stop_status", STOP_OBSTACLE, "obstacle stop"),
    ("stop_status", STOP_LEFT_FALL, "left fall"),
    ("stop_status", STOP_RIGHT_FALL, "right fall"),
    ("circuit_status", CIRCUIT_STEPPER_COMM, "stepper board comm"),
    ("circuit_status", CIRCUIT_JOY_COMM_LOST, "joystick link lost"),
    ("circuit_status", CIRCUIT_COLLISION_LINE, "collision line fault"),
    ("circuit_status", CIRCUIT_BATTERY_CRITICAL, "battery critical"),
    ("nav_status", NAV_OFF_TRACK, "off track"),
    ("nav_status", NAV_LOCALIZATION_LOST, "localization lost"),
    ("nav_status", NAV_OBSTACLE_3D, "3-D obstacle"),
    ("sensor_status", SENSOR_CAMERA_ALARM, "camera alarm"),
    ("sensor_status", SENSOR_THERMAL_ALARM, "thermal imager alarm"),
    ("battery_status", BATTERY_UNDER_VOLTAGE, "battery under-voltage"),
    ("battery_status", BATTERY_OVER_VOLTAGE, "battery over-voltage"),
    ("battery_status", BATTERY_LOW_TEMP, "battery low temperature"),
    ("battery_status", BATTERY_HIGH_TEMP, "battery high temperature"),
    ("battery_status", BATTERY_LINE_FAULT, "battery line fault"),
)
OFFLINE_ALARM = "backend link lost (offline_warn)"

Event = collections.namedtuple("Event", "t x y text")
# One meter reading: ``task`` the task id ("" for a backend's read_scale), ``value`` None when it failed.
Reading = collections.namedtuple("Reading", "t x y task stop target value unit alarm status reason")
READING_ALARMS = (ALARM_ALARM, ALARM_CHECK, ALARM_WARNING)   # outside its band (uncertain: check; warning zone)
ALARM_TEXT = {"none": "no limits"}
Stop = collections.namedtuple("Stop", "t x y duration")


class RunSummary(object):
    """Everything bag_report draws and prints. Times are seconds since the run's start (``start``)."""

    def __init__(self):
        self.start = None          # absolute bag time of the first robot_status (s)
        self.duration = 0.0
        self.distance = 0.0
        self.max_speed = 0.0
        self.status_count = 0
        self.t, self.x, self.y, self.speed, self.battery, self.mode = [], [], [], [], [], []
        self.stops, self.goals, self.readings = [], [], []   # readings: Reading tuples
        self.alarms, self.faults, self.obstacles = [], [], []
        self.tasks = collections.OrderedDict()   # task id -> last state seen (and reason)


class RunAnalyzer(object):
    def __init__(self, stop_speed=0.02, stop_yaw_rate=0.02, min_stop_s=2.0, max_jump_m=5.0):
        self._stop_speed = stop_speed
        self._stop_yaw_rate = stop_yaw_rate
        self._min_stop_s = min_stop_s
        self._max_jump = max_jump_m
        self._s = RunSummary()
        self._last = None            # previous robot_status fields
        self._still_since = None     # (t, x, y) when the robot last came to rest
        self._pending = []           # events before the first robot_status: placed once it is known
        self._last_result = None     # task_status last_result of the previous task_status (JSON text)

    # -- input, one call per message; t: absolute bag time in seconds -------------------------
    def add_status(self, t, status):
        """``status``: dict of robot_status fields (as in RobotStatus)."""
        s = self._s
        if s.start is None:
            s.start = t
        rel = t - s.start
        x, y = (list(status["position"]) + [float("nan")] * 2)[:2]
        other = list(status.get("other_status") or [0])
        if other[0] & STALE_NAV_STATUS:     # no nav_status (yet): the position is not a pose
            x = y = float("nan")
        if self._last is not None:
            ax, ay = self._anchor
            step = math.hypot(x - ax, y - ay)
            if not step == step:            # nan: no pose now or at the anchor
                if x == x:
                    self._anchor = (x, y)
            elif step > self._max_jump:     # relocalised: no distance, measure from here on
                self._anchor = (x, y)
            elif step >= 1e-3:              # below: pose jitter, measured once it adds up
                s.distance += step
                self._anchor = (x, y)
            self._edges(rel, x, y, self._last, status)
        else:
            self._anchor = (x, y)
            if status.get("offline_warn"):
                s.alarms.append(Event(rel, x, y, OFFLINE_ALARM))
        speed = float(status["velocity_x"])
        s.max_speed = max(s.max_speed, abs(speed))
        s.status_count += 1
        for series, value in ((s.t, rel), (s.x, x), (s.y, y), (s.speed, speed),
                              (s.battery, int(status["battery_quantity"])), (s.mode, int(status["mode"]))):
            series.append(value)
        self._track_stop(rel, x, y, speed, float(status["velocity_yaw"]))
        self._last = dict(status, position=[x, y])
        s.duration = rel
        for pending in self._pending:
            pending()
        self._pending = []

    def add_goal(self, t, data):
        """A move_action goal's JSON ``data``; returns a problem text or None (bad goals are not drawn)."""
        try:
            position = json.loads(data)["goal_pose"]["position"]
            gx, gy = float(position["x"]), float(position["y"])
        except (ValueError, KeyError, TypeError) as exc:
            return "move_action goal without a readable goal_pose (%s)" % (exc.__class__.__name__,)
        self._at(t, lambda rel, x, y: self._s.goals.append(Event(rel, gx, gy, "goal")))
        return None

    def add_obstacle(self, t, obstacle):
        if obstacle:
            self._at(t, lambda rel, x, y: self._s.obstacles.append(Event(rel, x, y, "3-D obstacle")))

    def add_reading(self, t, source, values):
        """``values``: the numbers of a read_scale_ack that a backend asked for (scale + foreign_scale)."""
        values = [float(v) for v in values]
        self._at(t, lambda rel, x, y: self._s.readings.append(
            Reading(rel, x, y, "", 0, source, values or None, "", ALARM_NONE, STATUS_READ if values else STATUS_FAILED,
                    "" if values else "no value")))

    def add_task_status(self, t, data):
        """One task_status message's JSON ``data``; returns a problem text or None (bad ones are skipped)."""
        try:
            status = json.loads(data)
            task_id, state = str(status["task_id"]), str(status["state"])
            result = status.get("last_result")
            readings = [] if result is None else [
                (str(r["target"]), r.get("value"), str(r.get("unit", "")), str(r.get("alarm", "")),
                 str(r.get("status", "")), str(r.get("reason", result.get("reason", ""))))
                for r in result["readings"]]
            stop = int(result["stop"]) if result is not None else 0
            if not all(r[1] is None or (isinstance(r[1], (int, float)) and not isinstance(r[1], bool))
                       for r in readings):
                raise TypeError("a reading value is not a number")
        except (ValueError, KeyError, TypeError, AttributeError) as exc:
            return "task_status without a readable task_id, state or last_result (%s)" % (exc.__class__.__name__,)
        key = json.dumps(result, sort_keys=True)
        if result is not None and key != self._last_result:
            # task_id is the task the result was recorded for: the running one, or the one that just ended
            for fields in readings:
                self._at(t, lambda rel, x, y, f=fields: self._task_reading(Reading(rel, x, y, task_id, stop, *f)))
        self._last_result = key
        if task_id:
            before = self._s.tasks.get(task_id)
            self._s.tasks[task_id] = (state, str(status.get("reason", "")))
            if state == STATE_FAILED and (before is None or before[0] != STATE_FAILED):
                self._at(t, lambda rel, x, y: self._s.faults.append(
                    Event(rel, x, y, "task %s failed: %s" % (task_id, status.get("reason", "")))))
        return None

    def _task_reading(self, reading):
        s = self._s
        s.readings.append(reading)
        where = (reading.t, reading.x, reading.y)
        if reading.alarm in READING_ALARMS:
            s.alarms.append(Event(*where, text="reading %s: %s %s" % (reading.alarm, reading.target,
                                                                      value_text(reading))))
        if reading.status == STATUS_FAILED:
            s.faults.append(Event(*where, text="reading failed: %s: %s" % (reading.target, reading.reason or "?")))

    def add_ack(self, t, topic, ack, data):
        if ack == ACK_FAILED:
            self._at(t, lambda rel, x, y: self._s.faults.append(Event(rel, x, y, "%s failed: %s" % (topic, data))))

    def add_action_result(self, t, action, ret_code, data):
        if ret_code != "0":
            try:
                reason = json.loads(data).get("reason", data)
            except (ValueError, AttributeError):
                reason = data
            self._at(t, lambda rel, x, y: self._s.faults.append(
                Event(rel, x, y, "%s ended with %s: %s" % (action, ret_code, reason))))

    def finish(self):
        s = self._s
        if self._still_since is not None and s.t:
            self._close_stop(s.t[-1])
        return s

    # -- helpers --------------------------------------------------------------------------------
    def _at(self, t, record):
        """Call ``record(rel_t, x, y)`` with the robot's latest position (after the first status)."""
        if self._s.start is None:
            self._pending.append(lambda: self._at(t, record))
            return
        x, y = self._last["position"] if self._last else (float("nan"), float("nan"))
        record(t - self._s.start, x, y)

    def _edges(self, rel, x, y, before, after):
        for field, bit, name in ALARM_BITS:
            if int(after[field]) & bit and not int(before[field]) & bit:
                self._s.alarms.append(Event(rel, x, y, name))
        if after["offline_warn"] and not before["offline_warn"]:
            self._s.alarms.append(Event(rel, x, y, OFFLINE_ALARM))
        for i, (old, new) in enumerate(zip(before["motor_status"], after["motor_status"])):
            if new and not old:
                name = MOTOR_NAMES[i] if i < len(MOTOR_NAMES) else "motor %d" % i
                self._s.faults.append(Event(rel, x, y, "%s motor_status 0x%02x" % (name, new)))

    def _track_stop(self, rel, x, y, speed, yaw_rate):
        still = abs(speed) < self._stop_speed and abs(yaw_rate) < self._stop_yaw_rate
        if still and self._still_since is None:
            self._still_since = (rel, x, y)
        elif still and self._still_since[1] != self._still_since[1]:   # stood still before the first pose
            self._still_since = (self._still_since[0], x, y)
        elif not still and self._still_since is not None:
            self._close_stop(rel)

    def _close_stop(self, rel):
        since, x, y = self._still_since
        self._still_since = None
        if rel - since >= self._min_stop_s:
            self._s.stops.append(Stop(since, x, y, rel - since))


def value_text(reading):
    """``118.2 C``, ``0.5, 1.25`` (several values of one read), or ``failed``."""
    if reading.status == STATUS_FAILED or reading.value is None:
        return STATUS_FAILED
    if isinstance(reading.value, list):
        return ", ".join("%g" % v for v in reading.value)
    return ("%g %s" % (reading.value, reading.unit)).strip()


def reading_text(reading):
    """One line of the summary and of the picture: where it was asked, what, the value and its state."""
    source = ("%s stop %d" % (reading.task, reading.stop)) if reading.task else "backend"
    state = reading.reason if reading.status == STATUS_FAILED else ALARM_TEXT.get(reading.alarm, reading.alarm)
    if reading.status == STATUS_UNCERTAIN:
        state = "%s, uncertain: %s" % (state, reading.reason)
    return "%s: %s = %s (%s)" % (source, reading.target, value_text(reading), state or "?")


def where_text(x, y):
    """``at (1.0, 2.0)``, or ``position unknown`` for an event before the robot had a pose (never nan)."""
    if not (math.isfinite(x) and math.isfinite(y)):
        return "position unknown"
    return "at (%.1f, %.1f)" % (x, y)


def _clock(seconds):
    seconds = max(0, int(round(seconds)))
    return "%d:%02d:%02d" % (seconds // 3600, seconds // 60 % 60, seconds % 60)


def _events(title, events, limit=10):
    lines = ["%s: %d" % (title, len(events))]
    for e in events[:limit]:
        lines.append("  %s  %-40s %s" % (_clock(e.t), e.text, where_text(e.x, e.y)))
    if len(events) > limit:
        lines.append("  ... and %d more" % (len(events) - limit))
    return lines


def mode_time(summary):
    """Seconds spent in each mode name (time until the next status counted for the previous mode)."""
    spent = collections.OrderedDict()
    for i in range(len(summary.t) - 1):
        name = MODE_NAMES.get(summary.mode[i], str(summary.mode[i]))
        spent[name] = spent.get(name, 0.0) + summary.t[i + 1] - summary.t[i]
    return spent


def format_summary(summary, bag_name=""):
    s = summary
    battery = ("%d %% -> %d %%" % (s.battery[0], s.battery[-1])) if s.battery else "n/a"
    lines = ["run %s" % bag_name if bag_name else "run",
             "duration: %s (%.1f s), robot_status messages: %d" % (_clock(s.duration), s.duration, s.status_count),
             "distance: %.1f m, max speed %.2f m/s, battery %s" % (s.distance, s.max_speed, battery),
             "modes: " + (", ".join("%s %.0f s" % kv for kv in mode_time(s).items()) or "n/a"),
             "goals: %d" % len(s.goals)]
    lines.append("stops: %d" % len(s.stops))
    for stop in s.stops[:10]:
        lines.append("  %s  %.0f s %s" % (_clock(stop.t), stop.duration, where_text(stop.x, stop.y)))
    if len(s.stops) > 10:
        lines.append("  ... and %d more" % (len(s.stops) - 10))
    alarmed = sum(1 for r in s.readings if r.alarm in READING_ALARMS)
    failed = sum(1 for r in s.readings if r.status == STATUS_FAILED)
    readings = _events("readings", [Event(r.t, r.x, r.y, reading_text(r)) for r in s.readings], limit=40)
    readings[0] += " (%d alarm, %d failed)" % (alarmed, failed)
    lines += readings
    lines.append("tasks: %d" % len(s.tasks))
    lines += ["  %s %s%s" % (task, state, (": " + reason) if reason else "")
              for task, (state, reason) in s.tasks.items()]
    lines += _events("alarms", s.alarms)
    lines += _events("faults", s.faults)
    lines += _events("3-D obstacles", s.obstacles, limit=5)
    return "\n".join(lines)
