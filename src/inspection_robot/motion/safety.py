"""Safety latch: which inputs stop the robot, which switches disable them, what clears them.

Inputs and what clears them (docs/interface.md, "Motion and safety"):
- soft e-stop (control_cmd enable_stop): until ``disable_stop``.
- hard e-stop button: pressing it also engages the soft e-stop, so the robot stays stopped
  after the button is released, until ``disable_stop`` (refused while the button is pressed).
- bumper strip (front collision, anti-collision switch), left/right fall sensors (anti-fall
  switch), obstacle_status=true (obstacle detection switch): stop while the input is active and
  its switch enabled. Clearing the input (or disabling the switch) lifts the refusal, but the
  robot only moves again on a *new* move_cmd (the target is dropped at the stop).
- drive faults (a motor disconnected, a stepper fault, the stepper board's comm alarm): stop
  while present; no switch.
Switches are all enabled at boot.
"""
from inspection_robot.command import CommandError
from inspection_robot.interface import (
    CIRCUIT_STEPPER_COMM, LIGHT_BUMPER, LIGHT_HARD_ESTOP, LIGHT_SOFT_ESTOP, SERVO_DISCONNECTED, SERVO_FAULT,
    STEPPER_ERROR, STOP_FRONT_COLLISION, STOP_LEFT_FALL, STOP_OBSTACLE, STOP_RIGHT_FALL, WHEEL_COLLISION_OFF,
    WHEEL_FALL_OFF, WHEEL_OBSTACLE_OFF)

SWITCHES = ("collision", "fallen", "obstacle")  # the control_cmd names: enable_/disable_/switch_<name>
SWITCH_OFF_BITS = {"collision": WHEEL_COLLISION_OFF, "fallen": WHEEL_FALL_OFF, "obstacle": WHEEL_OBSTACLE_OFF}
SERVO_COUNT = 4


class SafetyLatch(object):
    def __init__(self):
        self.enabled = {name: True for name in SWITCHES}
        self.soft_estop = False
        self.hard_estop = False
        self.bumper = False
        self.fall_left = False
        self.fall_right = False
        self.obstacle = False
        self.drive_fault = False

    # --- inputs ------------------------------------------------------------------------------
    def update_chassis(self, state):
        """Take the chassis' safety inputs from a ChassisState."""
        self.hard_estop = bool(state.hard_estop)
        if self.hard_estop:
            self.soft_estop = True
        self.bumper = bool(state.bumper)
        self.fall_left = bool(state.fall_left)
        self.fall_right = bool(state.fall_right)
        servo_bad = any(s & (SERVO_DISCONNECTED | SERVO_FAULT) for s in state.motor_status[:SERVO_COUNT])
        stepper_bad = any(s & STEPPER_ERROR for s in state.motor_status[SERVO_COUNT:])
        self.drive_fault = bool(servo_bad or stepper_bad or state.circuit_status & CIRCUIT_STEPPER_COMM)

    def set_obstacle(self, present):
        self.obstacle = bool(present)

    # --- control_cmd -------------------------------------------------------------------------
    def set_switch(self, name, enabled=None):
        """Enable (True), disable (False) or toggle (None) a switch; returns the new state."""
        if name not in self.enabled:
            raise CommandError("unknown switch '%s'" % (name,))
        self.enabled[name] = (not self.enabled[name]) if enabled is None else bool(enabled)
        return self.enabled[name]

    def enable_stop(self):
        self.soft_estop = True

    def disable_stop(self):
        if self.hard_estop:
            raise CommandError("hard e-stop still pressed: release the button first")
        self.soft_estop = False

    # --- outputs -----------------------------------------------------------------------------
    def reasons(self):
        """Names of the active stop reasons (empty = motion allowed)."""
        active = []
        if self.soft_estop:
            active.append("soft_estop")
        if self.hard_estop:
            active.append("hard_estop")
        if self.bumper and self.enabled["collision"]:
            active.append("front_collision")
        if self.fall_left and self.enabled["fallen"]:
            active.append("left_fall")
        if self.fall_right and self.enabled["fallen"]:
            active.append("right_fall")
        if self.obstacle and self.enabled["obstacle"]:
            active.append("obstacle")
        if self.drive_fault:
            active.append("drive_fault")
        return active

    def blocks(self):
        return bool(self.reasons())

    def stop_status(self):
        bits = 0
        if self.bumper and self.enabled["collision"]:
            bits |= STOP_FRONT_COLLISION
        if self.obstacle and self.enabled["obstacle"]:
            bits |= STOP_OBSTACLE
        if self.fall_left and self.enabled["fallen"]:
            bits |= STOP_LEFT_FALL
        if self.fall_right and self.enabled["fallen"]:
            bits |= STOP_RIGHT_FALL
        return bits

    def light_bits(self):
        """light_status b4-b6 (the lamp and relay bits come from the chassis)."""
        return ((LIGHT_SOFT_ESTOP if self.soft_estop else 0) | (LIGHT_HARD_ESTOP if self.hard_estop else 0)
                | (LIGHT_BUMPER if self.bumper else 0))

    def wheel_off_bits(self):
        """wheel_status b5-b7: set when a switch is OFF."""
        bits = 0
        for name, bit in SWITCH_OFF_BITS.items():
            if not self.enabled[name]:
                bits |= bit
        return bits
