"""MotionController: arbitration + safety + validation + watchdog + odometry around a ChassisDriver.

Pure logic (no rospy); robot_control wires it to topics. Every public method takes the one lock,
so callbacks from several threads and the control timer see a consistent state, and a safety
input stops the robot *in the call that delivers it* (not at the next control cycle).

Motion rules:
- A move_cmd moves the robot only if its sender holds the current mode (arbitration), it is
  valid (velocity), and no stop reason is active (safety). A refused move_cmd from the holder
  stops the robot (its intent is unknown); one from a non-holder is ignored.
- The accepted target is sent to the driver at once and again every control cycle.
- ``cmd_timeout`` s after the last accepted move_cmd the target is dropped and ``stop`` is sent
  once (watchdog); then zero velocity every cycle.
- Any stop (safety, mode change, timeout, offline) drops the target: motion resumes only with a
  new move_cmd.
- With ``obstacle_timeout``, an obstacle state not refreshed for that long (the detector re-asserts
  it every second) is doubtful: an obstacle is assumed until the next report. The clock starts with
  the first report: a rig without a detector (none ever reported) moves as before.
"""
import math
import threading

from inspection_robot.command import CommandError, CommandTable, failed, no_data, success
from inspection_robot.interface import (ACK_SUCCESS, BATTERY_CHARGING, CIRCUIT_JOY_COMM_LOST, IMU_COMMANDS,
                                        MODE_CMD_ACQUIRE, MODE_JOY, MODE_NAMES, MODE_SERVER, WHEEL_STRAIGHT)
from inspection_robot.motion.arbitration import REFUSAL_OFFLINE, ModeArbiter, refused
from inspection_robot.motion.chassis import ChassisError
from inspection_robot.motion.odometry import Odometry
from inspection_robot.motion.safety import SWITCHES, SafetyLatch
from inspection_robot.motion.status import control_status_fields
from inspection_robot.motion.voice import status_sentence

OFFLINE_RECHECK = 1.0  # s an acquire of backend mode waits for a robot_status on its own heartbeat
MAX_PENDING = 8        # such acquires waiting at once; more are refused at once


class MotionController(object):
    """``driver``: a ChassisDriver; ``limits``: VelocityLimits; ``clock()``: monotonic seconds;
    ``log(level, text)``: level is "info" or "warn"; ``speak(words)``: publishes a VoiceCmd."""

    def __init__(self, driver, limits, cmd_timeout, clock, log=None, speak=None, obstacle_timeout=None):
        if not cmd_timeout > 0:
            raise ValueError("cmd_timeout must be positive, got %r" % (cmd_timeout,))
        if obstacle_timeout is not None and not obstacle_timeout > 0:
            raise ValueError("obstacle_timeout must be positive or None, got %r" % (obstacle_timeout,))
        self.obstacle_timeout = obstacle_timeout
        self._obstacle_time = None    # clock() of the last obstacle report, None = none yet
        self.obstacle_stale = False   # True while an obstacle is assumed for want of a fresh report
        self.driver = driver
        self.limits = limits
        self.cmd_timeout = float(cmd_timeout)
        self._clock = clock
        self._log = log or (lambda level, text: None)
        self._speak = speak or (lambda words: None)
        self._lock = threading.RLock()
        self.arbiter = ModeArbiter()
        self.safety = SafetyLatch()
        self.odometry = Odometry()
        self.target = None            # Velocity being followed, None = stopped
        self.wheel_mode = WHEEL_STRAIGHT
        self._last_cmd_time = None
        self._last_tick = None
        self._lamps = None
        self._offline = False
        self._session = 0   # heartbeat session named by the latest robot_status (its trans_id)
        self._pending = []  # acquires waiting for a robot_status: (sender, cmd, data, trans_id, answer, deadline)
        self._chassis = driver.state()
        self.stop_count = 0
        driver.set_safety_listener(self.on_chassis_event)
        self.control_table = self._build_control_table()
        self.imu_table = self._build_imu_table()

    def set_speaker(self, speak):
        """``speak(words)`` publishes query_status' sentence."""
        self._speak = speak

    def locked(self):
        """The controller's lock, for callers that touch the driver directly (simulator faults)."""
        return self._lock

    @property
    def mode(self):
        return self.arbiter.mode

    # --- inputs ------------------------------------------------------------------------------
    def on_mode_cmd(self, sender, cmd, data, answer=None, trans_id=0):
        """Decide a mode_cmd: returns the Decision, or None when ``answer(decision)`` will get it later.

        An ``acquire server`` is granted only on a robot_status that is online and names the
        acquire's ``trans_id`` as its heartbeat session (or names none: session 0, a backend that
        does not number its heartbeats). Otherwise, when the caller can be answered later, it waits
        up to OFFLINE_RECHECK s for a robot_status that is: a client that saw its own heartbeat
        answered sent its acquire after that status, but the status travels on another topic and
        may reach this node after the acquire, behind older offline ones still queued (a loaded
        node works through a backlog), so an offline status meanwhile decides nothing. A backend
        whose own heartbeat has not arrived by then is refused: granting it on another (older)
        backend's heartbeat would let that heartbeat's expiry take the robot back a moment later.
        """
        with self._lock:
            if cmd == MODE_CMD_ACQUIRE and data == MODE_NAMES[MODE_SERVER] and not self._heartbeat_of(trans_id):
                if answer is not None and len(self._pending) < MAX_PENDING:
                    self._pending.append((sender, cmd, data, trans_id, answer, self._clock() + OFFLINE_RECHECK))
                    return None
                return self._offline_refusal(sender, cmd, data, trans_id)
            return self._decide(sender, cmd, data)

    def _heartbeat_of(self, trans_id):
        """True when the latest robot_status is online on the heartbeat of session ``trans_id``
        (or on an unnumbered heartbeat, session 0)."""
        return not self._offline and self._session in (0, trans_id)

    def _decide(self, sender, cmd, data):
        decision = self.arbiter.request(sender, cmd, data)
        self._log_decision(sender, cmd, data, decision)
        if decision.changed:
            self._stop("mode change")
        return decision

    def _offline_refusal(self, sender, cmd, data, trans_id):
        if self._offline:
            decision = refused(REFUSAL_OFFLINE, "acquire server refused: backend offline (robot_status.offline_warn)")
        else:
            decision = refused(REFUSAL_OFFLINE, "acquire server refused: no heartbeat of session %d yet "
                               "(robot_status names session %d)" % (trans_id, self._session))
        self._log_decision(sender, cmd, data, decision)
        return decision

    def _log_decision(self, sender, cmd, data, decision):
        self._log("info" if decision.accepted else "warn", "mode_cmd %s(%r) from %r: %s"
                  % (cmd, data, sender, decision.reason))

    def _settle_pending(self):
        """Decide the deferred acquires: granted on their session's heartbeat, refused when overdue.
        Returns [(answer, decision)] for the caller to deliver outside the lock."""
        now = self._clock()
        settled, waiting = [], []
        for sender, cmd, data, trans_id, answer, deadline in self._pending:
            if self._heartbeat_of(trans_id):
                settled.append((answer, self._decide(sender, cmd, data)))
            elif now >= deadline:
                settled.append((answer, self._offline_refusal(sender, cmd, data, trans_id)))
            else:   # offline, or online on another session's heartbeat: a later status may name its own
                waiting.append((sender, cmd, data, trans_id, answer, deadline))
        self._pending = waiting
        return settled

    def mode_reply(self, decision):
        """The mode_ack answer to a Decision: success with the mode now in force (and, when a stop
        reason is active, ``; motion blocked: <reasons>``: granted, but the robot will not move yet),
        or failed with the refusal ``"<code>: <text>"``. None (the request raised) is an internal error."""
        if decision is None:
            return failed("internal error: request not applied, robot stopped")
        if not decision.accepted:
            return failed(decision.reason)
        with self._lock:
            data = MODE_NAMES[self.mode]
            blocking = self.safety.reasons()
        if blocking:
            data += "; motion blocked: %s" % ",".join(blocking)
        return success(data)

    def on_move_cmd(self, sender, velocity_x, velocity_yaw, wheel_control):
        """Returns a Reply for the log: success, or failed with the reason the command was not obeyed."""
        with self._lock:
            if not self.arbiter.may_move(sender):
                return failed("sender '%s' does not hold the robot (mode %d obeys '%s')"
                              % (sender, self.mode, self.arbiter.holder()))
            try:
                velocity = self.limits.check(velocity_x, velocity_yaw, wheel_control)
            except CommandError as err:
                self._stop("refused move_cmd")
                return failed("refused: %s; robot stopped" % err)
            if self.safety.blocks():
                self._stop_if_moving("safety")
                return failed("motion refused: %s" % ",".join(self.safety.reasons()))
            try:
                self.driver.send_velocity(velocity.x, velocity.yaw, velocity.wheel_mode)
            except ChassisError as err:   # no chassis (driver: none), or the board refused
                self._stop("chassis refused move_cmd")
                return failed("chassis: %s; robot stopped" % err)
            self.target = velocity
            self.wheel_mode = velocity.wheel_mode
            self._last_cmd_time = self._clock()
            return success("clamped" if velocity.clamped else "")

    def on_obstacle(self, present):
        with self._lock:
            self._obstacle_time = self._clock()
            if self.obstacle_stale:
                self._log("info", "obstacle_status reported again (obstacle %s)" % bool(present))
            self.obstacle_stale = False
            self.safety.set_obstacle(present)
            if self.safety.blocks():
                self._stop_if_moving("obstacle")

    def on_offline(self, offline, session=0):
        """robot_status: offline_warn and the heartbeat session it names (its trans_id). Going
        offline in mode 1 stops and returns to task mode; acquires waiting for this status are
        decided. Another session's heartbeat changes nothing of the mode: any heartbeat keeps the
        robot online."""
        with self._lock:
            went_offline = offline and not self._offline
            self._offline = bool(offline)
            self._session = session
            if went_offline and self.mode == MODE_SERVER:
                self.arbiter.force_task()
                self._stop("backend offline")
                self._log("warn", "backend offline in mode 1: stopped, back to task mode")
            settled = self._settle_pending()
        for answer, decision in settled:
            answer(decision)

    def on_chassis_event(self):
        """Safety listener of the driver: re-read the chassis and stop at once if needed."""
        with self._lock:
            self._refresh_chassis()

    def on_control_cmd(self, sender, cmd, data):
        with self._lock:
            reply = self.control_table.dispatch(cmd, data)
            self._log("info" if reply.ack == ACK_SUCCESS else "warn",
                      "control_cmd %s(%r) from %r: %s %s" % (cmd, data, sender, reply.ack, reply.data))
            return reply

    def on_imu_cmd(self, cmd, data):
        with self._lock:
            return self.imu_table.dispatch(cmd, data)

    # --- control cycle -----------------------------------------------------------------------
    def tick(self):
        """One control cycle: safety inputs, watchdog, target to the driver, odometry, lamps."""
        with self._lock:
            now = self._clock()
            self._check_obstacle_age(now)
            self._refresh_chassis()
            if self.target is not None and now - self._last_cmd_time > self.cmd_timeout:
                self._stop("move_cmd timeout (%.2f s)" % self.cmd_timeout)
            if self.target is not None:
                self.driver.send_velocity(self.target.x, self.target.yaw, self.target.wheel_mode)
            else:
                self.driver.send_velocity(0.0, 0.0, self.wheel_mode)
            state = self._chassis
            if self._last_tick is not None:
                self.odometry.update(state.velocity_x, state.velocity_yaw, now - self._last_tick)
            self._last_tick = now
            self._update_lamps(state)
            settled = self._settle_pending()
        for answer, decision in settled:
            answer(decision)

    def status(self):
        """control_status fields (dict)."""
        with self._lock:
            return control_status_fields(self.mode, self.safety, self._chassis)

    def shutdown(self):
        with self._lock:
            self.target = None
            self.driver.stop()

    # --- internals ---------------------------------------------------------------------------
    def _refresh_chassis(self):
        self._chassis = self.driver.state()
        self.safety.update_chassis(self._chassis)
        if self._chassis.circuit_status & CIRCUIT_JOY_COMM_LOST and self.mode == MODE_JOY:
            self.arbiter.force_task()
            self._stop("joystick link lost")
            self._log("warn", "joystick link lost in mode 2: stopped, back to task mode")
        if self.safety.blocks():
            self._stop_if_moving(",".join(self.safety.reasons()))

    def _check_obstacle_age(self, now):
        if self.obstacle_stale or self._obstacle_time is None or self.obstacle_timeout is None:
            return
        if now - self._obstacle_time > self.obstacle_timeout:
            self.obstacle_stale = True
            self.safety.set_obstacle(True)
            self._log("warn", "obstacle_status silent for %.1f s (> obstacle_timeout %.1f s): obstacle assumed "
                      "until obstacle_detector reports again" % (now - self._obstacle_time, self.obstacle_timeout))
            if self.safety.blocks():
                self._stop_if_moving("obstacle_status silent")

    def _stop_if_moving(self, reason):
        if self.target is not None or abs(self._chassis.velocity_x) > 1e-4 or abs(self._chassis.velocity_yaw) > 1e-4:
            self._stop(reason)

    def _stop(self, reason):
        was_moving = self.target is not None
        self.target = None
        self.driver.stop()
        self.stop_count += 1
        if was_moving:
            self._log("info", "stop: %s" % reason)

    def _update_lamps(self, state):
        blocked = self.safety.blocks()
        lamps = (blocked, not blocked, bool(state.battery_status & BATTERY_CHARGING))
        if lamps != self._lamps:
            self.driver.set_lamps(*lamps)
            self._lamps = lamps

    def _build_control_table(self):
        """control_cmd: data is ignored (a safety command is never refused over a formatting detail)."""
        table = CommandTable()
        for name in SWITCHES:
            table.register("enable_" + name, self._switch_handler(name, True))
            table.register("disable_" + name, self._switch_handler(name, False))
            table.register("switch_" + name, self._switch_handler(name, None))
        table.register("enable_charge", lambda _d: self._charge(True))
        table.register("disable_charge", lambda _d: self._charge(False))
        table.register("enable_stop", self._enable_stop)
        table.register("disable_stop", self._disable_stop)
        table.register("query_status", self._query_status)
        return table

    def _switch_handler(self, name, enabled):
        def handler(_data):
            state = self.safety.set_switch(name, enabled)
            if self.safety.blocks():
                self._stop_if_moving(name)
            return "%s %s" % (name, "enabled" if state else "disabled")
        return handler

    def _charge(self, closed):
        try:
            self.driver.set_charge_relay(closed)
        except ChassisError as err:
            raise CommandError("charge relay: %s" % err)
        self._chassis = self.driver.state()
        return "charge relay %s" % ("closed" if closed else "open")

    def _enable_stop(self, _data):
        self.safety.enable_stop()
        self._stop("soft e-stop")
        return "soft e-stop engaged"

    def _disable_stop(self, _data):
        self._chassis = self.driver.state()
        self.safety.update_chassis(self._chassis)
        self.safety.disable_stop()
        return "soft e-stop released"

    def _query_status(self, _data):
        words = status_sentence(control_status_fields(self.mode, self.safety, self._chassis), self.safety.reasons())
        self._speak(words)
        return ",".join(words)

    def _build_imu_table(self):
        table = CommandTable({
            "calibrate": no_data(lambda _data: self._imu_calibrate()),
            "reset": no_data(lambda _data: self._imu_reset()),
            "query": no_data(lambda _data: self._imu_query()),
        })
        assert set(table.names) == set(IMU_COMMANDS)
        return table

    def _imu_calibrate(self):
        try:
            self.driver.imu_calibrate()
        except ChassisError as err:
            raise CommandError(str(err))
        return "calibrated"

    def _imu_reset(self):
        try:
            self.driver.imu_reset()
        except ChassisError as err:
            raise CommandError(str(err))
        return "reset"

    def _imu_query(self):
        reading = self.driver.imu_reading()
        return "%.2f,%.2f,%.2f,%d" % (math.degrees(reading.roll), math.degrees(reading.pitch),
                                      math.degrees(reading.yaw), 1 if reading.calibrated else 0)
