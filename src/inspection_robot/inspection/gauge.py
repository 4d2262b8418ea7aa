"""Pointer-gauge maths: needle angle <-> reading, linear or through a non-linear scale table.

Angles are in degrees in the gauge's frontal (rectified) view, measured CLOCKWISE from 12 o'clock
(straight up), in [0, 360). A gauge sweeps clockwise from ``start_angle`` (value ``start_value``)
to ``end_angle`` (value ``end_value``); the sweep may cross 12 o'clock (wrap-around), e.g. start
225 (7:30) and end 135 (4:30) is the classic 270-degree dial. A non-linear scale is a table of
(value, angle) marks, piecewise linear between them, in increasing sweep order.
"""
import math


def wrap360(angle):
    """Angle in degrees wrapped to [0, 360)."""
    a = math.fmod(float(angle), 360.0)
    return a + 360.0 if a < 0 else a


def angle_diff(a, b):
    """Signed smallest difference a - b in degrees, in (-180, 180]."""
    d = wrap360(a - b)
    return d - 360.0 if d > 180.0 else d


class GaugeScale(object):
    """Maps needle angles to values for one pointer gauge.

    ``table``: optional [(value, angle), ...] marks of a non-linear scale, ordered along the
    sweep; when given, its first and last marks define the ends (start/end arguments are
    then only checked for consistency by the caller).
    """

    def __init__(self, start_angle, end_angle, start_value, end_value, table=None):
        self.start_angle = wrap360(start_angle)
        self.end_angle = wrap360(end_angle)
        sweep = wrap360(self.end_angle - self.start_angle)
        self.sweep = 360.0 if sweep == 0.0 else sweep
        self.start_value = float(start_value)
        self.end_value = float(end_value)
        if self.start_value == self.end_value:
            raise ValueError("start_value and end_value must differ")
        self._marks = None  # [(offset_deg along sweep, value)]
        if table:
            marks = [(self.offset(angle), float(value)) for value, angle in table]
            if len(marks) < 2:
                raise ValueError("a scale_table needs at least 2 marks")
            offsets = [m[0] for m in marks]
            if any(b <= a for a, b in zip(offsets, offsets[1:])):
                raise ValueError("scale_table angles must increase along the sweep from start_angle")
            values = [m[1] for m in marks]
            rising = values[-1] > values[0]
            if any((b <= a) if rising else (b >= a) for a, b in zip(values, values[1:])):
                raise ValueError("scale_table values must be monotonic")
            self._marks = marks
            self.start_value, self.end_value = values[0], values[-1]

    @property
    def full_scale(self):
        """Span of the scale in value units (always positive)."""
        return abs(self.end_value - self.start_value)

    def offset(self, angle):
        """Clockwise offset of ``angle`` from the start, in [0, 360)."""
        return wrap360(angle - self.start_angle)

    def clamp_offset(self, angle):
        """Offset along the sweep; an angle in the dead zone goes to the nearer end."""
        off = self.offset(angle)
        if off <= self.sweep:
            return off
        dead = 360.0 - self.sweep
        return self.sweep if off - self.sweep < dead / 2.0 else 0.0

    def in_sweep(self, angle, margin_deg=0.0):
        off = self.offset(angle)
        return off <= self.sweep + margin_deg or off >= 360.0 - margin_deg

    def value(self, angle):
        """Reading for a needle at ``angle`` (clamped to the scale's ends)."""
        off = self.clamp_offset(angle)
        if self._marks is None:
            return self.start_value + (self.end_value - self.start_value) * off / self.sweep
        marks = self._marks
        if off <= marks[0][0]:
            return marks[0][1]
        for (o0, v0), (o1, v1) in zip(marks, marks[1:]):
            if off <= o1:
                return v0 + (v1 - v0) * (off - o0) / (o1 - o0)
        return marks[-1][1]

    def entries(self):
        """The scale as [(value, angle)]: the table's marks, or the two ends of a linear scale."""
        if self._marks is None:
            return [(self.start_value, self.start_angle), (self.end_value, self.end_angle)]
        return [(value, wrap360(self.start_angle + offset)) for offset, value in self._marks]

    def angle(self, value):
        """Needle angle for ``value`` (clamped to the scale's ends); the inverse of value()."""
        value = float(value)
        if self._marks is None:
            t = (value - self.start_value) / (self.end_value - self.start_value)
            t = min(max(t, 0.0), 1.0)
            return wrap360(self.start_angle + t * self.sweep)
        marks = self._marks
        rising = marks[-1][1] > marks[0][1]
        lo, hi = (marks[0][1], marks[-1][1]) if rising else (marks[-1][1], marks[0][1])
        value = min(max(value, lo), hi)
        for (o0, v0), (o1, v1) in zip(marks, marks[1:]):
            if min(v0, v1) <= value <= max(v0, v1):
                return wrap360(self.start_angle + o0 + (o1 - o0) * (value - v0) / (v1 - v0))
        return wrap360(self.start_angle + marks[-1][0])

    def error_percent_fs(self, measured, truth):
        """Absolute error in percent of full scale."""
        return 100.0 * abs(float(measured) - float(truth)) / self.full_scale
