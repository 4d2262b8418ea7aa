"""Mode arbitration (INTERFACE.md section 4, "Mode and motion"): who holds the robot, who may move it.

Priority joystick (mode 2) > backend (mode 1) > task (mode 0); the robot boots in task mode.
- ``acquire joy`` is accepted only from ``joy_control``, ``acquire server`` only from ``server``.
  An acquire of a mode with lower priority than the current one is refused (the mode stays);
  acquiring the mode one already holds succeeds without change; a higher-priority acquire
  pre-empts the holder.
- ``release`` is accepted only from the current holder's sender and always returns to task mode
  (a pre-empted backend does not get the robot back: it must acquire again).
- Only the holder's sender moves the robot: ``move_base`` in mode 0, ``server`` in 1,
  ``joy_control`` in 2 (interface.MOVE_SENDER_BY_MODE).

Every refusal's reason starts with one of REFUSALS and a colon, so a backend reading mode_ack can
tell why without parsing prose: ``busy`` (a mode of higher priority holds the robot: the joystick),
``offline`` (the backend is offline), ``not_allowed`` (this sender may not take or give back that
mode), ``not_held`` (nothing to release, or the named mode is not the current one), ``bad_request``
(unknown cmd or data).
"""
from collections import namedtuple

from inspection_robot.command import echoed
from inspection_robot.interface import (BUSY, MODE_BY_ACQUIRE_DATA, MODE_CMD_ACQUIRE, MODE_CMD_RELEASE, MODE_NAMES,
                                        MODE_TASK, MOVE_SENDER_BY_MODE)

Decision = namedtuple("Decision", "accepted changed reason")

REFUSAL_BUSY = BUSY
REFUSAL_OFFLINE = "offline"
REFUSAL_NOT_ALLOWED = "not_allowed"
REFUSAL_NOT_HELD = "not_held"
REFUSAL_BAD_REQUEST = "bad_request"
REFUSALS = (REFUSAL_BUSY, REFUSAL_OFFLINE, REFUSAL_NOT_ALLOWED, REFUSAL_NOT_HELD, REFUSAL_BAD_REQUEST)


def refused(code, text):
    """A refusal Decision whose reason is ``"<code>: <text>"`` (code one of REFUSALS)."""
    return Decision(False, False, "%s: %s" % (code, text))


class ModeArbiter(object):
    def __init__(self):
        self.mode = MODE_TASK

    def holder(self):
        """The sender whose move_cmd moves the robot in the current mode."""
        return MOVE_SENDER_BY_MODE[self.mode]

    def may_move(self, sender):
        return sender == self.holder()

    def request(self, sender, cmd, data):
        """Apply a mode_cmd; return a Decision (accepted, changed, reason for the log)."""
        if cmd == MODE_CMD_ACQUIRE:
            return self._acquire(sender, data)
        if cmd == MODE_CMD_RELEASE:
            return self._release(sender, data)
        return refused(REFUSAL_BAD_REQUEST, "unknown mode_cmd '%s' (acquire|release)" % (echoed(cmd),))

    def force_task(self):
        """Return to task mode whatever the holder (backend offline, joystick link lost)."""
        changed = self.mode != MODE_TASK
        self.mode = MODE_TASK
        return changed

    def _acquire(self, sender, data):
        wanted = MODE_BY_ACQUIRE_DATA.get(data)
        if wanted is None:
            return refused(REFUSAL_BAD_REQUEST, "acquire data must be joy|server, got '%s'" % (echoed(data),))
        if sender != MOVE_SENDER_BY_MODE[wanted]:
            return refused(REFUSAL_NOT_ALLOWED, "sender '%s' may not acquire %s (only %s)"
                           % (echoed(sender), data, MOVE_SENDER_BY_MODE[wanted]))
        if wanted == self.mode:
            return Decision(True, False, "already in %s mode" % data)
        if wanted < self.mode:  # mode numbers are the priorities
            return refused(REFUSAL_BUSY, "acquire %s refused: %s mode has priority"
                           % (data, MODE_NAMES[self.mode]))
        self.mode = wanted
        return Decision(True, True, "%s acquired %s mode" % (sender, data))

    def _release(self, sender, data):
        if data and data not in MODE_BY_ACQUIRE_DATA:
            return refused(REFUSAL_BAD_REQUEST, "release data must be empty, joy or server, got '%s'"
                           % (echoed(data),))
        if self.mode == MODE_TASK:
            return refused(REFUSAL_NOT_HELD, "release refused: already in task mode")
        if data and MODE_BY_ACQUIRE_DATA[data] != self.mode:
            return refused(REFUSAL_NOT_HELD, "release %s refused: mode is %s" % (data, MODE_NAMES[self.mode]))
        if sender != self.holder():
            return refused(REFUSAL_NOT_ALLOWED, "release refused: '%s' does not hold %s mode"
                           % (echoed(sender), MODE_NAMES[self.mode]))
        self.mode = MODE_TASK
        return Decision(True, True, "%s released; task mode" % sender)
