"""The chassis driver interface: what robot_control needs from a motion-control board.

No wire protocol of the motion board is specified, so this module is the contract a vendor
implements (``inspection_robot.sim.chassis.SimChassis`` is the reference implementation).
robot_control loads a driver with ``~driver: sim``, ``~driver: ros`` (any base with a ROS driver:
``motion/ros_chassis.py`` over the pure ``motion/base_inputs.py``) or ``~driver: package.module:ClassName``;
the class is constructed as ``ClassName(**driver_params)`` from ``~driver_params``.

Threading: robot_control calls a driver from several threads (subscriber callbacks apply
safety stops at once, the control timer sends the target every cycle) but always under one
lock, so a driver needs no locking of its own for calls *into* it. A driver that reads the
board on its own thread reports safety inputs through the ``safety_listener`` callback; it
must not call back into the driver from there (robot_control will, under its lock).

Units are SI (m/s, rad/s, V, A, degC) in this interface; robot_control converts to the
spec's status units (0.1 V, 0.1 A, 0.1 degC) when it assembles control_status.
"""
from collections import namedtuple

from inspection_robot.drivers import not_fitted_class
from inspection_robot.interface import MOTOR_COUNT, TEMPERATURE_COUNT, WHEEL_STRAIGHT

_STATE_FIELDS = (
    "velocity_x",        # m/s, measured (wheel encoders), forward +
    "velocity_yaw",      # rad/s, measured, counter-clockwise +
    "wheel_mode",        # WHEEL_STRAIGHT (0) or WHEEL_STEER (1): the geometry the wheels are in
    "switching",         # True while the steering is moving between modes (no motion meanwhile)
    "hard_estop",        # True while the hard e-stop button is pressed
    "bumper",            # True while the front bumper strip is pressed (collision)
    "fall_left",         # True while the left fall (cliff) sensor sees no ground
    "fall_right",        # True while the right fall sensor sees no ground
    "charge_relay",      # True while the charge relay is closed
    "lamps",             # (red, green, blue) booleans
    "battery_voltage",   # V
    "battery_current",   # A, positive = charging, negative = discharging
    "battery_quantity",  # state of charge, %, 0..100
    "battery_status",    # spec battery_status bits (BATTERY_*)
    "circuit_status",    # spec circuit_status bits (CIRCUIT_*): board, joystick, sensor lines
    "motor_status",      # 8 ints, spec motor_status bits, order interface.MOTOR_NAMES
    "motor_info",        # 8 ints, spec motor_info bits
    "temperatures_c",    # 13 floats, degC, None = not sampled, order of the spec's temperature[]
    "fault_clear",       # spec wheel_status bits b3/b4 (stepper/servo fault cleared) the board reports
)

ChassisState = namedtuple("ChassisState", _STATE_FIELDS)
ChassisState.__new__.__defaults__ = (
    0.0, 0.0, WHEEL_STRAIGHT, False, False, False, False, False, False, (False, False, False),
    0.0, 0.0, 0, 0, 0, (0,) * MOTOR_COUNT, (0,) * MOTOR_COUNT, (None,) * TEMPERATURE_COUNT, 0)

ImuReading = namedtuple("ImuReading", "roll pitch yaw calibrated")
"""Attitude in radians (ROS conventions: roll right-down +, pitch nose-down +, yaw CCW +)."""


class ChassisError(Exception):
    """The board refused or could not carry out a request; the message says why."""


class ChassisDriver(object):
    """Abstract motion board. Subclass and implement every method; see the module docstring.

    Requirements a vendor implementation must meet:
    - ``send_velocity`` is called every control cycle (default 50 Hz) with the current target;
      the board must stop by itself if it is not called for ~0.2 s (hardware watchdog), so a
      hung robot_control never leaves the robot driving.
    - ``stop`` must take effect at once (no acceleration ramp beyond the board's emergency
      deceleration) and must not block for longer than a few milliseconds.
    - ``state`` returns the latest values the board reported; it must not block on I/O
      (poll the board on a thread of the driver and cache).
    """

    def set_safety_listener(self, listener):
        """Register ``listener()``, called (from any thread) when a safety input changes:
        hard e-stop, bumper, fall sensors, motor disconnection, joystick link, battery critical.
        robot_control then reads ``state()`` and stops at once if needed."""
        raise NotImplementedError

    def send_velocity(self, velocity_x, velocity_yaw, wheel_mode):
        """Drive at ``velocity_x`` m/s and ``velocity_yaw`` rad/s in ``wheel_mode``.

        Values are already validated and clamped by robot_control. In WHEEL_STEER (spin in
        place) velocity_x is 0. A wheel_mode different from the current one starts the
        straight/steer switch: the board brings the robot to rest, turns the wheels (state
        ``switching`` True meanwhile) and only then follows the velocity.
        """
        raise NotImplementedError

    def stop(self):
        """Zero velocity now (safety stop)."""
        raise NotImplementedError

    def state(self):
        """The latest ChassisState."""
        raise NotImplementedError

    def set_charge_relay(self, closed):
        raise NotImplementedError

    def set_lamps(self, red, green, blue):
        raise NotImplementedError

    def imu_calibrate(self):
        """Start an IMU calibration (robot at rest); raise ChassisError if refused."""
        raise NotImplementedError

    def imu_reset(self):
        """Reset the IMU's attitude estimate (yaw back to 0)."""
        raise NotImplementedError

    def imu_reading(self):
        """The latest ImuReading."""
        raise NotImplementedError

    def close(self):
        """Stop and release the link to the board."""
        raise NotImplementedError


def _no_chassis_velocity(self, velocity_x, velocity_yaw, wheel_mode):
    if velocity_x or velocity_yaw:
        raise ChassisError(self.reason)


NoChassis = not_fitted_class(
    ChassisDriver, ChassisError, "chassis", set_safety_listener=lambda self, listener: None,
    send_velocity=_no_chassis_velocity, stop=lambda self: None, state=lambda self: ChassisState(),
    set_lamps=lambda self, red, green, blue: None)
"""``~driver: none``: a control cycle's zero velocity, every stop and the lamps (none to light: the
control cycle sets them) pass, anything else fails."""
