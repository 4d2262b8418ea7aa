"""Invariants of the chaos soak (soak.py), checked continuously from timestamped observations.

Pure: the soak feeds what it sees (driver commands, stop causes, node pids, resident memory,
objects it created and what the robot lists) and asks for violations; times are seconds on one
clock (wall time: the driver-command stamps robot_control writes). Each checker counts the checks it
made, so the closing table shows invariants that really were exercised, not just never violated.
"""
from collections import OrderedDict

from inspection_robot.interface import ACK_SUCCESS


class Checker(object):
    """Base: ``checks`` made, ``violations`` (text lines) found."""

    name = ""

    def __init__(self):
        self.checks = 0
        self.violations = []

    def _violate(self, text):
        self.violations.append(text)


class MotionAuthority(Checker):
    """No motion without a live authorised source; every stop within one control cycle of its cause.

    ``authorise(t)``: a live source may drive from now (backend holds control, heartbeat alive).
    ``stop_cause(t_cause, t_deadline, cause)``: the cause reached the robot at ``t_cause`` at the
    latest; from ``t_deadline`` (one control cycle later) every driver command must be zero until
    the next ``authorise``, and a zero command must have reached the driver by then.
    ``command(t, vx, vyaw)``: a command reaching the driver, stamped by robot_control.

    Judged by stamps, not by arrival: the stop's command usually reaches the soak before the cause
    is declared (the fault service answers after robot_control stopped), so commands ignored while
    authorised are kept for ``REPLAY`` s and judged again when a cause stamped before them arrives.
    """

    REPLAY = 5.0

    name = "no motion without a live authorised source; stop within one cycle"

    def __init__(self, eps=1e-6):
        super(MotionAuthority, self).__init__()
        self._eps = eps
        self._authorised = False
        self._deadline = None     # stop must be in effect from here
        self._cause = "start-up (not yet authorised)"
        self._pending = None      # (t_cause, deadline, cause) of a stop not yet seen at the driver
        self.stop_latencies = []  # s from a cause to its first zero command at the driver
        self._unjudged = []       # (t, vx, vyaw) that arrived while authorised, newest last

    def authorise(self, t):
        self._authorised = True
        self._deadline = None
        self._pending = None
        self._unjudged = []

    def stop_cause(self, t_cause, t_deadline, cause):
        self._authorised = False
        self._deadline = t_deadline
        self._cause = cause
        self._pending = (t_cause, t_deadline, cause)
        arrived_first = [c for c in self._unjudged if c[0] >= t_cause]
        self._unjudged = []
        for c in sorted(arrived_first):
            self._judge(*c)

    def command(self, t, vx, vyaw):
        if self._authorised:
            self._unjudged = [c for c in self._unjudged if c[0] > t - self.REPLAY]
            self._unjudged.append((t, vx, vyaw))
            return
        self._judge(t, vx, vyaw)

    def _judge(self, t, vx, vyaw):
        self.checks += 1
        moving = abs(vx) > self._eps or abs(vyaw) > self._eps
        if not moving:
            if self._pending is not None and t >= self._pending[0]:
                t_cause, deadline, cause = self._pending
                self.stop_latencies.append(t - t_cause)
                if t > deadline:
                    self._violate("stop after %s reached the driver %.3f s after the cause (limit %.3f s)"
                                  % (cause, t - t_cause, deadline - t_cause))
                self._pending = None
            return
        if self._deadline is None or t > self._deadline:
            self._violate("motion (%.3f m/s, %.3f rad/s) at %.3f without an authorised source (after %s)"
                          % (vx, vyaw, t, self._cause))

    def tick(self, t, grace=1.0):
        """A stop whose zero command never came (none within ``grace`` s after its deadline)."""
        if self._pending is not None and t > self._pending[1] + grace:
            self.checks += 1
            self._violate("no stop at the driver after %s" % self._pending[2])
            self._pending = None


class NodeLiveness(Checker):
    """Every node alive, or respawned within ``max_down`` s; counts respawns (pid changes)."""

    def __init__(self, max_down=5.0):
        super(NodeLiveness, self).__init__()
        self.name = "every node alive or respawned within %g s" % max_down
        self._max_down = max_down
        self._pid = {}
        self._down_since = {}
        self.respawns = 0

    def seen(self, t, node, pid):
        self.checks += 1
        since = self._down_since.pop(node, None)
        if since is not None and t - since > self._max_down:
            self._violate("%s down for %.1f s (> %.1f s)" % (node, t - since, self._max_down))
        if node in self._pid and self._pid[node] != pid:
            self.respawns += 1
        self._pid[node] = pid

    def respawned(self, node, seconds):
        """A node killed on purpose came back (restarted, registered with the master and its topics
        and services registered again) ``seconds`` after the kill; None: it never did."""
        self.checks += 1
        if seconds is None or seconds > self._max_down:
            self._violate("%s respawned %s after its kill (limit %.1f s)"
                          % (node, "never" if seconds is None else "%.1f s" % seconds, self._max_down))

    def unchanged(self, node, pid_before, pid_after):
        """``node`` must have lived through a fault of its device: the same process before and after."""
        self.checks += 1
        if pid_before != pid_after:
            self._violate("%s did not survive its device's fault (pid %s, then %s)" % (node, pid_before, pid_after))

    def missing(self, t, node):
        self.checks += 1
        since = self._down_since.setdefault(node, t)
        if t - since > self._max_down and not any(node in v for v in self.violations):
            self._violate("%s down for more than %.1f s" % (node, self._max_down))

    @property
    def pids(self):
        return dict(self._pid)


class MemoryGrowth(Checker):
    """Resident memory of every process within ``limit`` (+10 %) of its level after warm-up.

    The level is the median of the samples of the first ``warmup`` s of a process (a respawned
    process gets a new one); a violation is a process whose median of its last ``window`` samples
    exceeds it by more than ``limit`` when ``finish`` is called.
    """

    name = "resident memory within +10 % after warm-up"

    def __init__(self, warmup, limit=0.10, window=5):
        super(MemoryGrowth, self).__init__()
        self._warmup = warmup
        self._limit = limit
        self._window = window
        self._samples = OrderedDict()   # (node, pid) -> [(t, rss)]

    def sample(self, t, node, pid, rss):
        self._samples.setdefault((node, pid), []).append((t, rss))

    def levels(self):
        """{(node, pid): (level after warm-up, level at the end)} of every process sampled long enough."""
        out = OrderedDict()
        for key, samples in self._samples.items():
            t0 = samples[0][0]
            warm = [r for t, r in samples if t - t0 <= self._warmup]
            late = [r for t, r in samples if t - t0 > self._warmup]
            if len(warm) >= 1 and len(late) >= self._window:
                out[key] = (_median(warm), _median(late[-self._window:]))
        return out

    def finish(self):
        for (node, pid), (level, end) in self.levels().items():
            self.checks += 1
            if end > level * (1.0 + self._limit):
                self._violate("%s (pid %d) grew from %.1f to %.1f MB (+%.0f %%)"
                              % (node, pid, level / 1e6, end / 1e6, (end / level - 1.0) * 100.0))


class Ledger(Checker):
    """Nothing the backend stored (presets, virtual obstacles, readings) lost or corrupted."""

    name = "no preset / virtual obstacle / reading lost or corrupted"

    def __init__(self):
        super(Ledger, self).__init__()
        self._expected = OrderedDict()   # (kind, key) -> value

    def stored(self, kind, key, value):
        self._expected[(kind, key)] = value

    def removed(self, kind, key):
        self._expected.pop((kind, key), None)

    def expected(self, kind):
        return OrderedDict((k, v) for (kd, k), v in self._expected.items() if kd == kind)

    def listed(self, kind, found):
        """``found``: {key: value} the robot lists now for ``kind``."""
        for key, value in self.expected(kind).items():
            self.checks += 1
            if key not in found:
                self._violate("%s %s lost" % (kind, key))
            elif found[key] != value:
                self._violate("%s %s corrupted: %r, stored %r" % (kind, key, found[key], value))


class Availability(Checker):
    """After a fault clears, the device answers again within ``limit`` s."""

    name = "devices answer again after a fault"

    def __init__(self, limit):
        super(Availability, self).__init__()
        self.limit = limit
        self.recoveries = []

    def recovered(self, what, seconds):
        self.checks += 1
        if seconds is None or seconds > self.limit:
            self._violate("%s did not answer within %.0f s after its fault cleared" % (what, self.limit))
        else:
            self.recoveries.append(seconds)


class FaultReasons(Checker):
    """During a device fault every request fails, with a reason that names the fault."""

    name = "requests fail with the fault's reason during a fault"

    def answered(self, what, ack, reason, fragments):
        """``ack``/``reason`` of ``what`` sent during a fault; the reason must contain one of ``fragments``."""
        self.checks += 1
        if ack == ACK_SUCCESS:
            self._violate("%s succeeded during the fault" % what)
        elif not any(f in reason for f in fragments):
            self._violate("%s failed without naming the fault (%s): %r" % (what, " | ".join(fragments), reason))


class CallsAcrossRestart(Checker):
    """A service node killed while a backend calls it without pause: no call fails but one made while
    the node is away (from the kill to its new registration at the master), and those name it."""

    name = "service calls fail only while their node is away, saying so"
    REASON = "is not available: its node is restarting or down"

    def calls(self, service, killed, back, calls):
        """``calls``: (start, end, answered, reason) of every call around one kill at ``killed``, the
        node seen registered again at ``back`` (one clock). At least one call must follow ``back``."""
        after = [call for call in calls if call[0] > back]
        self.checks += 1
        if not after:
            self._violate("no call of %s after its node came back" % service)
        for start, end, answered, reason in calls:
            self.checks += 1
            if answered:
                continue
            if not (start <= back and end >= killed):
                self._violate("a call of %s failed while its node was there (%.2f s after it came back): %s"
                              % (service, start - back, reason))
            elif self.REASON not in reason:
                self._violate("a call of %s failed during the restart without saying so: %r" % (service, reason))


class ControlKept(Checker):
    """A backend that reconnects and acquires at once keeps control: the old connection's heartbeat
    expiring after the grant does not take the robot back to task mode."""

    name = "control kept by a backend that reconnects and acquires at once"

    def observed(self, what, kept, state=""):
        """``kept``: mode 1 and online held from the grant until the old heartbeat had expired."""
        self.checks += 1
        if not kept:
            self._violate("%s: control lost after the grant (%s)" % (what, state))


class SpoofsRefused(Checker):
    """A client claiming another node's safety input changes nothing: while a box stops the robot,
    a spoofed obstacle clear and a spoofed joystick acquire leave the stop and the mode as they were."""

    name = "spoofed safety inputs change nothing"

    def observed(self, what, unchanged, state=""):
        """``unchanged``: every robot_status kept the obstacle bit and the mode stayed the backend's."""
        self.checks += 1
        if not unchanged:
            self._violate("%s: a spoofed input took effect (%s)" % (what, state))


def _median(values):
    ordered = sorted(values)
    return ordered[len(ordered) // 2]


def table(faults, checkers):
    """The closing report: faults injected (name -> count) and every invariant (checks, violations)."""
    lines = ["%-44s %6s" % ("fault injected", "count")]
    lines += ["%-44s %6d" % (name, count) for name, count in faults.items()]
    lines.append("")
    lines.append("%-66s %7s %10s  %s" % ("invariant", "checks", "violations", "result"))
    for checker in checkers:
        if not checker.checks:
            result = "NOT EXERCISED"
        else:
            result = "VIOLATED" if checker.violations else "HELD"
        lines.append("%-66s %7d %10d  %s" % (checker.name, checker.checks, len(checker.violations), result))
        lines += ["    - %s" % v for v in checker.violations[:10]]
    return "\n".join(lines)


def held(checkers):
    return all(c.checks and not c.violations for c in checkers)
