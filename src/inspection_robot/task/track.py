"""The path a task drove: the robot's poses, thinned, for the report's map and its distance driven.

task_manager hands every pose of robot_status (the localiser's pose in the map frame) to the
active task's PathThinner; a pose is kept when the robot has moved ``min_step_m`` (0.5 m) from the
last kept one, or turned ``min_turn_rad`` (0.5 rad), or ``period_s`` (5 s) passed and it moved at
all (more than ``still_m``, 2 cm): a drive gives a point every half metre, a turn on the spot its
headings, standing still nothing. The first pose of a task is always kept, and its last when it
ends. Kept poses wait in a
bounded buffer until the node stores them (``take``, a few times a second; a full buffer drops its
oldest and counts them, see ``dropped``). The distance driven is the kept path's length: on a
curve the half-metre chords miss under 1 % for radii above 1.5 m.
Pure module: no ROS, no store.
"""
import math
from collections import namedtuple

TrackConfig = namedtuple("TrackConfig", "min_step_m min_turn_rad period_s still_m buffer")
DEFAULT_TRACK = TrackConfig(min_step_m=0.5, min_turn_rad=0.5, period_s=5.0, still_m=0.02, buffer=2000)


def _turn(a, b):
    return abs(math.atan2(math.sin(a - b), math.cos(a - b)))


class PathThinner(object):
    """The kept poses of one task, (unix s, x, y, yaw), waiting to be stored."""

    def __init__(self, task_id, config=DEFAULT_TRACK):
        self.task_id = task_id
        self.config = config
        self._last = None
        self._tail = None     # the newest pose offered when it was not kept: the path's end
        self._pending = []
        self.dropped = 0

    def add(self, t, x, y, yaw):
        """Offer one pose; True when it is kept. Non-finite poses are ignored."""
        if not all(math.isfinite(v) for v in (t, x, y, yaw)):
            return False
        if self._last is not None:
            lt, lx, ly, lyaw = self._last
            moved = math.hypot(x - lx, y - ly)
            if not (moved >= self.config.min_step_m or _turn(yaw, lyaw) >= self.config.min_turn_rad
                    or (t - lt >= self.config.period_s and moved > self.config.still_m)):
                self._tail = (t, x, y, yaw)
                return False
        self._last, self._tail = (t, x, y, yaw), None
        self._pending.append(self._last)
        if len(self._pending) > self.config.buffer:
            del self._pending[0]
            self.dropped += 1
        return True

    @property
    def pending(self):
        """How many kept poses wait to be stored."""
        return len(self._pending)

    def take(self, final=False):
        """The kept poses not yet taken, oldest first (the caller stores them); ``final`` (the task
        ended) adds the newest pose offered if it was not kept, so the path reaches where the task ended."""
        if final and self._tail is not None:
            self._pending.append(self._tail)
            self._last, self._tail = self._tail, None
        out, self._pending = self._pending, []
        return out

    def give_back(self, poses):
        """Poses ``take`` returned that could not be stored: kept for the next try (bounded)."""
        self._pending = list(poses) + self._pending
        excess = len(self._pending) - self.config.buffer
        if excess > 0:
            del self._pending[:excess]
            self.dropped += excess


def path_length(path):
    """Length (m) of a path [(t, x, y, yaw)] as driven, segment by segment."""
    return sum(math.hypot(b[1] - a[1], b[2] - a[2]) for a, b in zip(path, path[1:]))
