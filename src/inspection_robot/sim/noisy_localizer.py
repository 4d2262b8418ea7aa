"""A simulated localizer: the chassis simulator's true pose with gaussian noise, a rate and a latency,
so move_base in simulation drives on poses like a real lidar localizer's, not on ground truth.

Defaults (config/sim_localizer.yaml) are those of a good lidar localizer in a fenced yard: σ 0.02 m
per axis, σ 0.5° in heading, 10 Hz, 50 ms late. The published covariance is the noise it adds, so
move_base's covariance check sees what it would see from amcl. ``initialpose`` is ignored: like
ground truth, this localizer is never lost.
"""
import collections
import math
import random

from inspection_robot.angles import wrap_angle
from inspection_robot.nav.pose_adapter import planar_covariance


class NoisyLocalizer(object):
    def __init__(self, sigma_xy, sigma_yaw, latency, seed=None):
        for name, value in (("sigma_xy", sigma_xy), ("sigma_yaw", sigma_yaw), ("latency", latency)):
            if not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
                raise ValueError("~%s must be a number >= 0, got %r" % (name, value))
        self.sigma_xy, self.sigma_yaw, self.latency = float(sigma_xy), float(sigma_yaw), float(latency)
        self.covariance = planar_covariance(self.sigma_xy, self.sigma_yaw)
        self._rng = random.Random(seed)
        self._truth = collections.deque()   # (arrival, stamp, (x, y, yaw)), oldest first
        self._last_stamp = None

    def add(self, now, stamp, pose):
        """A true pose that arrived at ``now`` (carrying ``stamp``); non-finite ones are dropped."""
        if all(math.isfinite(v) for v in pose):
            self._truth.append((now, stamp, tuple(pose)))

    def output(self, now):
        """(stamp, (x, y, yaw)) to publish now: the newest true pose at least ``latency`` old, with
        noise; None when there is no new one (a stopped simulator stops this localizer too)."""
        ready = None
        while self._truth and self._truth[0][0] <= now - self.latency:
            ready = self._truth.popleft()
        if ready is None or ready[1] == self._last_stamp:
            return None
        self._last_stamp = ready[1]
        x, y, yaw = ready[2]
        gauss = self._rng.gauss
        return ready[1], (x + gauss(0.0, self.sigma_xy), y + gauss(0.0, self.sigma_xy),
                          wrap_angle(yaw + gauss(0.0, self.sigma_yaw)))
