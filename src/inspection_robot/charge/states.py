"""The words of a charge cycle: charge_control's states and triggers, the timings of its retries, each
failure kind with its alarm text and voice clip (docs/interface.md, "Charging (charge_control)").

Apart from machine.py so that the vocabulary reads on its own, in the order of a cycle: the voice
catalogue must hold every clip (voice/phrases.py), docs/interface.md quotes the timings, the tests
drive the machine through the states. No rospy.
"""
from inspection_robot.task.states import ENDED_STATES as TASK_ENDED_STATES, STATE_IDLE as TASK_IDLE, \
    STATE_PAUSED as TASK_PAUSED

IDLE = "idle"
PAUSING = "pausing_task"
TO_APPROACH = "to_approach"
DOCKING = "docking"
RELAY_ON = "relay_on"
WAIT_CURRENT = "wait_current"
CHARGING = "charging"
RELAY_OFF = "relay_off"
BACKING_OFF = "backing_off"
RESUMING = "resuming_task"
FAILED = "failed"
STATES = (IDLE, PAUSING, TO_APPROACH, DOCKING, RELAY_ON, WAIT_CURRENT, CHARGING, RELAY_OFF, BACKING_OFF,
          RESUMING, FAILED)
DRIVE_STATES = (TO_APPROACH, DOCKING, BACKING_OFF)
DRIVE_FAILURES = {TO_APPROACH: "approach", DOCKING: "dock", BACKING_OFF: "backoff"}  # state -> failure kind

TRIGGER_LOW_BATTERY = "low_battery"
TRIGGER_MANUAL = "manual"
TRIGGER_RECOVERED = "recovered"  # found on the dock with the relay closed (e.g. after a restart)

# task_manager's task_status states in which the patrol sends no goal (charge_control may drive)
TASK_QUIET_STATES = (TASK_PAUSED, TASK_IDLE) + TASK_ENDED_STATES
TASK_HOLD = "charge"  # data of task_control pause/resume
PAUSE_RETRY_S = 1.0   # s between pause requests to a task_manager that does not answer (e.g. respawning)
GOAL_RETRY_S = 3.0    # s before a failed move_action goal is sent again
SERVER_RETRY_S = 1.0  # s between goals while move_action's server is not up (move_base starting or respawning)
SERVER_TIMEOUT_S = 60.0  # s a drive state waits for that server before it counts as a failed goal

# failure kind -> (voice clip, reason format); the reason is the alarm text (docs/interface.md)
FAILURES = {
    "pause": ("charge_task_not_paused", "task_manager did not pause: %s"),
    "approach": ("charge_dock_unreachable", "dock unreachable: approach goal failed: %s"),
    "dock": ("charge_dock_unreachable", "dock unreachable: docking goal failed: %s"),
    "relay_on": ("charge_relay_not_confirmed", "relay not confirmed: %s"),
    "current": ("charge_no_current", "no charging current: %s"),
    "relay_off": ("charge_relay_not_released", "relay not released: %s"),
    "backoff": ("charge_backoff_failed", "back-off failed: %s"),
    "resume": ("charge_task_not_resumed", "task_manager did not resume: %s"),
}
VOICE_ALARM = "charge_alarm"
VOICE_LOW_BATTERY = "charge_battery_low"
VOICE_GOING_TO_DOCK = "charge_going_to_dock"
VOICE_CHARGED = "charge_done"
VOICE_CLIPS = (VOICE_ALARM, VOICE_LOW_BATTERY, VOICE_GOING_TO_DOCK, VOICE_CHARGED) + tuple(
    sorted(set(clip for clip, _ in FAILURES.values())))
