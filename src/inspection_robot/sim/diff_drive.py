"""A stand-in for a differential-drive base run by ros_control's diff_drive_controller.

What robot_control's ``~driver: ros`` meets on such a base, modelled after diff_drive_controller:
- a velocity command takes effect ``latency`` s after it arrives (controller update + motor drive);
- it is clamped to ``max_velocity_x`` / ``max_velocity_yaw`` and approached at ``max_accel_x`` /
  ``max_accel_yaw`` (the controller's linear/angular limits);
- ``cmd_timeout`` s after the last command the target drops to zero (``cmd_vel_timeout``),
  decelerating within the same limits;
- odometry integrates the wheel-measured velocity, which reads ``odom_scale_error`` long in
  translation and ``odom_yaw_error`` in rotation (wheel radius / separation calibration drift);
- the hard e-stop cuts motor power: the base stops at ``estop_decel`` and ignores commands;
- the battery drains with an idle load plus a load per m/s, and charges while the charge relay is
  closed (no dock geometry: the relay closed means the charger is connected).

Time advances lazily to ``clock()`` on every public call, so a test can drive it with a fake clock.
Pure: no rospy (nodes/sim_diff_drive.py publishes it).
"""
import collections
import math

from inspection_robot.angles import wrap_angle
from inspection_robot.sim.chassis import battery_voltage

DEFAULTS = dict(
    latency=0.03,             # s, command -> wheels
    max_velocity_x=1.0,       # m/s
    max_velocity_yaw=1.5,     # rad/s
    max_accel_x=1.0,          # m/s^2
    max_accel_yaw=2.0,        # rad/s^2
    estop_decel=3.0,          # m/s^2 (and rad/s^2) with motor power cut
    cmd_timeout=0.5,          # s, diff_drive_controller's cmd_vel_timeout
    odom_scale_error=0.01,    # measured / true translation - 1
    odom_yaw_error=-0.005,    # measured / true rotation - 1
    battery_capacity_ah=40.0,
    battery_soc=80.0,         # % at start
    idle_current=1.5,         # A
    current_per_m_s=12.0,     # A per m/s
    charge_current=10.0,      # A with the relay closed
    battery_time_scale=1.0,   # state of charge moves this many times faster (tests)
)
MAX_STEP = 0.005  # s, integration sub-step
MAX_PENDING = 200  # commands waiting out the latency (at 50 Hz and 30 ms: 2)


def _approach(value, target, max_delta):
    return min(target, value + max_delta) if target > value else max(target, value - max_delta)


class DiffDriveBase(object):
    """clock(): monotonic seconds. ``params``: DEFAULTS' names; an unknown name is refused."""

    def __init__(self, clock, **params):
        unknown = sorted(set(params) - set(DEFAULTS))
        if unknown:
            raise ValueError("unknown diff drive parameter(s) %s (known: %s)"
                             % (", ".join(unknown), ", ".join(DEFAULTS)))
        self.params = dict(DEFAULTS, **{k: float(v) for k, v in params.items()})
        for name in ("max_velocity_x", "max_velocity_yaw", "max_accel_x", "max_accel_yaw", "estop_decel",
                     "cmd_timeout", "battery_capacity_ah", "battery_time_scale"):
            if not self.params[name] > 0:
                raise ValueError("diff drive parameter %s must be positive, got %r" % (name, self.params[name]))
        if not self.params["latency"] >= 0:
            raise ValueError("diff drive parameter latency must be >= 0, got %r" % self.params["latency"])
        self._clock = clock
        self._now = clock()
        self._pending = collections.deque(maxlen=MAX_PENDING)  # (effective time, vx, wz)
        self._target = (0.0, 0.0)
        self._last_cmd = None     # effective time of the last command reaching the wheels
        self._vx = self._wz = 0.0  # true velocities
        self.pose = [0.0, 0.0, 0.0]  # odometry (measured) pose x, y, yaw in the odom frame
        self.true_pose = [0.0, 0.0, 0.0]
        self.estop = False
        self.bumper = False
        self.relay = False
        self._soc = self.params["battery_soc"]

    # --- inputs ------------------------------------------------------------------------------
    def command(self, velocity_x, velocity_yaw):
        """A cmd_vel arriving now; non-finite values are ignored (returns False), as the controller does."""
        if not (math.isfinite(velocity_x) and math.isfinite(velocity_yaw)):
            return False
        self._advance()
        self._pending.append((self._now + self.params["latency"], float(velocity_x), float(velocity_yaw)))
        return True

    def set_estop(self, pressed):
        self._advance()
        self.estop = bool(pressed)

    def set_relay(self, closed):
        self._advance()
        self.relay = bool(closed)

    # --- outputs -----------------------------------------------------------------------------
    def odometry(self):
        """(x, y, yaw, velocity_x, velocity_yaw): measured, odom frame / base frame."""
        self._advance()
        p = self.params
        return (self.pose[0], self.pose[1], self.pose[2], self._vx * (1 + p["odom_scale_error"]),
                self._wz * (1 + p["odom_yaw_error"]))

    def battery(self):
        """(voltage V, current A + = charging, state of charge %, charging)."""
        self._advance()
        current = self._current()
        return battery_voltage(self._soc), current, self._soc, current > 0

    # --- physics -----------------------------------------------------------------------------
    def _current(self):
        p = self.params
        if self.relay:
            return p["charge_current"]
        return -(p["idle_current"] + p["current_per_m_s"] * abs(self._vx))

    def _advance(self):
        now = self._clock()
        while self._now < now:
            dt = min(MAX_STEP, now - self._now)
            self._now += dt
            self._step(dt)

    def _step(self, dt):
        p = self.params
        while self._pending and self._pending[0][0] <= self._now:
            _t, vx, wz = self._pending.popleft()
            self._target = (max(-p["max_velocity_x"], min(p["max_velocity_x"], vx)),
                            max(-p["max_velocity_yaw"], min(p["max_velocity_yaw"], wz)))
            self._last_cmd = self._now
        if self._last_cmd is not None and self._now - self._last_cmd > p["cmd_timeout"]:
            self._target = (0.0, 0.0)
        if self.estop:
            self._vx = _approach(self._vx, 0.0, p["estop_decel"] * dt)
            self._wz = _approach(self._wz, 0.0, p["estop_decel"] * dt)
        else:
            self._vx = _approach(self._vx, self._target[0], p["max_accel_x"] * dt)
            self._wz = _approach(self._wz, self._target[1], p["max_accel_yaw"] * dt)
        for pose, scale_x, scale_yaw in ((self.true_pose, 1.0, 1.0),
                                         (self.pose, 1 + p["odom_scale_error"], 1 + p["odom_yaw_error"])):
            heading = pose[2] + 0.5 * self._wz * scale_yaw * dt
            pose[0] += self._vx * scale_x * dt * math.cos(heading)
            pose[1] += self._vx * scale_x * dt * math.sin(heading)
            pose[2] = wrap_angle(pose[2] + self._wz * scale_yaw * dt)
        self._soc += (self._current() * dt * p["battery_time_scale"] / 3600.0 / p["battery_capacity_ah"]) * 100.0
        self._soc = max(0.0, min(100.0, self._soc))
