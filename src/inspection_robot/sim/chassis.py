"""Simulated chassis: the reference implementation of motion.chassis.ChassisDriver.

Behaves like the motion board of a four-wheel-steering inspection robot:
- Kinematics: in straight mode (wheel_control 0) the front and rear wheels steer in opposite
  directions, so the yaw rate is limited to ``|velocity_x| / min_turn_radius``; in steer mode
  (wheel_control 1) the wheels point tangentially and the robot spins in place (velocity_x 0).
- Acceleration limits on both axes; ``stop()`` brakes at ``brake_decel``.
- The straight/steer switch first brings the robot to rest, then turns the wheels for
  ``switch_time`` seconds (``switching`` True, wheel_status b2) and only then follows commands.
- Battery: drains with an idle load plus loads proportional to speed and to yaw rate; charges
  only with the charge relay closed while the robot stands on the dock (its true pose within the
  dock's tolerances, see charge.dock; or the ``at_dock`` condition forced) and the dock has power
  (condition ``charger_off`` cleared). ``battery_time_scale`` multiplies how fast the state of
  charge moves (currents stay physical), so tests see a drain and a charge in seconds. Voltage
  follows the state of charge.
- Temperatures: first-order towards ambient plus a load term (servos, steppers, battery).
- Wheel encoders report the true velocity scaled by ``1 + encoder_scale_error`` (odometry drift).
- IMU: yaw integrates the true yaw rate plus a gyro bias that ``imu_calibrate`` removes.
- Ground truth: the pose in the map frame, from the configured start pose.
- Faults (``FAULTS``) are injected with :meth:`inject`; the node exposes them as the
  ``sim/inject_fault`` service (cmd = fault name, data = 1|0). A hard e-stop also cuts motor
  power on the board itself, as real hardware does.

Time advances lazily: every public call integrates the physics up to ``clock()``, so the
simulator needs no thread and a test can drive it with a fake clock.
"""
import math

from inspection_robot.angles import wrap_angle
from inspection_robot.charge.dock import is_docked, parse_dock
from inspection_robot.command import CommandError, CommandTable, parse_choice, parse_float, split_fields
from inspection_robot.interface import (
    BATTERY_CHARGING, BATTERY_DISCHARGING, BATTERY_UNDER_VOLTAGE, CIRCUIT_BATTERY_CRITICAL,
    CIRCUIT_JOY_COMM_LOST, CIRCUIT_STEPPER_COMM, MOTOR_COUNT, MOTOR_INFO_DISCONNECTED,
    SERVO_DISCONNECTED, TEMP_BATTERY, TEMP_IPC, TEMP_MOTION_CARD, TEMP_POD_INSIDE, TEMP_POD_OUTSIDE,
    TEMP_SERVO_LF, TEMP_STEPPER_LF, TEMPERATURE_COUNT, WHEEL_STEER, WHEEL_STRAIGHT)
from inspection_robot.motion.chassis import ChassisDriver, ChassisError, ChassisState, ImuReading

# Injectable faults (sim/inject_fault cmd names). data 1 = fault present, 0 = cleared.
FAULTS = ("hard_estop", "bumper", "fall_left", "fall_right", "motor_disconnect", "joystick_link_lost",
          "stepper_comm", "low_battery")
# World conditions settable through the same service: at_dock forces "on the dock" wherever the
# robot is; charger_off cuts the dock's power (relay closed, docked, yet no charging current).
CONDITIONS = ("at_dock", "charger_off")
SAFETY_FAULTS = frozenset(FAULTS)  # every fault changes a safety-relevant state

DEFAULTS = dict(
    max_accel_x=0.8,          # m/s^2
    max_accel_yaw=1.5,        # rad/s^2
    brake_decel=3.0,          # m/s^2 (and rad/s^2) after stop()
    min_turn_radius=0.6,      # m, straight mode
    switch_time=1.0,          # s, straight <-> steer
    encoder_scale_error=0.01,  # measured / true - 1
    gyro_bias=0.002,          # rad/s until calibrated
    battery_capacity_ah=40.0,
    battery_soc=90.0,         # % at start
    idle_current=1.5,         # A
    current_per_m_s=12.0,     # A per m/s
    current_per_rad_s=6.0,    # A per rad/s
    charge_current=10.0,      # A at a dock with the relay closed
    battery_time_scale=1.0,   # state of charge moves this many times faster than real (tests)
    low_battery_soc=8.0,      # % the low_battery fault drops the charge to
    critical_soc=10.0,        # % below which circuit_status b7 is set
    under_voltage=46.0,       # V below which battery_status b0 is set
    ambient_c=25.0,
)
MAX_STEP = 0.01  # s, physics sub-step


def _approach(value, target, max_delta):
    if target > value:
        return min(target, value + max_delta)
    return max(target, value - max_delta)


def battery_voltage(soc):
    """Open-circuit voltage of the 48 V pack (13S Li-ion) at ``soc`` %."""
    return 42.0 + 12.6 * max(0.0, min(100.0, soc)) / 100.0


class SimChassis(ChassisDriver):
    """``dock`` (a charge.dock.Dock or None): where the robot charges; without one only the
    ``at_dock`` condition lets it charge."""

    def __init__(self, clock, start_pose=(0.0, 0.0, 0.0), dock=None, **params):
        unknown = set(params) - set(DEFAULTS)
        if unknown:
            raise ValueError("unknown simulator parameters: %s" % ", ".join(sorted(unknown)))
        self.params = dict(DEFAULTS)
        self.params.update({k: float(v) for k, v in params.items()})
        if self.params["battery_time_scale"] <= 0:
            raise ValueError("battery_time_scale must be positive")
        self.dock = dock
        self._clock = clock
        self._last = clock()
        self._listener = None
        self._command_listeners = []
        self.pose = [float(v) for v in start_pose]  # x, y, yaw in the map frame (ground truth)
        self._vx = 0.0
        self._wz = 0.0
        self._target = (0.0, 0.0)
        self._braking = False
        self._wheel_mode = WHEEL_STRAIGHT
        self._wanted_mode = WHEEL_STRAIGHT
        self._switch_left = None  # s of steering switch remaining, None = not switching
        self._soc = self.params["battery_soc"]
        self._soc_before_low = None
        self._current = 0.0
        ambient = self.params["ambient_c"]
        self._temps = [ambient] * TEMPERATURE_COUNT
        self._temps[TEMP_IPC] = ambient + 20.0
        self._temps[TEMP_MOTION_CARD] = ambient + 15.0
        self._temps[TEMP_POD_INSIDE] = ambient + 5.0
        self._charge_relay = False
        self._lamps = (False, False, False)
        self.faults = {name: False for name in FAULTS}
        self.conditions = {name: False for name in CONDITIONS}
        self._imu_yaw = 0.0
        self._imu_bias = self.params["gyro_bias"]
        self._imu_calibrated = False

    # --- ChassisDriver ------------------------------------------------------------------------
    def set_safety_listener(self, listener):
        self._listener = listener

    def add_command_listener(self, listener):
        """``listener(velocity_x, velocity_yaw, wheel_mode)`` on every command (sim/chassis_cmd)."""
        self._command_listeners.append(listener)

    def send_velocity(self, velocity_x, velocity_yaw, wheel_mode):
        self._advance()
        if wheel_mode not in (WHEEL_STRAIGHT, WHEEL_STEER):
            raise ChassisError("wheel_mode must be 0 or 1, got %r" % (wheel_mode,))
        if not (math.isfinite(velocity_x) and math.isfinite(velocity_yaw)):
            raise ChassisError("non-finite velocity")
        self._wanted_mode = wheel_mode
        self._target = (0.0 if wheel_mode == WHEEL_STEER else float(velocity_x), float(velocity_yaw))
        self._braking = self._target == (0.0, 0.0) and self._braking
        self._notify_command(self._target[0], self._target[1], wheel_mode)

    def stop(self):
        self._advance()
        self._target = (0.0, 0.0)
        self._braking = True
        self._notify_command(0.0, 0.0, self._wanted_mode)

    def state(self):
        self._advance()
        scale = 1.0 + self.params["encoder_scale_error"]
        motor_status = [0] * MOTOR_COUNT
        motor_info = [0] * MOTOR_COUNT
        if self.faults["motor_disconnect"]:
            motor_status[0] |= SERVO_DISCONNECTED
            motor_info[0] |= MOTOR_INFO_DISCONNECTED
        circuit = 0
        if self.faults["joystick_link_lost"]:
            circuit |= CIRCUIT_JOY_COMM_LOST
        if self.faults["stepper_comm"]:
            circuit |= CIRCUIT_STEPPER_COMM
        if self._soc < self.params["critical_soc"]:
            circuit |= CIRCUIT_BATTERY_CRITICAL
        voltage = self._voltage()
        battery = 0
        if voltage < self.params["under_voltage"]:
            battery |= BATTERY_UNDER_VOLTAGE
        if self._current > 0.05:
            battery |= BATTERY_CHARGING
        elif self._current < -0.05:
            battery |= BATTERY_DISCHARGING
        return ChassisState(
            velocity_x=self._vx * scale, velocity_yaw=self._wz * scale,
            wheel_mode=self._wheel_mode, switching=self._switch_left is not None,
            hard_estop=self.faults["hard_estop"], bumper=self.faults["bumper"],
            fall_left=self.faults["fall_left"], fall_right=self.faults["fall_right"],
            charge_relay=self._charge_relay, lamps=self._lamps,
            battery_voltage=voltage, battery_current=self._current, battery_quantity=int(round(self._soc)),
            battery_status=battery, circuit_status=circuit,
            motor_status=tuple(motor_status), motor_info=tuple(motor_info),
            temperatures_c=tuple(self._temps), fault_clear=0)

    def set_charge_relay(self, closed):
        self._advance()
        self._charge_relay = bool(closed)

    def set_lamps(self, red, green, blue):
        self._lamps = (bool(red), bool(green), bool(blue))

    def imu_calibrate(self):
        self._advance()
        if abs(self._vx) > 1e-3 or abs(self._wz) > 1e-3:
            raise ChassisError("robot moving: IMU calibration needs the robot at rest")
        self._imu_bias = 0.0
        self._imu_calibrated = True

    def imu_reset(self):
        self._advance()
        self._imu_yaw = 0.0

    def imu_reading(self):
        self._advance()
        return ImuReading(0.0, 0.0, wrap_angle(self._imu_yaw),
                          self._imu_calibrated)

    def close(self):
        self.stop()

    # --- simulator ----------------------------------------------------------------------------
    @classmethod
    def from_world(cls, clock, world, **params):
        """The chassis of the simulated yard ``world`` (the ``world`` mapping of config/sim_world.yaml):
        it starts at world.robot.start_pose and charges on world.dock (optional)."""
        start_pose = [float(v) for v in world.get("robot", {}).get("start_pose", [0.0, 0.0, 0.0])]
        if len(start_pose) != 3:
            raise ValueError("world.robot.start_pose must be [x, y, yaw]")
        dock = parse_dock(world["dock"]) if "dock" in world else None
        return cls(clock, start_pose, dock, **params)

    def docked(self):
        """True when the charge contacts touch: on the dock within tolerance, or ``at_dock`` forced."""
        self._advance()
        return self._docked()

    def true_pose(self):
        """(x, y, yaw) in the map frame, and the true (velocity_x, velocity_yaw)."""
        self._advance()
        return tuple(self.pose), (self._vx, self._wz)

    def inject(self, name, active):
        """Set fault or world condition ``name``; notifies the safety listener for faults."""
        self._advance()
        active = bool(active)
        if name in self.conditions:
            self.conditions[name] = active
            return
        if name not in self.faults:
            raise KeyError(name)
        if name == "low_battery" and active != self.faults[name]:
            if active:
                self._soc_before_low, self._soc = self._soc, min(self._soc, self.params["low_battery_soc"])
            elif self._soc_before_low is not None:
                self._soc = max(self._soc, self._soc_before_low)
        self.faults[name] = active
        if name == "hard_estop" and active:
            self._target = (0.0, 0.0)
            self._braking = True
        if self._listener is not None:
            self._listener()

    def fault_table(self):
        """CommandTable of the sim/inject_fault service: one command per fault/condition + query."""
        table = CommandTable()
        for name in FAULTS + CONDITIONS:
            table.register(name, self._fault_handler(name))
        table.register("query", lambda _data: ",".join(
            sorted(n for n, on in list(self.faults.items()) + list(self.conditions.items()) if on)))
        table.register("set_pose", self._set_pose)
        table.register("set_soc", self._set_soc)
        return table

    def _fault_handler(self, name):
        def handler(data):
            self.inject(name, parse_choice(data, name, ("0", "1")) == "1")
            return "%s=%s" % (name, data)
        return handler

    def _set_pose(self, data):
        x, y, yaw = (parse_float(f, n) for f, n in zip(split_fields(data, 3), ("x", "y", "yaw")))
        if abs(self._vx) > 1e-3 or abs(self._wz) > 1e-3:
            raise CommandError("robot moving")
        self.pose = [x, y, yaw]
        return data

    def _set_soc(self, data):
        """Set the state of charge (%, 0-100): tests start a charge scenario without waiting."""
        self._advance()
        self._soc = parse_float(data, "state of charge", 0.0, 100.0)
        self._soc_before_low = None
        return data

    def _docked(self):
        return self.conditions["at_dock"] or (self.dock is not None and is_docked(self.dock, self.pose))

    def _notify_command(self, velocity_x, velocity_yaw, wheel_mode):
        for listener in self._command_listeners:
            listener(velocity_x, velocity_yaw, wheel_mode)

    def _voltage(self):
        return battery_voltage(self._soc) + 0.02 * self._current

    def _advance(self):
        now = self._clock()
        dt_total = now - self._last
        self._last = now
        while dt_total > 1e-9:
            dt = min(MAX_STEP, dt_total)
            dt_total -= dt
            self._step(dt)

    def _step(self, dt):
        p = self.params
        target_x, target_yaw = self._target
        powered = not self.faults["hard_estop"]
        if not powered:
            target_x, target_yaw = 0.0, 0.0
        if self._wanted_mode != self._wheel_mode or self._switch_left is not None:
            target_x, target_yaw = 0.0, 0.0
            at_rest = abs(self._vx) < 1e-6 and abs(self._wz) < 1e-6
            if self._switch_left is None and at_rest and powered:
                self._switch_left = p["switch_time"]
        if self._wheel_mode == WHEEL_STRAIGHT:
            limit = abs(target_x) / p["min_turn_radius"]
            target_yaw = max(-limit, min(limit, target_yaw))
        else:
            target_x = 0.0
        braking = self._braking or not powered
        accel_x = p["brake_decel"] if braking else p["max_accel_x"]
        accel_yaw = p["brake_decel"] if braking else p["max_accel_yaw"]
        vx_before, wz_before = self._vx, self._wz
        self._vx = _approach(self._vx, target_x, accel_x * dt)
        self._wz = _approach(self._wz, target_yaw, accel_yaw * dt)
        vx_mean, wz_mean = 0.5 * (vx_before + self._vx), 0.5 * (wz_before + self._wz)
        if self._switch_left is not None and powered:
            self._switch_left -= dt
            if self._switch_left <= 0.0:
                self._switch_left = None
                self._wheel_mode = self._wanted_mode
        # ground truth (midpoint heading)
        yaw_mid = self.pose[2] + 0.5 * wz_mean * dt
        self.pose[0] += vx_mean * math.cos(yaw_mid) * dt
        self.pose[1] += vx_mean * math.sin(yaw_mid) * dt
        yaw = self.pose[2] + wz_mean * dt
        self.pose[2] = wrap_angle(yaw)
        self._imu_yaw += (wz_mean + self._imu_bias) * dt
        self._update_power(dt)
        self._update_temperatures(dt)

    def _update_power(self, dt):
        p = self.params
        load = p["idle_current"] + p["current_per_m_s"] * abs(self._vx) + p["current_per_rad_s"] * abs(self._wz)
        charging = self._charge_relay and not self.conditions["charger_off"] and self._docked()
        self._current = (p["charge_current"] if charging else 0.0) - load
        self._soc += 100.0 * self._current * dt * p["battery_time_scale"] / 3600.0 / p["battery_capacity_ah"]
        self._soc = max(0.0, min(100.0, self._soc))

    def _update_temperatures(self, dt):
        ambient = self.params["ambient_c"]
        tau = 300.0  # s, thermal time constant
        motor_rise = 15.0 * abs(self._vx) + 8.0 * abs(self._wz)
        targets = list(self._temps)
        targets[TEMP_BATTERY] = ambient + 0.3 * abs(self._current)
        for i in range(4):
            targets[TEMP_SERVO_LF + i] = ambient + motor_rise
            targets[TEMP_STEPPER_LF + i] = ambient + 0.5 * motor_rise + (5.0 if self._switch_left is not None else 0.0)
        targets[TEMP_POD_OUTSIDE] = ambient
        for i in (TEMP_BATTERY, TEMP_POD_OUTSIDE) + tuple(range(TEMP_SERVO_LF, TEMP_STEPPER_LF + 4)):
            self._temps[i] += (targets[i] - self._temps[i]) * min(1.0, dt / tau)
