"""charge_control's docking state machine: when to charge, the docking sequence, retries and alarms.

No rospy: the node feeds it robot_status (``on_battery``), task_status (``on_task_status``), the
replies of task_control (``on_task_reply``) and move_action (``on_move_result``), and calls
``tick()`` periodically; the machine acts only through its ``ports`` (see ports.ChargePorts),
which never call back into it synchronously. Time comes from an injected ``clock`` (seconds), so
unit tests drive every timeout with a fake clock.

One charge cycle (docs/interface.md, "Charging (charge_control)")::

    idle --low battery | dock--> pausing_task --paused/idle (or no task_manager)-->
    to_approach --goal ok--> docking (precision 1) --goal ok--> relay_on --light b0-->
    wait_current --battery b4--> charging --level >= full--> relay_off --light b0 clear-->
    backing_off (backward to the approach pose) --goal ok--> resuming_task --> idle

A failure is retried ``retries`` times (each kind counted separately within a cycle; a failed
goal is sent again only GOAL_RETRY_S later, so a transient fault cannot use up every retry at
once; a move_action server that is not up yet, as while move_base starts, is asked again every
SERVER_RETRY_S and counts as a failure only after SERVER_TIMEOUT_S), then the cycle stops in ``failed``: the
relay is opened, ``ports.alarm`` raises the reason (topic + voice) and the patrol stays paused
until an operator sends ``dock`` (try again) or ``undock`` (relay off, back off if on the dock,
resume the patrol). The robot drives only in task mode; in another
mode the machine waits and says why in its status. Found idle on the dock with the relay closed
(charge_control restarted mid-charge) it adopts that charge and finishes the cycle. The states,
timings, failure kinds and voice clips are in states.py.
"""
import json

from inspection_robot.charge.dock import is_docked, near_dock
from inspection_robot.charge.ports import validate_config
from inspection_robot.charge.states import BACKING_OFF, CHARGING, DOCKING, DRIVE_FAILURES, DRIVE_STATES, FAILED, \
    FAILURES, GOAL_RETRY_S, IDLE, PAUSE_RETRY_S, PAUSING, RELAY_OFF, RELAY_ON, RESUMING, SERVER_RETRY_S, \
    SERVER_TIMEOUT_S, TASK_QUIET_STATES, TO_APPROACH, TRIGGER_LOW_BATTERY, TRIGGER_MANUAL, TRIGGER_RECOVERED, \
    VOICE_ALARM, VOICE_CHARGED, VOICE_GOING_TO_DOCK, VOICE_LOW_BATTERY, WAIT_CURRENT
from inspection_robot.command import CommandError, CommandTable, no_data
from inspection_robot.interface import MODE_NAMES, MODE_TASK


class ChargeMachine(object):
    def __init__(self, config, dock, ports, clock):
        self._config = validate_config(config)
        self._dock = dock
        self._ports = ports
        self._clock = clock
        self.state = IDLE
        self.trigger = ""
        self.alarm = ""
        self.waiting = ""
        self._entered = clock()
        self._battery = None
        self._battery_time = None
        self._task_state = None
        self._token = 0
        self._awaiting = None      # "task" or "goal" while a request with self._token is out
        self._pause_acked = False
        self._pause_retry_at = 0.0   # when to ask an unreachable task_manager again
        self._unreachable = ""       # its last error, for the status and the final warning
        self._task_paused = False  # a charge hold is (or may be) in place on task_manager
        self._after_backoff = RESUMING
        self._goal_at = 0.0        # no goal before this time (a retry's delay)
        self._retrying = ""        # the failure a delayed goal retries, for the status
        self._no_server = ""       # why the last goal could not be sent (move_action's server not up)
        self._attempts = {}
        self._auto = True          # dock by itself on low battery (off after a manual undock)
        self._charging_seen = self._entered
        self._last_status = None
        self._steps = dict({IDLE: self._step_idle, PAUSING: self._step_pausing, RESUMING: self._step_resuming,
                            RELAY_ON: self._step_relay_on, WAIT_CURRENT: self._step_wait_current,
                            CHARGING: self._step_charging, RELAY_OFF: self._step_relay_off},
                           **dict.fromkeys(DRIVE_STATES, self._step_driving))
        self._publish_status()

    # --- inputs ---------------------------------------------------------------------------------
    def on_battery(self, battery):
        self._battery = battery
        self._battery_time = self._clock()
        self._step()

    def on_task_status(self, state):
        self._task_state = state
        self._step()

    def on_task_reply(self, token, ok, data):
        """task_manager's answer (``ok`` True, False, or None: unreachable) to our pause or resume."""
        if token != self._token or self._awaiting != "task":
            return
        self._awaiting = None
        handler = {PAUSING: self._pause_reply, RESUMING: self._resume_reply}.get(self.state)
        if handler is not None:
            handler(ok, data)

    def _pause_reply(self, ok, data):
        if ok is None and self._task_state is None:
            # no task_status ever seen: this robot runs no task_manager
            self._ports.warn("task_manager not reachable (%s): charging without pausing a patrol" % (data,))
            self._go_after_pause()
        elif ok is None:
            # task_manager exists (it published task_status) but does not answer: it may be
            # respawning, and a respawned task_manager resumes its patrol with goals of its own.
            # Ask again until pause_timeout rather than race it for move_base.
            self._pause_retry_at = self._clock() + PAUSE_RETRY_S
            self._unreachable = data or "no reply"
            self._step()
        elif ok:
            self._unreachable = ""
            self._pause_acked = self._task_paused = True
            self._step()
        else:
            self._unreachable = ""
            self._fail("pause", "refused: %s" % (data,))

    def _resume_reply(self, ok, data):
        if ok is None:
            self._ports.warn("task_manager not reachable (%s): nothing to resume" % (data,))
            self._finish()
        elif ok:
            self._finish()
        else:
            self._fail("resume", "refused: %s" % (data,))

    def on_move_result(self, token, ok, reason):
        """move_base's answer to our goal: ``ok`` True, False, or None: the server is not up, the goal not sent."""
        if token != self._token or self._awaiting != "goal" or self.state not in DRIVE_STATES:
            return
        self._awaiting = None
        if ok is None:
            # move_base still starting (it loads the map first) or respawning: not a dock fault until
            # SERVER_TIMEOUT_S; the goal goes again SERVER_RETRY_S later (_step_driving)
            self._no_server = reason
            self._goal_at = self._clock() + SERVER_RETRY_S
            self._step()
            return
        self._no_server = ""
        if ok:
            if self.state == TO_APPROACH:
                self._drive(DOCKING)
            elif self.state == DOCKING:
                self._ports.relay(True)
                self._enter(RELAY_ON)
            else:
                self._after_backoff_done()
            return
        if not self._in_task_mode():
            # move_base gave the goal up because someone else holds the robot: not a dock fault;
            # _step sends it again once robot_control is back in task mode
            self._step()
            return
        self._fail(DRIVE_FAILURES[self.state], reason)

    def tick(self):
        self._step()

    # --- commands (charge_cmd / charge_control) ---------------------------------------------------
    def command_table(self):
        return CommandTable({"dock": no_data(self._cmd_dock), "undock": no_data(self._cmd_undock),
                             "status": no_data(lambda _data: json.dumps(self.status(), sort_keys=True))})

    def _cmd_dock(self, _data):
        if self.state not in (IDLE, FAILED):
            raise CommandError("busy: charge cycle already running (%s)" % (self.state,))
        self._start(TRIGGER_MANUAL)
        return "docking started"

    def _cmd_undock(self, _data):
        if self.state in (BACKING_OFF, RESUMING) or (self.state == RELAY_OFF and self._after_backoff == RESUMING):
            return "already undocking (%s)" % (self.state,)
        if self.state == IDLE:
            if not self._near_dock():
                raise CommandError("not at the dock")
            self.trigger = TRIGGER_MANUAL
        if self.state in (TO_APPROACH, DOCKING):
            self._ports.cancel_goal()
        self.alarm = ""
        self._after_backoff = RESUMING
        # the operator chose to leave: no automatic docking until the battery is above low_level again
        self._auto = False
        if self.state == PAUSING:
            self._resume()
        else:
            self._ports.relay(False)
            self._enter(RELAY_OFF)
        return "undocking"

    # --- status -----------------------------------------------------------------------------------
    def status(self):
        battery = self._battery
        return {
            "state": self.state,
            "trigger": self.trigger,
            "battery": battery.quantity if battery else None,
            "charging": bool(battery and battery.charging),
            "relay": bool(battery and battery.relay),
            # the contacts touch: charging current proves it; without current the pose decides (a
            # noisy localizer's single pose can stray past the 3 cm tolerance while the robot charges)
            "docked": bool(battery and (battery.charging or (battery.pose and is_docked(self._dock, battery.pose)))),
            "waiting": self.waiting,
            "alarm": self.alarm,
            "task_paused": self._task_paused,
            "auto": self._auto,
            "attempts": dict(self._attempts),
            "low_level": self._config.low_level,
            "full_level": self._config.full_level,
        }

    def _publish_status(self):
        status = self.status()
        if status != self._last_status:
            self._last_status = status
            self._ports.status(status)

    # --- the sequence -----------------------------------------------------------------------------
    def _start(self, trigger):
        self.trigger = trigger
        self.alarm = ""
        self._attempts = {}
        self._after_backoff = DOCKING
        clips = [VOICE_GOING_TO_DOCK] if trigger == TRIGGER_MANUAL else [VOICE_LOW_BATTERY, VOICE_GOING_TO_DOCK]
        self._ports.speak(clips)
        self._pause()

    def _pause(self):
        self._pause_acked = False
        self._unreachable = ""
        self._enter(PAUSING)
        self._request_task("pause")

    def _resume(self):
        self._enter(RESUMING)
        self._request_task("resume")

    def _go_after_pause(self):
        if self._near_dock():
            self._after_backoff = DOCKING
            self._drive(BACKING_OFF)  # standing on the dock: leave it straight before lining up again
        else:
            self._drive(TO_APPROACH)

    def _after_backoff_done(self):
        if self._after_backoff == DOCKING:
            self._drive(DOCKING)
        else:
            self._resume()

    def _finish(self):
        self._task_paused = False
        self._enter(IDLE)

    def _step(self):
        """Re-evaluate the current state against the latest inputs and the clock: the state's handler
        (``_steps``) returns True when it has moved on (it published), else the status is published."""
        now = self._clock()
        battery = self._fresh_battery(now)
        self.waiting = ""
        state = self.state
        if battery and battery.quantity > self._config.low_level:
            self._auto = True
        handler = self._steps.get(state)
        if handler is not None and handler(now, now - self._entered, battery):
            return
        if state in (RELAY_ON, WAIT_CURRENT, RELAY_OFF, CHARGING) and battery is None:
            self.waiting = "no robot_status for %.0f s" % (self._config.status_timeout,)
        self._publish_status()

    def _step_idle(self, _now, _elapsed, battery):
        if battery and battery.relay and self._near_dock():
            # charge_control restarted mid-charge: finish that cycle instead of leaving the relay closed
            self.trigger = TRIGGER_RECOVERED
            self._task_paused = True  # a resume with no hold in place is harmless
            self._after_backoff = RESUMING
            self._enter(WAIT_CURRENT)
            return True
        if battery and battery.quantity <= self._config.low_level and not battery.charging:
            if self._auto:
                self._start(TRIGGER_LOW_BATTERY)
                return True
            self.waiting = "battery low, automatic docking off after a manual undock (send dock)"
        return False

    def _step_pausing(self, now, elapsed, _battery):
        if self._pause_acked and self._task_state in TASK_QUIET_STATES + (None,):
            self._go_after_pause()
            return True
        if self._unreachable:
            if elapsed > self._config.pause_timeout:
                self._ports.warn("task_manager not reachable for %.0f s (%s): charging without pausing a patrol"
                                 % (elapsed, self._unreachable))
                self._unreachable = ""
                self._go_after_pause()
                return True
            self.waiting = "task_manager not reachable (%s): asking again" % (self._unreachable,)
            if self._awaiting is None and now >= self._pause_retry_at:
                self._request_task("pause")
            return True
        if elapsed > self._config.pause_timeout:
            self._fail("pause", "task_status still '%s' %.0f s after pause" % (self._task_state, elapsed))
            return True
        self.waiting = "task_manager finishing its current preset (%s)" % (self._task_state,)
        return False

    def _step_resuming(self, _now, elapsed, _battery):
        return self._timed_out(elapsed, self._config.pause_timeout, "resume", "no reply %.0f s after resume")

    def _step_driving(self, now, elapsed, _battery):
        if not self._in_task_mode():
            self.waiting = "robot_control in %s mode: waiting for task mode" % (self._mode_name(),)
        elif self._no_server and self._awaiting is None and elapsed > SERVER_TIMEOUT_S:
            reason, self._no_server = self._no_server, ""
            self._fail(DRIVE_FAILURES[self.state], "%s (for %.0f s)" % (reason, elapsed))
            return True
        elif self._no_server and self._awaiting is None and now < self._goal_at:
            self.waiting = "%s: asking again" % (self._no_server,)
        elif self._awaiting is None and now < self._goal_at:
            self.waiting = "%s; sending the goal again %.0f s after the failure" % (self._retrying, GOAL_RETRY_S)
        elif self._awaiting is None:
            self._send_goal()
        return False

    def _step_relay_on(self, _now, elapsed, battery):
        if battery and battery.relay:
            self._enter(WAIT_CURRENT)
            return True
        return self._timed_out(elapsed, self._config.relay_timeout, "relay_on",
                               "light_status b0 not set %.0f s after enable_charge")

    def _step_wait_current(self, _now, elapsed, battery):
        if battery and battery.charging:
            self._enter(CHARGING)
            return True
        return self._timed_out(elapsed, self._config.current_timeout, "current",
                               "battery_status b4 not set %.0f s after the relay closed")

    def _step_relay_off(self, _now, elapsed, battery):
        if battery and not battery.relay:
            if self._near_dock():
                self._drive(BACKING_OFF)
            elif self._after_backoff == DOCKING:
                self._drive(TO_APPROACH)
            else:
                self._resume()
            return True
        return self._timed_out(elapsed, self._config.relay_timeout, "relay_off",
                               "light_status b0 still set %.0f s after disable_charge")

    def _timed_out(self, elapsed, timeout, kind, text):
        """Fail ``kind`` (``text`` % elapsed) once a state has waited longer than ``timeout``; whether it did."""
        if elapsed > timeout:
            self._fail(kind, text % (elapsed,))
            return True
        return False

    def _step_charging(self, now, _elapsed, battery):
        if battery is None:
            return False
        if battery.charging:
            self._charging_seen = now
            if battery.quantity >= self._config.full_level:
                self._ports.speak([VOICE_CHARGED])
                self._after_backoff = RESUMING
                self._ports.relay(False)
                self._enter(RELAY_OFF)
                return True
        elif now - self._charging_seen > self._config.current_lost_timeout:
            self._fail("current", "battery_status b4 cleared for %.0f s while charging at %d %%"
                       % (now - self._charging_seen, battery.quantity))
            return True
        return False

    def _fail(self, kind, detail):
        clip, text = FAILURES[kind]
        reason = text % (detail,)
        count = self._attempts.get(kind, 0) + 1
        self._attempts[kind] = count
        if count <= self._config.retries:
            self._ports.warn("%s; retry %d of %d" % (reason, count, self._config.retries))
            self._retrying = reason
            self._retry(kind)
            return
        if kind in ("relay_on", "current", "relay_off"):
            self._ports.relay(False)  # never leave the contacts live after giving up
        self.alarm = reason
        self._enter(FAILED)
        self._ports.alarm(reason, [VOICE_ALARM, clip])

    def _retry(self, kind):
        if kind == "pause":
            self._pause()
        elif kind in ("approach", "dock"):
            self._drive(TO_APPROACH, GOAL_RETRY_S)  # line up again before the precise approach
        elif kind == "relay_on":
            self._ports.relay(True)
            self._enter(RELAY_ON)
        elif kind == "current":
            # contacts misaligned or dirty: open the relay, back off and dock again
            self._after_backoff = DOCKING
            self._ports.relay(False)
            self._enter(RELAY_OFF)
        elif kind == "relay_off":
            self._ports.relay(False)
            self._enter(RELAY_OFF)
        elif kind == "backoff":
            self._drive(BACKING_OFF, GOAL_RETRY_S)
        else:
            self._resume()

    # --- helpers ----------------------------------------------------------------------------------
    def _enter(self, state):
        self.state = state
        self._entered = self._clock()
        self._charging_seen = self._entered
        self._awaiting = None
        self._no_server = ""
        self._token += 1  # late replies to anything sent before are ignored
        self.waiting = ""
        self._publish_status()  # every state shows, even one the next input leaves at once
        self._step()

    def _drive(self, state, delay=0.0):
        """Enter a drive state; _step sends its goal once the robot is in task mode and ``delay`` s have passed."""
        self._goal_at = self._clock() + delay
        self._enter(state)

    def _send_goal(self):
        dock = self._dock
        if self.state == TO_APPROACH:
            target, precision, backward = dock.approach, False, False
        elif self.state == DOCKING:
            target, precision, backward = dock.pose, True, False
        else:
            target, precision, backward = dock.approach, False, True
        self._token += 1
        self._awaiting = "goal"
        self._ports.goal(self._token, target, precision, backward)

    def _request_task(self, cmd):
        self._token += 1
        self._awaiting = "task"
        self._ports.task(self._token, cmd)

    def _fresh_battery(self, now):
        if self._battery is None or now - self._battery_time > self._config.status_timeout:
            return None
        return self._battery

    def _in_task_mode(self):
        return self._battery is not None and self._battery.mode == MODE_TASK

    def _mode_name(self):
        return MODE_NAMES.get(self._battery.mode, "unknown") if self._battery else "unknown (no robot_status)"

    def _near_dock(self):
        battery = self._battery
        return bool(battery and battery.pose and near_dock(self._dock, battery.pose))
