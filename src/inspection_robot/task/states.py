"""The words of task_manager's interface that more than one module reads: task states (task_status
``state``, the store's tasks), reading statuses and alarm states (result rows, reports, the console
through query_results). One place: the patrol, the store, the reports, task_action, task_manager,
charge_control and bag_report all import them (docs/interface.md, "Patrol (task_manager)").
"""
from inspection_robot.interface import THERMAL_UNIT

# --- task states (task_status "state"; tasks.state in the store) -----------------------------
STATE_IDLE = "idle"
STATE_RUNNING = "running"
STATE_PAUSED = "paused"
STATE_RETURNING_HOME = "returning_home"
STATE_DONE = "done"
STATE_CANCELLED = "cancelled"
STATE_FAILED = "failed"
STATE_SUSPENDED = "suspended"   # stored state of a routine task pre-empted by a special one
ENDED_STATES = (STATE_DONE, STATE_CANCELLED, STATE_FAILED)
UNFINISHED_STATES = (STATE_RUNNING, STATE_PAUSED, STATE_SUSPENDED)   # resumed after a restart

# --- reading statuses (readings.status) --------------------------------------------------------
STATUS_READ = "read"
STATUS_UNCERTAIN = "uncertain"   # a value the reader doubts (its reason says why): needs review
STATUS_FAILED = "failed"         # no value
READING_STATUSES = (STATUS_READ, STATUS_UNCERTAIN, STATUS_FAILED)

# --- alarm states (readings.alarm, readings.review_alarm) --------------------------------------
ALARM_ALARM = "alarm"     # a value outside its band (outside its alarm band when it has one)
ALARM_CHECK = "check"     # an uncertain value outside its band: go and look, never silence
ALARM_WARNING = "warning"  # outside the normal band, inside the alarm band around it
ALARM_FAILED = "failed"   # no reading
ALARM_TREND = "trend"     # inside its band but drifting toward it, to cross within days (task/trend.py)
ALARM_NORMAL = "normal"
ALARM_NONE = "none"       # no band for this target
ALARM_ORDER = (ALARM_ALARM, ALARM_CHECK, ALARM_WARNING, ALARM_FAILED, ALARM_TREND, ALARM_NORMAL,
               ALARM_NONE)   # most urgent first


def alarm_state(value, band, uncertain=False, alarm_band=None):
    """The alarm of ``value`` against its normal ``band`` [low, high] (None: no band) and the optional
    ``alarm_band`` around it: outside the normal band but inside the alarm band is ``warning``, outside
    both ``alarm``; ``uncertain`` values outside the normal band are ``check`` (go and look)."""
    if value is None:
        return ALARM_FAILED
    if band is None:
        return ALARM_NONE
    if band[0] <= value <= band[1]:
        return ALARM_NORMAL
    if uncertain:
        return ALARM_CHECK
    if alarm_band is not None and alarm_band[0] <= value <= alarm_band[1]:
        return ALARM_WARNING
    return ALARM_ALARM


def target_unit(kind, unit=""):
    """The unit of a target's readings: a pointer's or a display's calibrated ``unit``, ``C`` (degrees Celsius,
    the spec's temperature unit) for thermal targets, "" for lamps and switches (state codes)."""
    if kind == "thermal":
        return THERMAL_UNIT
    return unit if kind in ("pointer", "digital") else ""
