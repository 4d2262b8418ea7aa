"""Pure logic of status_control: heartbeat timing and the robot_status merge.

robot_status is the backend's single view of the robot. It is built from the latest input of
each source; a source silent for longer than its timeout is *flagged* in ``other_status[0]``
(STALE_* bits) rather than silently repeated as if fresh (docs/interface.md, "Staleness").

Heartbeat sessions (docs/interface.md, "Heartbeat and status", **Sessions**): a backend names its
connection by a session number, the ``trans_id`` of its server_status. robot_status's header
answers the heartbeat that keeps the robot online: ``trans_id`` its session, ``receiver`` its
sender (0 and "" while offline), so a backend can tell its own heartbeat from an older one's.
"""
import math

from inspection_robot.angles import wrap_angle
from inspection_robot.interface import MOTOR_COUNT, TEMPERATURE_COUNT, TEMPERATURE_NOT_SAMPLED

# other_status[0] of robot_status: which inputs are stale (no message within their timeout).
STALE_CONTROL_STATUS = 1 << 0
STALE_NAV_STATUS = 1 << 1
STALE_ODOMETRY = 1 << 2
STALE_SOURCES = (("control", STALE_CONTROL_STATUS), ("nav", STALE_NAV_STATUS),
                 ("odom", STALE_ODOMETRY))

# ControlStatus fields that robot_status copies, in RobotStatus order after sensor_status.
CONTROL_FIELDS = ("wheel_status", "light_status", "stop_status", "circuit_status", "other_status",
                  "battery_voltage", "battery_current", "battery_quantity", "battery_status",
                  "motor_status", "motor_info", "temperature")
# Arrays with a documented length: padded/truncated so robot_status always has that length.
FIXED_LENGTHS = {"motor_status": (MOTOR_COUNT, 0), "motor_info": (MOTOR_COUNT, 0),
                 "temperature": (TEMPERATURE_COUNT, TEMPERATURE_NOT_SAMPLED)}
MAX_HEARTBEAT_TEXT = 256
MAX_TRANS_ID = 2 ** 32 - 1
NO_SESSION = ("", 0)   # robot_status (receiver, trans_id) while offline


class Heartbeat(object):
    """Offline after ``timeout`` seconds without a server_status; online at the next one.

    ``session(now)`` is (sender, trans_id) of the latest server_status while online, NO_SESSION
    while offline. Any server_status keeps the robot online, whoever sends it (the spec's rule); the
    session only says whose heartbeat arrived last. A sender that fails heartbeat_text_problem is
    answered as "" (never echoed), a trans_id outside uint32 as 0.
    """

    def __init__(self, timeout):
        if timeout <= 0:
            raise ValueError("heartbeat timeout must be positive, got %r" % (timeout,))
        self.timeout = timeout
        self._last = None
        self._session = NO_SESSION

    def beat(self, now, sender="", trans_id=0):
        self._last = now
        if heartbeat_text_problem(sender):
            sender = ""
        if not isinstance(trans_id, int) or not 0 <= trans_id <= MAX_TRANS_ID:
            trans_id = 0
        self._session = (sender, trans_id)

    def offline(self, now):
        return self._last is None or now - self._last > self.timeout

    def session(self, now):
        return NO_SESSION if self.offline(now) else self._session


class PublishGate(object):
    """When status_control publishes robot_status at once, besides its ~rate.

    A change of any field goes out at once (the spec's rule). A change of the heartbeat session
    alone goes out at once at most once per ``period`` s, else with the next periodic status:
    backends beating in turn (or one flooding heartbeats under changing session numbers) add at
    most 1/period messages a second to robot_status.
    """

    def __init__(self, period):
        if not period > 0:
            raise ValueError("period must be positive, got %r" % (period,))
        self.period = float(period)
        self._status = None
        self._session = None
        self._session_sent = None

    def due(self, now, status, session):
        """True when (status, session) should be published now, outside the periodic tick."""
        if status != self._status:
            return True
        return session != self._session and (self._session_sent is None
                                             or now - self._session_sent >= self.period)

    def sent(self, now, status, session):
        """(status, session) went out at ``now``."""
        if session != self._session:
            self._session_sent = now
        self._status = status
        self._session = session


def heartbeat_text_problem(*texts):
    """Return why a server_status's strings look malformed, or None. Malformed beats still count."""
    for text in texts:
        if len(text) > MAX_HEARTBEAT_TEXT:
            return "string longer than %d characters" % MAX_HEARTBEAT_TEXT
        if any(ord(c) < 32 and c not in "\t\r\n" for c in text):
            return "control characters in %r" % (text[:40],)
    return None


def fit_array(name, values):
    """Return ``values`` as a list of the documented length for ``name`` (pad or truncate)."""
    values = list(values)
    if name not in FIXED_LENGTHS:
        return values
    length, fill = FIXED_LENGTHS[name]
    return (values + [fill] * length)[:length]


class StatusMerger(object):
    """Holds the latest value of every input and builds the robot_status field dict."""

    def __init__(self, heartbeat, stale_timeouts):
        self.heartbeat = heartbeat
        self.stale_timeouts = dict(stale_timeouts)  # source name -> seconds
        self._seen = {}
        self.mode = 0
        self.control = {name: fit_array(name, []) for name in CONTROL_FIELDS}
        for name in ("wheel_status", "light_status", "stop_status", "circuit_status",
                     "battery_voltage", "battery_current", "battery_quantity", "battery_status"):
            self.control[name] = 0
        self.velocity_x = 0.0
        self.velocity_yaw = 0.0
        self.position = [0.0, 0.0]
        self.orientation = 0.0
        self.nav_warn = 0
        self.sensor_status = 0

    def update_control(self, now, fields):
        """Take a control_status as a dict; returns a list of problems (arrays of wrong length)."""
        problems = []
        self.mode = int(fields["mode"])
        for name in CONTROL_FIELDS:
            value = fields[name]
            if name in FIXED_LENGTHS:
                value = list(value)
                if len(value) != FIXED_LENGTHS[name][0]:
                    problems.append("%s has %d values, expected %d" % (name, len(value), FIXED_LENGTHS[name][0]))
                value = fit_array(name, value)
            elif isinstance(value, (list, tuple, bytes)):
                value = list(value)
            self.control[name] = value
        self._seen["control"] = now
        return problems

    def update_nav(self, now, nav_warn, position, orientation):
        problems = []
        position = list(position)
        if len(position) < 2 or not all(math.isfinite(v) for v in position[:2]) or not math.isfinite(orientation):
            problems.append("nav_status pose invalid: position=%s orientation=%s" % (position, orientation))
        else:
            self.position = [float(position[0]), float(position[1])]
            self.orientation = wrap_angle(orientation)
        self.nav_warn = int(nav_warn)
        self._seen["nav"] = now
        return problems

    def update_odometry(self, now, velocity_x, velocity_yaw):
        if math.isfinite(velocity_x) and math.isfinite(velocity_yaw):
            self.velocity_x = float(velocity_x)
            self.velocity_yaw = float(velocity_yaw)
        self._seen["odom"] = now

    def set_sensor_bit(self, bit_mask, alarm):
        if alarm:
            self.sensor_status |= bit_mask
        else:
            self.sensor_status &= ~bit_mask

    def stale_bits(self, now):
        bits = 0
        for source, mask in STALE_SOURCES:
            seen = self._seen.get(source)
            if seen is None or now - seen > self.stale_timeouts[source]:
                bits |= mask
        return bits

    def robot_status(self, now):
        """All RobotStatus fields after the header block, as a dict."""
        status = {
            "offline_warn": 1 if self.heartbeat.offline(now) else 0,
            "mode": self.mode,
            "velocity_x": self.velocity_x,
            "velocity_yaw": self.velocity_yaw,
            "position": list(self.position),
            "orientation": self.orientation,
            "nav_status": self.nav_warn,
            "sensor_status": self.sensor_status,
        }
        for name in CONTROL_FIELDS:
            value = self.control[name]
            status[name] = list(value) if isinstance(value, list) else value
        other = list(status["other_status"]) or [0]
        other[0] = (other[0] & ~0x7) | self.stale_bits(now)
        status["other_status"] = other
        return status
