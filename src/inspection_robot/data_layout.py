"""The robot's data root: the folders under it and their owners, and the device capture roots in it.

Every file the robot writes lives under one data root per robot (``DATA_SUBDIRS``); a node's path
parameters are taken relative to it (``under``), and a node started outside core.launch falls back
to ``standalone_data_root``. A device's capture roots may never overlap a folder another node owns
(``capture_roots``), and ``CaptureQuota`` bounds the bytes they hold. Apart from files.py (paths,
atomic writes), whose FileError and ``inside`` it uses: this is where the files are, not how they
are written.
"""
import os
import threading
import time

from inspection_robot.files import FileError, inside

# --- one robot, one state directory -----------------------------------------------------------
# Every file the robot writes lives under its data root (the namespace parameter ``data_root``),
# in these sub-directories; a node's path parameters are relative to the root unless absolute.
DATA_SUBDIRS = {
    "nav": "virtual obstacles and the last good pose (move_base)",
    "arm": "arm trajectories (robot_arm, preset_scale)",
    "presets": "recorded presets and their calibration (preset_scale, find_scale, read_scale)",
    "pictures": "find_scale's pictures and read_scale's annotated results",
    "captures": "camera_node's capture_picture pictures given a relative path",
    "thermal": "infrared_imager's pictures and radiometric frames given a relative path",
    "voice_out": "robot_voice's output files in simulation",
    "tasks": "task_manager's tasks and results",
}


CAPTURE_SUBDIRS = ("captures", "thermal")   # written by the devices' capture commands; the rest by their owners


def capture_roots(roots, data_root):
    """``roots`` (absolute) checked as a device's capture roots: none may be, contain or lie inside
    a data-root folder another node owns (presets, pictures, tasks, ...), so no capture can ever
    replace a preset or a result. ValueError naming the root otherwise; returns ``roots``."""
    owned = [os.path.realpath(os.path.join(data_root, d)) for d in sorted(DATA_SUBDIRS) if d not in CAPTURE_SUBDIRS]
    for root in roots:
        real = os.path.realpath(root)
        for folder in owned:
            if inside(real, [folder]) or inside(folder, [real]):
                raise ValueError("capture root %s overlaps %s, which only its owner writes (%s); use captures, "
                                 "thermal or a folder outside the data root's owned folders"
                                 % (root, folder, DATA_SUBDIRS[os.path.basename(folder)]))
    return list(roots)


DEFAULT_CAPTURE_QUOTA_MIB = 2048        # 2 GiB per device's capture roots (camera_node, infrared_imager ~quota_mib)
QUOTA_RESCAN_S = 60.0                    # the usage is counted again at most this old (files deleted meanwhile)
STAGED_RESERVE_BYTES = 256 << 20         # beyond the quota, for the owners' staged pictures (moved away at once)


class CaptureQuota(object):
    """The bytes a device's capture roots may hold, every file counted (hidden ones too: staged
    pictures, a client's leftovers). A full walk of the roots is what a capture would otherwise cost
    each time; here the roots are walked once, then each write adds its size, and the count is
    taken again when older than ``rescan_s`` or before a capture is refused (so files deleted
    meanwhile count at once). A staged picture (staged_name: preset_scale's and find_scale's, moved
    out of the roots at once) may use STAGED_RESERVE_BYTES beyond the quota, so captures a backend
    left behind do not stop recordings and patrols. Thread-safe. ``limit_bytes`` 0: no quota."""

    def __init__(self, roots, limit_bytes=DEFAULT_CAPTURE_QUOTA_MIB << 20, rescan_s=QUOTA_RESCAN_S,
                 clock=time.monotonic):
        if isinstance(limit_bytes, bool) or not isinstance(limit_bytes, int) or limit_bytes < 0:
            raise ValueError("capture quota must be a whole number of bytes >= 0 (0: none), got %r" % (limit_bytes,))
        self.roots = list(roots)
        self.limit = limit_bytes
        self._rescan_s = float(rescan_s)
        self._clock = clock
        self._lock = threading.Lock()
        self._used = None
        self._counted_at = None

    @classmethod
    def from_mib(cls, roots, mib):
        """A quota of ``mib`` MiB (a node's ~quota_mib: ROS parameters are 32-bit integers, 2 GiB in
        bytes is not one); ValueError unless a whole number >= 0."""
        if isinstance(mib, bool) or not isinstance(mib, int) or mib < 0:
            raise ValueError("~quota_mib must be a whole number of MiB >= 0 (0: none), got %r" % (mib,))
        return cls(roots, mib << 20)

    def used(self, fresh=False):
        """Bytes in the roots (counted again when ``fresh`` or when the count is older than rescan_s)."""
        with self._lock:
            if fresh or self._used is None or self._clock() - self._counted_at > self._rescan_s:
                self._used = sum(tree_bytes(root) for root in self.roots)
                self._counted_at = self._clock()
            return self._used

    def check(self, size, what="the capture", staged=False):
        """FileError, before anything is written, when ``size`` more bytes would exceed the quota (a
        ``staged`` picture: the quota and STAGED_RESERVE_BYTES)."""
        limit = self.limit + (STAGED_RESERVE_BYTES if staged else 0)
        if not self.limit or self.used() + size <= limit:
            return
        used = self.used(fresh=True)
        if used + size > limit:
            raise FileError("capture quota exceeded: the capture folders hold %d of %d bytes and %s needs %d; "
                            "delete old captures (nothing written)" % (used, limit, what, size))

    def add(self, size):
        """Count ``size`` bytes just written."""
        with self._lock:
            if self._used is not None:
                self._used += size


def tree_bytes(folder):
    """The size of every file below ``folder`` (links not followed, unreadable folders skipped)."""
    total = 0
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return 0
    for entry in entries:
        try:
            if entry.is_dir(follow_symlinks=False):
                total += tree_bytes(entry.path)
            elif entry.is_file(follow_symlinks=False):
                total += entry.stat(follow_symlinks=False).st_size
        except OSError:   # removed while counting
            continue
    return total


def under(root, path):
    """``path`` (``~`` expanded) taken relative to ``root``; an absolute path is kept as it is."""
    path = os.path.expanduser(str(path))
    return path if os.path.isabs(path) else os.path.normpath(os.path.join(root, path))


def standalone_data_root(environ, namespace):
    """The data root of a node started without the ``data_root`` parameter (outside core.launch):
    ``$ROS_HOME/inspection_robot/<namespace>`` (ROS_HOME defaults to ~/.ros), one per namespace."""
    ros_home = environ.get("ROS_HOME") or os.path.join(os.path.expanduser("~"), ".ros")
    name = namespace.strip("/").replace("/", "_") or "robot"
    return os.path.join(ros_home, "inspection_robot", name)
