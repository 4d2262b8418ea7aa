"""A ROS-standard base as a chassis: the pure half of ``~driver: ros`` (no rospy).

Any base with a ROS driver (ros_control's diff_drive_controller, a vendor node) speaks
geometry_msgs/Twist in, nav_msgs/Odometry, sensor_msgs/BatteryState and std_msgs/Bool out.
``BaseInputs`` turns what those topics last said, and how long ago, into the ChassisState
robot_control already understands; ``motion/ros_chassis.py`` only moves messages in and out.

Fault mapping (docs/interface.md, "ROS base driver"):
- odometry or battery older than its timeout, or not received yet, or a wired safety input
  (e-stop, bumper, fall) not received yet: circuit_status b0 (the spec's "stepper board comm
  alarm": the drive's board is not reporting). The safety latch treats b0 as a drive fault, so the
  robot stops and stays stopped until the input is fresh again (and a new move_cmd arrives).
- battery stale or missing additionally sets battery_status b7 (battery line fault); a bumper input
  not received yet circuit b4 (collision line fault), fall inputs b5/b6 (left/right TOF line fault).
- While odometry is stale the measured velocity is reported as 0 (nothing known), so
  robot_control's odometry does not integrate an old speed.
"""
import math
from collections import OrderedDict, namedtuple

from inspection_robot.interface import (
    BATTERY_CHARGING, BATTERY_DISCHARGING, BATTERY_HIGH_TEMP, BATTERY_LINE_FAULT, BATTERY_LOW_TEMP,
    BATTERY_OVER_VOLTAGE, BATTERY_UNDER_VOLTAGE, CIRCUIT_BATTERY_CRITICAL, CIRCUIT_COLLISION_LINE,
    CIRCUIT_LEFT_TOF_LINE, CIRCUIT_RIGHT_TOF_LINE, CIRCUIT_STEPPER_COMM, TEMP_BATTERY, TEMPERATURE_COUNT)
from inspection_robot.motion.chassis import ChassisState

PARAM = "ros_base"   # robot_control's ~ros_base: the settings below

# name: (default, kind, meaning). kind "topic"/"service": a ROS name, "" = not wired;
# "seconds"/"percent": a positive number.
SETTINGS = OrderedDict([
    ("cmd_vel_topic", ("cmd_vel", "topic", "geometry_msgs/Twist out: the base's velocity command")),
    ("odom_topic", ("odom", "required_topic", "nav_msgs/Odometry in: measured velocity (twist, child frame)")),
    ("battery_topic", ("battery_state", "topic", "sensor_msgs/BatteryState in; \"\" = no battery reported")),
    ("estop_topic", ("", "topic", "std_msgs/Bool in: true while the hard e-stop is pressed")),
    ("bumper_topic", ("", "topic", "std_msgs/Bool in: true while the front bumper is pressed")),
    ("fall_left_topic", ("", "topic", "std_msgs/Bool in: true while the left fall sensor sees no ground")),
    ("fall_right_topic", ("", "topic", "std_msgs/Bool in: true while the right fall sensor sees no ground")),
    ("charge_relay_service", ("", "topic", "std_srvs/SetBool out: data true closes the charge relay")),
    ("charge_relay_topic", ("", "topic", "std_msgs/Bool out (latched): true closes the charge relay")),
    ("charge_relay_state_topic", ("", "topic", "std_msgs/Bool in: true while the relay is closed")),
    ("odom_timeout", (0.5, "seconds", "odometry older than this stops the robot (fault)")),
    ("battery_timeout", (5.0, "seconds", "BatteryState older than this stops the robot (fault)")),
    ("startup_timeout", (5.0, "seconds", "an input silent this long after start is logged as an error")),
    ("relay_timeout", (1.0, "seconds", "the charge relay service must answer within this")),
    ("battery_critical_percent", (10.0, "percent", "below this: battery_status b0, circuit_status b7")),
])
Settings = namedtuple("Settings", list(SETTINGS))

# The Bool safety inputs: ChassisState field -> (setting, circuit bit while never received).
SAFETY_INPUTS = OrderedDict([
    ("hard_estop", ("estop_topic", 0)),
    ("bumper", ("bumper_topic", CIRCUIT_COLLISION_LINE)),
    ("fall_left", ("fall_left_topic", CIRCUIT_LEFT_TOF_LINE)),
    ("fall_right", ("fall_right_topic", CIRCUIT_RIGHT_TOF_LINE)),
])

# sensor_msgs/BatteryState constants (test_ros_base checks them against the message).
POWER_SUPPLY_STATUS_CHARGING = 1
POWER_SUPPLY_STATUS_DISCHARGING = 2
POWER_SUPPLY_HEALTH_OVERHEAT = 2
POWER_SUPPLY_HEALTH_DEAD = 3
POWER_SUPPLY_HEALTH_OVERVOLTAGE = 4
POWER_SUPPLY_HEALTH_COLD = 6
HEALTH_BITS = {POWER_SUPPLY_HEALTH_OVERHEAT: BATTERY_HIGH_TEMP, POWER_SUPPLY_HEALTH_DEAD: BATTERY_UNDER_VOLTAGE,
               POWER_SUPPLY_HEALTH_OVERVOLTAGE: BATTERY_OVER_VOLTAGE, POWER_SUPPLY_HEALTH_COLD: BATTERY_LOW_TEMP}
STATUS_BITS = {POWER_SUPPLY_STATUS_CHARGING: BATTERY_CHARGING, POWER_SUPPLY_STATUS_DISCHARGING: BATTERY_DISCHARGING}

Battery = namedtuple("Battery", "voltage current percent status_bits temperature_c")
"""V, A (+ = charging), % 0..100 or None (unknown), battery_status bits, degC or None."""


class SettingsError(ValueError):
    """A ~ros_base setting is wrong; the message names it."""


def parse_settings(values):
    """Settings from the ``~ros_base`` dict (missing keys take their default); SettingsError otherwise."""
    if not isinstance(values, dict):
        raise SettingsError("%s must be a dict of settings (%s), got %r" % (PARAM, ", ".join(SETTINGS), values))
    unknown = sorted(set(values) - set(SETTINGS))
    if unknown:
        raise SettingsError("%s: unknown setting(s) %s (known: %s)"
                            % (PARAM, ", ".join(map(str, unknown)), ", ".join(SETTINGS)))
    parsed = {}
    for name, (default, kind, _meaning) in SETTINGS.items():
        value = values.get(name, default)
        where = "%s/%s" % (PARAM, name)
        if kind in ("topic", "required_topic"):
            if not isinstance(value, str) or value != value.strip() or " " in value:
                raise SettingsError("%s must be a ROS name (\"\" = not wired), got %r" % (where, value))
            if kind == "required_topic" and not value:
                raise SettingsError("%s must name a topic: robot_control cannot drive without odometry" % where)
        else:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                    or value <= 0 or (kind == "percent" and value > 100):
                raise SettingsError("%s must be a positive number of %s%s, got %r"
                                    % (where, kind, " (at most 100)" if kind == "percent" else "", value))
            value = float(value)
        parsed[name] = value
    if parsed["charge_relay_service"] and parsed["charge_relay_topic"]:
        raise SettingsError("%s/charge_relay_service and %s/charge_relay_topic are both set: wire the relay "
                            "through one of them" % (PARAM, PARAM))
    return Settings(**parsed)


def battery_from_message(voltage, current, percentage, power_supply_status, power_supply_health, temperature,
                         critical_percent):
    """A Battery from BatteryState fields (percentage 0..1, NaN = unknown; ROS current: + = charging)."""
    def finite(value):
        return float(value) if value is not None and math.isfinite(value) else None
    percent = finite(percentage)
    percent = None if percent is None else max(0.0, min(100.0, percent * 100.0))
    bits = STATUS_BITS.get(power_supply_status, 0) | HEALTH_BITS.get(power_supply_health, 0)
    if percent is not None and percent < critical_percent:
        bits |= BATTERY_UNDER_VOLTAGE
    return Battery(finite(voltage) or 0.0, finite(current) or 0.0, percent, bits, finite(temperature))


Problem = namedtuple("Problem", "setting text")


class BaseInputs(object):
    """What the base's topics last said and when; ``state()`` is the ChassisState it amounts to.

    clock(): monotonic seconds (ages are measured on arrival, so a base with another clock or a
    wrong header stamp still counts as alive while it publishes). Not thread-safe on its own: the
    ROS driver holds one lock around every call.
    """

    def __init__(self, settings, clock):
        self.settings = settings
        self._clock = clock
        self._start = clock()
        self._odom = None        # (arrival, velocity_x, velocity_yaw, roll, pitch, yaw)
        self._battery = None     # (arrival, Battery)
        self._switches = {name: None for name, (setting, _bit) in SAFETY_INPUTS.items()
                          if getattr(settings, setting)}
        self._relay_reported = None
        self._reported = {}      # setting -> text of the problem last logged

    # --- inputs ------------------------------------------------------------------------------
    def on_odometry(self, velocity_x, velocity_yaw, roll=0.0, pitch=0.0, yaw=0.0):
        """Returns False (and keeps the last sample) for a non-finite velocity."""
        if not (math.isfinite(velocity_x) and math.isfinite(velocity_yaw)):
            return False
        self._odom = (self._clock(), float(velocity_x), float(velocity_yaw), roll, pitch, yaw)
        return True

    def on_battery(self, battery):
        self._battery = (self._clock(), battery)

    def on_switch(self, name, active):
        """A Bool safety input; returns True when its value changed (the caller tells robot_control)."""
        changed = self._switches.get(name) != bool(active)
        self._switches[name] = bool(active)
        return changed

    def on_relay_state(self, closed):
        changed = self._relay_reported != bool(closed)
        self._relay_reported = bool(closed)
        return changed

    # --- outputs -----------------------------------------------------------------------------
    def odometry_fresh(self):
        return self._odom is not None and self._clock() - self._odom[0] <= self.settings.odom_timeout

    def battery_fresh(self):
        return self._battery is not None and self._clock() - self._battery[0] <= self.settings.battery_timeout

    def attitude(self):
        """(roll, pitch, yaw) of the last odometry pose, rad (zeros before the first)."""
        return self._odom[3:] if self._odom is not None else (0.0, 0.0, 0.0)

    def relay_reported(self):
        """The relay as charge_relay_state_topic last said (None: not wired or nothing yet)."""
        return self._relay_reported

    def problems(self):
        """Every input that holds the robot stopped now, as Problems (empty: all fresh)."""
        now = self._clock()
        found = []
        s = self.settings

        def check(setting, sample, timeout, what):
            if sample is None:
                found.append(Problem(setting, "no %s received on %r since start %.1f s ago"
                                     % (what, getattr(s, setting), now - self._start)))
            elif now - sample[0] > timeout:
                found.append(Problem(setting, "%s on %r stale: last %.2f s ago (%s/%s %.2f s)"
                                     % (what, getattr(s, setting), now - sample[0], PARAM,
                                        setting.replace("_topic", "_timeout"), timeout)))
        check("odom_topic", self._odom, s.odom_timeout, "nav_msgs/Odometry")
        if s.battery_topic:
            check("battery_topic", self._battery, s.battery_timeout, "sensor_msgs/BatteryState")
        for name, value in self._switches.items():
            if value is None:
                setting = SAFETY_INPUTS[name][0]
                found.append(Problem(setting, "no std_msgs/Bool received on %r since start %.1f s ago"
                                     % (getattr(s, setting), now - self._start)))
        return found

    def reports(self):
        """(new, cleared): problems to log as errors now, and settings whose problem has cleared.

        A problem is reported once when it appears; one that is only "nothing received since start"
        waits for ``startup_timeout`` first, so a normal start-up (base node still coming up) is quiet.
        """
        now = self._clock()
        current = {p.setting: p.text for p in self.problems()}
        starting = now - self._start < self.settings.startup_timeout
        new = []
        for setting, text in current.items():
            if setting in self._reported:
                continue
            if starting and "since start" in text:
                continue
            new.append(Problem(setting, text))
            self._reported[setting] = text
        cleared = [setting for setting in list(self._reported) if setting not in current]
        for setting in cleared:
            del self._reported[setting]
        return new, cleared

    def state(self, wheel_mode, relay_commanded, lamps):
        """The ChassisState: measured velocity, battery, switches and the fault bits of the module docstring.

        wheel_mode: the last commanded one (a differential base has no steering to switch);
        relay_commanded: what robot_control last set (used unless charge_relay_state_topic reports).
        """
        circuit = 0
        battery_bits = 0
        vx = vyaw = 0.0
        if self.odometry_fresh():
            vx, vyaw = self._odom[1], self._odom[2]
        else:
            circuit |= CIRCUIT_STEPPER_COMM
        battery = Battery(0.0, 0.0, None, 0, None)
        if self.settings.battery_topic:
            if self._battery is not None:
                battery = self._battery[1]
            if not self.battery_fresh():
                circuit |= CIRCUIT_STEPPER_COMM
                battery_bits |= BATTERY_LINE_FAULT
        battery_bits |= battery.status_bits
        if battery.percent is not None and battery.percent < self.settings.battery_critical_percent:
            circuit |= CIRCUIT_BATTERY_CRITICAL
        switches = {}
        for name, (_setting, line_bit) in SAFETY_INPUTS.items():
            value = self._switches.get(name, False)
            if value is None:
                circuit |= CIRCUIT_STEPPER_COMM | line_bit
            switches[name] = bool(value)
        temperatures = [None] * TEMPERATURE_COUNT
        temperatures[TEMP_BATTERY] = battery.temperature_c
        relay = relay_commanded if self._relay_reported is None else self._relay_reported
        return ChassisState(
            velocity_x=vx, velocity_yaw=vyaw, wheel_mode=wheel_mode, switching=False,
            charge_relay=bool(relay), lamps=tuple(lamps), battery_voltage=battery.voltage,
            battery_current=battery.current,
            battery_quantity=0 if battery.percent is None else int(round(battery.percent)),
            battery_status=battery_bits, circuit_status=circuit, temperatures_c=tuple(temperatures), **switches)
