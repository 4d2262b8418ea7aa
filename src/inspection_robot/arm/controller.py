"""robot_arm's command table: jogging, absolute poses, trajectory record and playback (pure).

Data formats (INTERFACE.md section 4, "Arm"); multi-value data is comma separated, no spaces:

- ``move`` "x,y,z" / ``rotate`` "roll,pitch,yaw", each ``0|+|-``: continuous jog per axis (0 = that
  axis holds still). ``stop_move`` / ``stop_rotate``: "" stops every axis, or "a,b,c" each
  ``0`` (stop) | ``+`` (continue).
- ``set_position`` "x,y,z" mm and ``set_orientation`` "roll,pitch,yaw" deg (decimal numbers),
  absolute in the arm base frame: complete when reached, fail after ``move_timeout``; a pose
  outside the limits is refused and nothing moves. ``get_position`` / ``get_orientation`` return
  the same format with two decimals. ``reset``: the all-zero pose, completes when reached.
- ``record_orbit`` file ("" = the default file): samples the pose at ``record_rate_hz`` until
  ``stop_orbit`` (data "" = the recording's file, or another file) which writes the file.
- ``play_orbit`` "file,+" (forward) | "file,-" (reverse), file may be empty (default file):
  answers at once; the end (success) or a failure is reported later through ``report``.
  stop_orbit, stop_move, stop_rotate and reset stop a playback; other motions are refused
  while it runs.
"""
import threading
import time

from inspection_robot.arm import trajectory
from inspection_robot.arm.driver import ArmError, within
from inspection_robot.command import (CommandError, CommandTable, failed, no_data, parse_choice,
                                      parse_float, split_fields, success)
from inspection_robot.files import confine_path

AXIS_NAMES = (("x", "y", "z"), ("roll", "pitch", "yaw"))
JOG_DIRECTIONS = {"0": 0, "+": 1, "-": -1}


class _Task(object):
    """A record or playback thread with its stop flag."""

    def __init__(self, kind, path, target):
        self.kind = kind
        self.path = path
        self.stop = threading.Event()
        self.stopped_by = None
        self.started = None
        self.samples = []
        self.thread = threading.Thread(target=target, args=(self,), name="arm_" + kind)
        self.thread.daemon = True


class ArmController(object):
    def __init__(self, driver, roots, default_file, record_rate_hz=20.0, move_timeout=20.0,
                 tolerance_mm=0.5, tolerance_deg=0.5, max_record_s=600.0, report=None,
                 clock=time.monotonic, sleep=time.sleep):
        if record_rate_hz <= 0 or move_timeout <= 0 or max_record_s <= 0:
            raise ValueError("record_rate_hz, move_timeout and max_record_s must be positive")
        self.driver = driver
        self.roots = list(roots)
        self.default_file = confine_path(default_file, self.roots)
        self.record_rate = float(record_rate_hz)
        self.move_timeout = float(move_timeout)
        self.tolerance = (float(tolerance_mm), float(tolerance_deg))
        self.max_record_s = float(max_record_s)
        self._report = report or (lambda reply: None)
        self._clock = clock
        self._sleep = sleep
        self._task = None
        self._task_lock = threading.Lock()

    def table(self):
        return CommandTable({
            "move": lambda d: self._jog(d, 0), "rotate": lambda d: self._jog(d, 1),
            "stop_move": lambda d: self._stop_jog(d, 0, "stop_move"),
            "stop_rotate": lambda d: self._stop_jog(d, 1, "stop_rotate"),
            "set_position": lambda d: self._set_pose(d, 0), "set_orientation": lambda d: self._set_pose(d, 1),
            "get_position": no_data(lambda _d: self._get_pose(0)),
            "get_orientation": no_data(lambda _d: self._get_pose(1)), "reset": no_data(self._reset),
            "record_orbit": self._record, "stop_orbit": self._stop_orbit, "play_orbit": self._play,
        })

    # --- helpers ---------------------------------------------------------------------------
    def _pose(self, part):
        return _arm(self.driver.position if part == 0 else self.driver.orientation)

    def _refuse_while_playing(self):
        task = self._task
        if task is not None and task.kind == "play" and task.thread.is_alive():
            raise CommandError("busy: playing %s (send stop_orbit first)" % task.path)

    def _stop_playback(self, by):
        task = self._task
        if task is not None and task.kind == "play" and task.thread.is_alive():
            task.stopped_by = by
            task.stop.set()
            task.thread.join(2.0)

    def _wait_reached(self, part, target, what):
        deadline = self._clock() + self.move_timeout
        while True:
            pose = self._pose(part)
            if max(abs(a - b) for a, b in zip(pose, target)) <= self.tolerance[part]:
                return
            if self._clock() >= deadline:
                raise CommandError("arm did not reach %s %s within %.1f s (at %s)"
                                   % (what, _fmt(target), self.move_timeout, _fmt(pose)))
            self._sleep(0.02)

    # --- jog -------------------------------------------------------------------------------
    def _jog(self, data, part):
        names = AXIS_NAMES[part]
        fields = split_fields(data, 3)
        dirs = [JOG_DIRECTIONS[parse_choice(f, n, ("0", "+", "-"))] for f, n in zip(fields, names)]
        self._refuse_while_playing()
        _arm(lambda: self.driver.jog(**{("linear" if part == 0 else "angular"): dirs}))

    def _stop_jog(self, data, part, cmd):
        if data == "":
            keep = [False] * 3
        else:
            fields = split_fields(data, 3)
            keep = [parse_choice(f, n, ("0", "+")) == "+" for f, n in zip(fields, AXIS_NAMES[part])]
        self._stop_playback(cmd)
        current = _arm(self.driver.jog_state)[part]
        dirs = [d if k else 0 for d, k in zip(current, keep)]
        _arm(lambda: self.driver.jog(**{("linear" if part == 0 else "angular"): dirs}))

    # --- absolute poses ----------------------------------------------------------------------
    def _parse_pose(self, data, part):
        names = AXIS_NAMES[part]
        values = tuple(parse_float(f, n) for f, n in zip(split_fields(data, 3), names))
        ranges = self.driver.limits[part]
        bad = within(values, ranges)
        if bad is not None:
            raise CommandError("%s out of range [%s, %s]: %s" % (names[bad], ranges[bad][0], ranges[bad][1],
                                                                 values[bad]))
        return values

    def _set_pose(self, data, part):
        target = self._parse_pose(data, part)
        self._refuse_while_playing()
        _arm(lambda: self.driver.command_pose(**{("position" if part == 0 else "orientation"): target}))
        self._wait_reached(part, target, "position" if part == 0 else "orientation")

    def _get_pose(self, part):
        return _fmt(self._pose(part))

    def _reset(self, _data):
        self._stop_playback("reset")
        _arm(lambda: self.driver.command_pose((0.0, 0.0, 0.0), (0.0, 0.0, 0.0)))
        self._wait_reached(0, (0.0, 0.0, 0.0), "position")
        self._wait_reached(1, (0.0, 0.0, 0.0), "orientation")

    # --- record ------------------------------------------------------------------------------
    def _path(self, text):
        return self.default_file if text == "" else confine_path(text, self.roots)

    def _start(self, kind, path, target):
        with self._task_lock:
            task = self._task
            if task is not None and task.thread.is_alive():
                raise CommandError("busy: %s %s in progress" % ("recording" if task.kind == "record" else "playing",
                                                                task.path))
            task = _Task(kind, path, target)
            self._task = task
        return task

    def _record(self, data):
        path = self._path(data)
        self._pose(0)     # fail now, not in the thread, if the arm does not answer
        task = self._start("record", path, self._record_loop)
        task.started = self._clock()
        task.thread.start()
        return path

    def _record_loop(self, task):
        period = 1.0 / self.record_rate
        start = task.started
        next_time = start
        while not task.stop.is_set():
            now = self._clock()
            try:
                sample = trajectory.Sample(now - start, self.driver.position(), self.driver.orientation())
            except ArmError as err:
                task.stopped_by = "error"
                self._report(failed("record_orbit: recording to %s aborted: %s" % (task.path, err)))
                return
            task.samples.append(sample)
            if now - start >= self.max_record_s:
                task.stopped_by = "limit"
                self._finish_recording(task, task.path, "record_orbit: %.0f s limit reached" % self.max_record_s)
                return
            next_time += period
            task.stop.wait(max(0.0, next_time - self._clock()))

    def _finish_recording(self, task, path, why):
        try:
            trajectory.save(path, task.samples, self.record_rate)
        except trajectory.TrajectoryError as err:
            self._report(failed("%s; %s" % (why, err)))
            return
        self._report(success("%s; saved %d samples to %s" % (why, len(task.samples), path)))

    def _stop_orbit(self, data):
        task = self._task
        if task is None or not task.thread.is_alive():
            if data != "":
                self._path(data)   # still report a bad path as such
            raise CommandError("not recording or playing")
        if task.kind == "play":
            self._stop_playback("stop_orbit")
            return "stopped playing %s" % task.path
        path = task.path if data == "" else self._path(data)
        task.stop.set()
        task.thread.join(2.0)
        if task.stopped_by == "error":
            raise CommandError("recording to %s had failed; nothing saved" % task.path)
        # the pose at the moment of stop_orbit ends the trajectory, whatever the sampling phase
        task.samples.append(trajectory.Sample(self._clock() - task.started, self._pose(0), self._pose(1)))
        try:
            trajectory.save(path, task.samples, self.record_rate)
        except trajectory.TrajectoryError as err:
            raise CommandError(str(err))
        return "%s,%d" % (path, len(task.samples))

    # --- playback ------------------------------------------------------------------------------
    def _play(self, data):
        text = str(data)
        if "," not in text:
            raise CommandError("play_orbit data must be 'file,+' or 'file,-', got '%s'" % (text,))
        file_text, direction = text.rsplit(",", 1)
        parse_choice(direction, "direction", ("+", "-"))
        path = self._path(file_text)
        try:
            samples = trajectory.load(path)
        except trajectory.TrajectoryError as err:
            raise CommandError(str(err))
        for index, sample in enumerate(samples):
            for part, pose in ((0, sample.position), (1, sample.orientation)):
                bad = within(pose, self.driver.limits[part])
                if bad is not None:
                    raise CommandError("%s sample %d: %s %s outside the arm's limits"
                                       % (path, index + 1, AXIS_NAMES[part][bad], pose[bad]))
        if direction == "-":
            samples = trajectory.reversed_samples(samples)
        task = self._start("play", path, self._play_loop)
        task.samples = samples
        task.direction = direction
        task.thread.start()
        return "playing %s %s (%d samples, %.1f s)" % (path, direction, len(samples), samples[-1].t)

    def _play_loop(self, task):
        what = "play_orbit %s,%s" % (task.path, task.direction)
        try:
            first = task.samples[0]
            self.driver.command_pose(first.position, first.orientation)
            self._wait_pose(task, first, self.move_timeout)
            start = self._clock()
            for sample in task.samples[1:]:
                if task.stop.wait(max(0.0, start + sample.t - self._clock())):
                    break
                self.driver.command_pose(sample.position, sample.orientation)
            self._wait_pose(task, task.samples[-1], self.move_timeout)
        except (ArmError, CommandError) as err:
            self._safe_stop()
            self._report(failed("%s: %s" % (what, err)))
            return
        if task.stop.is_set():
            self._safe_stop()
            self._report(failed("%s: stopped by %s" % (what, task.stopped_by or "stop")))
        else:
            self._report(success("%s: finished" % what))

    def _wait_pose(self, task, sample, timeout):
        deadline = self._clock() + timeout
        while not task.stop.is_set():
            position, orientation = self.driver.position(), self.driver.orientation()
            if (max(abs(a - b) for a, b in zip(position, sample.position)) <= self.tolerance[0]
                    and max(abs(a - b) for a, b in zip(orientation, sample.orientation)) <= self.tolerance[1]):
                return
            if self._clock() >= deadline:
                raise CommandError("arm did not reach %s / %s within %.1f s"
                                   % (_fmt(sample.position), _fmt(sample.orientation), timeout))
            task.stop.wait(0.02)

    def _safe_stop(self):
        try:
            self.driver.stop()
        except ArmError:
            pass

    def shutdown(self):
        task = self._task
        if task is not None:
            task.stopped_by = "shutdown"
            task.stop.set()
        self._safe_stop()


def _fmt(values):
    return ",".join("%.2f" % v for v in values)


def _arm(action):
    try:
        return action()
    except ArmError as err:
        raise CommandError(str(err))
