"""Thermal defects graded the way substations judge heating: by comparison, after DL/T 664.

DL/T 664-2016 (infrared diagnosis of live electrical equipment) judges a current-heated defect by
comparing the hot point with the same point of its healthy sister phases and an ambient reference:

    relative temperature difference  dt = (T1 - T2) / (T1 - T0) x 100 %

T1 the hot point (the hottest phase's box maximum), T2 the normal corresponding point (the coolest
sister phase: a second heating phase must not hide the first), T0 the ambient reference box. A
defect is graded by its equipment class (GradeRule): critical or serious when the hot spot passes
the class's temperature or dt its percentage, general when dt passes the class's general percentage
or T1 - T2 exceeds ``general_diff`` K. The relative method is not applied when the hot point rises
less than ``min_rise`` K over ambient (the standard's advice: a ratio of small differences is
noise), nor without an ambient box; the absolute criteria still are.

Pure: the task service feeds box maxima (task.rows), tests feed matrices' maxima.
"""
import math
from collections import OrderedDict, namedtuple

PHASES = ("A", "B", "C")
AMBIENT = "ambient"
PHASE_CHOICES = PHASES + (AMBIENT,)
GRADE_NONE, GRADE_GENERAL, GRADE_SERIOUS, GRADE_CRITICAL = "", "general", "serious", "critical"
GRADES = (GRADE_GENERAL, GRADE_SERIOUS, GRADE_CRITICAL)   # least urgent first
KELVIN = 273.15

# dt thresholds in %, temperatures in degC, differences in K (see the module docstring)
GradeRule = namedtuple("GradeRule", "general_delta general_diff serious_delta serious_hot critical_delta "
                                    "critical_hot min_rise")

# Defaults per equipment class: serious and critical from DL/T 664-2016 Appendix H, Table H.1
# (current-heated equipment: hot spot temperature or dt); general: dt from the relative temperature
# difference table of DL/T 664-2008 (Table 1), or a difference over 15 K. Sites override them in
# config/task_manager.yaml (~thermal_grades); docs/interface.md prints this table.
DEFAULT_RULES = OrderedDict([
    # class: (general %, general K, serious %, serious degC, critical %, critical degC, min rise K)
    ("connector", GradeRule(35.0, 15.0, 80.0, 80.0, 95.0, 110.0, 15.0)),       # equipment-to-metal clamp, joint
    ("metal_joint", GradeRule(35.0, 15.0, 80.0, 90.0, 95.0, 130.0, 15.0)),     # metal-to-metal clamp, joint
    ("conductor", GradeRule(35.0, 15.0, 80.0, 80.0, 95.0, 110.0, 15.0)),       # bare metal conductor
    ("disconnector", GradeRule(35.0, 15.0, 80.0, 90.0, 95.0, 130.0, 15.0)),    # disconnector blade, pivot
    ("breaker", GradeRule(20.0, 15.0, 80.0, 55.0, 95.0, 80.0, 15.0)),          # breaker contacts (SF6, vacuum)
    ("current_transformer", GradeRule(35.0, 15.0, 80.0, 55.0, 95.0, 80.0, 15.0)),  # CT inner connection
    ("bushing", GradeRule(20.0, 15.0, 80.0, 55.0, 95.0, 80.0, 15.0)),          # bushing terminal (oil-filled)
    ("capacitor_fuse", GradeRule(35.0, 15.0, 80.0, 60.0, 95.0, 90.0, 15.0)),   # capacitor fuse
])
DEFAULT_CLASS = "connector"

Diagnosis = namedtuple("Diagnosis", "grade rule hot_phase t1 t2 t0 rise diff delta_t phases")


class DiagnosisError(ValueError):
    """Grade rules or temperatures that cannot be used; the message says which."""


def check_rules(overrides):
    """DEFAULT_RULES with ``overrides`` {class: {field: value}} applied and checked: known classes
    and fields only, finite numbers, percentages in (0, 100], general <= serious <= critical."""
    rules = OrderedDict(DEFAULT_RULES)
    for name, fields in (overrides or {}).items():
        if name not in rules:
            raise DiagnosisError("unknown equipment class '%s' (one of %s)" % (name, ", ".join(rules)))
        if not isinstance(fields, dict):
            raise DiagnosisError("%s: expected {field: number}, got %r" % (name, fields))
        unknown = sorted(set(fields) - set(GradeRule._fields))
        if unknown:
            raise DiagnosisError("%s: unknown field(s) %s (fields: %s)"
                                 % (name, ", ".join(unknown), ", ".join(GradeRule._fields)))
        values = rules[name]._asdict()
        for key, value in fields.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)) or value != value \
                    or abs(value) == float("inf"):
                raise DiagnosisError("%s.%s must be a finite number, got %r" % (name, key, value))
            values[key] = float(value)
        rules[name] = GradeRule(**values)
    for name, rule in rules.items():
        deltas = (rule.general_delta, rule.serious_delta, rule.critical_delta)
        if not all(0.0 < d <= 100.0 for d in deltas) or list(deltas) != sorted(deltas):
            raise DiagnosisError("%s: dt thresholds must be in (0, 100] %% with general <= serious <= critical, "
                                 "got %s" % (name, ", ".join("%g" % d for d in deltas)))
        if rule.serious_hot > rule.critical_hot:
            raise DiagnosisError("%s: serious_hot %g is above critical_hot %g" % (name, rule.serious_hot,
                                                                                  rule.critical_hot))
        if rule.general_diff <= 0.0 or rule.min_rise < 0.0:
            raise DiagnosisError("%s: general_diff must be > 0 and min_rise >= 0" % name)
    return rules


# Atmospheric transmission of the long-wave band over a path, after the model FLIR cameras record in
# their files (the coefficients' usual values: ExifTool's FLIR tags AtmosphericTransAlpha1..X): two
# absorption terms whose strength grows with the square root of the path and of the water vapour.
ATMOSPHERE_ALPHA = (0.006569, 0.012620)
ATMOSPHERE_BETA = (-0.002276, -0.006670)
ATMOSPHERE_X = 1.9
DEFAULT_HUMIDITY = 50.0     # % relative: the robot does not measure it (20 % or 90 %: 1.2 K apart at 80 C, 20 m)
MIN_EMISSIVITY = 0.1        # below, a surface's own radiance drowns in its reflection: not measurable
MAX_DISTANCE = 100.0        # m from the imager: past it a substation box is a few pixels and the model is stretched
AIR_RANGE_C = (-50.0, 60.0)  # the outdoor air the vapour formula holds for; an "ambient" box beyond it is no air


def transmission(distance, air, humidity=DEFAULT_HUMIDITY):
    """The share (0..1] of a surface's radiance that crosses ``distance`` m of air at ``air`` degC
    (taken within AIR_RANGE_C: a hot plate chosen as the ambient box must not overflow the vapour
    formula) and ``humidity`` % relative humidity; 1 at 0 m."""
    if distance <= 0.0:
        return 1.0
    air = min(AIR_RANGE_C[1], max(AIR_RANGE_C[0], air))
    vapour = humidity / 100.0 * math.exp(1.5587 + 0.06939 * air - 0.00027816 * air ** 2 + 0.00000068455 * air ** 3)
    half = math.sqrt(distance / 2.0)   # the path in two halves (the model's optics-window form, no window)
    x = ATMOSPHERE_X
    tau = (x * math.exp(-half * (ATMOSPHERE_ALPHA[0] + ATMOSPHERE_BETA[0] * math.sqrt(vapour)))
           + (1.0 - x) * math.exp(-half * (ATMOSPHERE_ALPHA[1] + ATMOSPHERE_BETA[1] * math.sqrt(vapour))))
    return min(1.0, max(0.0, tau)) ** 2


def object_temperature(apparent, emissivity, ambient, distance=0.0, humidity=DEFAULT_HUMIDITY):
    """The object's temperature (degC) behind an ``apparent`` blackbody-equivalent one (degC, the
    imager set to emissivity 1 and no distance) for a grey body of ``emissivity`` at ``distance`` m,
    its surroundings and the air between at ``ambient`` degC (total radiance, Stefan-Boltzmann):
    Ta^4 = tau (e T^4 + (1 - e) Tr^4) + (1 - tau) Tatm^4. DiagnosisError when the apparent radiance
    is below what the reflection and the air alone give (a box that is not the surface it claims)."""
    tau = transmission(distance, ambient, humidity)
    if emissivity >= 1.0 and tau >= 1.0:
        return float(apparent)
    ta, tr = apparent + KELVIN, ambient + KELVIN
    emitted = (ta ** 4 - (1.0 - tau) * tr ** 4) / tau - (1.0 - emissivity) * tr ** 4
    if emitted <= 0.0:
        raise DiagnosisError("apparent %.1f C is below what emissivity %.2f reflects from %.1f C"
                             % (apparent, emissivity, ambient))
    return (emitted / emissivity) ** 0.25 - KELVIN


def diagnose(phases, ambient, rule, class_name=DEFAULT_CLASS):
    """Diagnosis of one device: ``phases`` {"A": degC, ...} (one to three), ``ambient`` degC or None.

    ``grade`` is GRADE_NONE or one of GRADES, ``rule`` the sentence saying which criterion fired (or
    why none could), ``delta_t`` in % (None when the relative method does not apply).
    """
    if not phases:
        raise DiagnosisError("no phase to diagnose")
    hot_phase = max(phases, key=lambda p: phases[p])
    t1 = float(phases[hot_phase])
    others = [float(t) for p, t in phases.items() if p != hot_phase]
    t2 = min(others) if others else None
    diff = t1 - t2 if t2 is not None else None
    rise = t1 - ambient if ambient is not None else None
    delta_t = None
    why_not = ""
    if t2 is None:
        why_not = "no sister phase to compare with"
    elif ambient is None:
        why_not = "no ambient box"
    elif rise < rule.min_rise:
        why_not = "rise %.1f K over ambient under %g K" % (rise, rule.min_rise)
    else:
        delta_t = 100.0 * diff / rise
    grade, fired = _grade(t1, diff, delta_t, rule)
    if fired:
        text = "%s defect (%s): %s" % (grade, class_name, fired)
    else:
        text = "no defect (%s)%s" % (class_name, "; relative method not applied: " + why_not if why_not else "")
    return Diagnosis(grade, text, hot_phase, t1, t2, ambient, rise, diff, delta_t, dict(phases))


def _grade(t1, diff, delta_t, rule):
    """(grade, the criterion that fired) for the most urgent grade whose criterion holds."""
    for grade, hot, delta in ((GRADE_CRITICAL, rule.critical_hot, rule.critical_delta),
                              (GRADE_SERIOUS, rule.serious_hot, rule.serious_delta)):
        if t1 > hot:
            return grade, "hot spot %.1f C > %g C" % (t1, hot)
        if delta_t is not None and delta_t >= delta:
            return grade, "dt %.0f %% >= %g %%" % (delta_t, delta)
    if delta_t is not None and delta_t >= rule.general_delta:
        return GRADE_GENERAL, "dt %.0f %% >= %g %%" % (delta_t, rule.general_delta)
    if diff is not None and diff > rule.general_diff:
        return GRADE_GENERAL, "%.1f K over the coolest phase > %g K" % (diff, rule.general_diff)
    return GRADE_NONE, ""


def thermal_groups(entries):
    """The devices of a preset's thermal targets: {device: (phases {phase: index}, ambient index or
    None)} from ``entries`` [(index, phase, device)] (phase "": a box not diagnosed). A device
    without its own ambient box uses the preset's (device ""). DiagnosisError for a phase given
    twice in one device, or two ambient boxes for one device."""
    phases, ambients = OrderedDict(), {}
    for index, phase, device in entries:
        if not phase:
            continue
        if phase == AMBIENT:
            if device in ambients:
                raise DiagnosisError("device '%s' has two ambient boxes (targets %d and %d)"
                                     % (device, ambients[device], index))
            ambients[device] = index
            continue
        group = phases.setdefault(device, OrderedDict())
        if phase in group:
            raise DiagnosisError("device '%s' has phase %s twice (targets %d and %d)"
                                 % (device, phase, group[phase], index))
        group[phase] = index
    return OrderedDict((device, (group, ambients.get(device, ambients.get(""))))
                       for device, group in phases.items())
