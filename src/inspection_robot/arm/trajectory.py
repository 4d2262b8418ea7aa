"""Arm trajectory files (record_orbit / play_orbit).

Format (UTF-8 text, one sample per line, comma separated, no spaces)::

    # inspection_robot arm trajectory v1
    # rate_hz=20.0
    t_s,x_mm,y_mm,z_mm,roll_deg,pitch_deg,yaw_deg
    0.000,100.00,0.00,300.00,0.00,10.00,0.00
    0.050,101.20,0.00,300.00,0.00,10.00,0.00

Line 1 is the magic line; other ``#`` lines are comments; the column header is required. t_s is
seconds since the first sample, non-decreasing; the pose is in the arm base frame (mm, deg).
"""
import math
import os
from collections import namedtuple

from inspection_robot.files import FileError, write_atomic

MAGIC = "# inspection_robot arm trajectory v1"
COLUMNS = "t_s,x_mm,y_mm,z_mm,roll_deg,pitch_deg,yaw_deg"
MAX_SAMPLES = 200000
MAX_BYTES = 32 * 1024 * 1024

Sample = namedtuple("Sample", "t position orientation")


class TrajectoryError(Exception):
    """A trajectory file that cannot be read or written; the message names file and line."""


def dumps(samples, rate_hz):
    lines = [MAGIC, "# rate_hz=%g" % rate_hz, COLUMNS]
    for s in samples:
        lines.append(",".join(["%.3f" % s.t] + ["%.2f" % v for v in tuple(s.position) + tuple(s.orientation)]))
    return "\n".join(lines) + "\n"


def save(path, samples, rate_hz):
    """Write atomically (temporary file + rename): a reader never sees half a trajectory."""
    try:
        write_atomic(path, dumps(samples, rate_hz))
    except FileError as err:
        raise TrajectoryError("cannot write %s: %s" % (path, err))


def loads(text, name="trajectory"):
    lines = text.splitlines()
    if not lines or lines[0].strip() != MAGIC:
        raise TrajectoryError("%s: not an arm trajectory (first line must be '%s')" % (name, MAGIC))
    body = [(n, line) for n, line in enumerate(lines[1:], 2) if line.strip() and not line.startswith("#")]
    if not body or body[0][1].strip() != COLUMNS:
        raise TrajectoryError("%s: missing column header '%s'" % (name, COLUMNS))
    samples = []
    for number, line in body[1:]:
        fields = line.strip().split(",")
        if len(fields) != 7:
            raise TrajectoryError("%s line %d: expected 7 values, got %d" % (name, number, len(fields)))
        try:
            values = [float(f) for f in fields]
        except ValueError:
            raise TrajectoryError("%s line %d: not a number in '%s'" % (name, number, line.strip()))
        if not all(math.isfinite(v) for v in values):
            raise TrajectoryError("%s line %d: non-finite value" % (name, number))
        if values[0] < 0 or (samples and values[0] < samples[-1].t):
            raise TrajectoryError("%s line %d: time must be >= 0 and non-decreasing" % (name, number))
        samples.append(Sample(values[0], tuple(values[1:4]), tuple(values[4:7])))
        if len(samples) > MAX_SAMPLES:
            raise TrajectoryError("%s: more than %d samples" % (name, MAX_SAMPLES))
    if not samples:
        raise TrajectoryError("%s: no samples" % name)
    return samples


def load(path):
    try:
        if os.path.getsize(path) > MAX_BYTES:
            raise TrajectoryError("%s: larger than %d bytes" % (path, MAX_BYTES))
        with open(path, encoding="utf-8") as f:
            return loads(f.read(), path)
    except (OSError, UnicodeDecodeError) as err:
        raise TrajectoryError("cannot read %s: %s" % (path, err))


def reversed_samples(samples):
    """The same path backwards in time: t' = T - t."""
    end = samples[-1].t
    return [Sample(end - s.t, s.position, s.orientation) for s in reversed(samples)]
