"""Pure logic of bag_recorder: the recorded topic set, the ``rosbag record`` command line, the disk
budget (oldest closed bags go first, never the one being written) and the disk-full verdict.

Bags are written by Debian's/Noetic's ``rosbag record`` (a child process); this module only decides
what it is told and what is deleted. Topic names are regular expressions over *resolved* names
(the robot's namespace is a prefix), so a topic that appears later (e.g. the task topics) is
picked up when it is advertised (rosbag record polls the master in regex mode).
"""
import os
import re

# The interface topics (relative names; docs/operations.md "Recording"). Regex fragments.
INTERFACE_TOPICS = (
    "robot_status", "control_status", "nav_status", "robot_odom", "odom", "tf", "tf_static",
    "server_status", "diagnostics", "obstacle_status", "plan", "map", "virtual_obstacle_map",
    "virtual_obstacles",
    "move_action/.*", "find_scale_action/.*", "task_action/.*",
    "[A-Za-z0-9_]+_cmd", "[A-Za-z0-9_]+_ack",
    "task_status", "charge_status",
    "terrace_state", "camera_zoom", "client_count",
)
# Raw images never go into a bag (about 1 MB each); with record_images they are recorded as the
# JPEG CompressedImage topics that bag_recorder publishes at ``<topic>/compressed``.
IMAGE_SUFFIX = "/compressed"
BAG_SUFFIX = ".bag"
ACTIVE_SUFFIX = ".bag.active"   # rosbag record's name for the file it is writing


class RecorderError(ValueError):
    """A recorder parameter that cannot work (negative size, empty directory...)."""


def topic_pattern(namespace, names):
    """One anchored regex matching every name in ``names`` (regex fragments) under ``namespace``."""
    ns = "/" + namespace.strip("/") if namespace.strip("/") else ""
    return "^%s/(%s)$" % (re.escape(ns), "|".join(names))


def record_command(directory, prefix, namespace, split_size_mb, min_free_mb, image_topics=(),
                   extra_topics=(), executable="record"):
    """argv of rosbag's ``record`` executable (``executable``: its path) for the interface topics
    (+ the compressed ``image_topics``). The C++ executable is run directly: the ``rosbag record``
    wrapper cannot pass ``--min-space``, whose default (1 GB) would silently stop a bag."""
    if not directory:
        raise RecorderError("bag directory is empty")
    if split_size_mb <= 0:
        raise RecorderError("split_size_mb must be positive, got %r" % (split_size_mb,))
    if min_free_mb < 0:
        raise RecorderError("min_free_mb must not be negative, got %r" % (min_free_mb,))
    names = list(INTERFACE_TOPICS) + [re.escape(t.strip("/")) for t in extra_topics]
    names += [re.escape(t.strip("/") + IMAGE_SUFFIX) for t in image_topics]
    return [executable, "--regex", topic_pattern(namespace, names),
            "--exclude", ".*image_raw$",      # never a raw image, whatever a regex matches
            "--lz4", "--repeat-latched", "--split", "--size", str(int(split_size_mb)),
            "--min-space", "%dM" % int(min_free_mb),
            "-o", os.path.join(directory, prefix), "__name:=%s_record" % prefix]


def list_bags(directory):
    """(path, size_bytes, mtime, active) of every bag in ``directory``, oldest first."""
    try:
        names = os.listdir(directory)
    except FileNotFoundError:
        return []
    bags = []
    for name in names:
        if not (name.endswith(BAG_SUFFIX) or name.endswith(ACTIVE_SUFFIX)):
            continue
        path = os.path.join(directory, name)
        try:
            st = os.stat(path)
        except FileNotFoundError:   # rosbag renamed it (.active -> .bag) meanwhile
            continue
        bags.append((path, st.st_size, st.st_mtime, name.endswith(ACTIVE_SUFFIX)))
    bags.sort(key=lambda b: (b[2], b[0]))
    return bags


def bags_to_delete(bags, budget_bytes):
    """Oldest closed bags to delete so that the folder's bags fit ``budget_bytes``.

    ``bags`` as list_bags returns them. A bag being written (``.bag.active``) is never chosen: when
    it alone exceeds the budget, every closed bag goes and the active one stays.
    """
    total = sum(b[1] for b in bags)
    doomed = []
    for path, size, _mtime, active in bags:
        if total <= budget_bytes:
            break
        if active:
            continue
        doomed.append(path)
        total -= size
    return doomed


def enforce_budget(directory, budget_bytes, remove=os.remove):
    """Delete the oldest closed bags over budget; returns (deleted paths, errors as text)."""
    deleted, errors = [], []
    for path in bags_to_delete(list_bags(directory), budget_bytes):
        try:
            remove(path)
            deleted.append(path)
        except FileNotFoundError:
            pass
        except OSError as exc:
            errors.append("cannot delete %s: %s" % (path, exc.strerror or exc))
    return deleted, errors


def disk_verdict(free_bytes, min_free_bytes):
    """None when recording may go on, else the reason it must stop (disk full)."""
    if free_bytes < min_free_bytes:
        return "disk full: %.0f MB free, below the %.0f MB minimum" % (free_bytes / 1e6, min_free_bytes / 1e6)
    return None


def compress_image(data, width, height, step, encoding, quality=80):
    """JPEG bytes of a raw sensor_msgs/Image's fields; RecorderError for an encoding we do not know."""
    import cv2
    import numpy as np
    channels = {"bgr8": 3, "rgb8": 3, "mono8": 1}.get(encoding)
    if channels is None:
        raise RecorderError("image encoding %r not supported (bgr8, rgb8, mono8)" % (encoding,))
    if step < width * channels or len(data) < step * height:
        raise RecorderError("image of %d bytes is too short for %dx%d step %d" % (len(data), width, height, step))
    rows = np.frombuffer(bytes(data), np.uint8)[:step * height].reshape(height, step)
    img = rows[:, :width * channels].reshape(height, width, channels)
    if encoding == "rgb8":
        img = img[:, :, ::-1]
    ok, jpeg = cv2.imencode(".jpg", np.ascontiguousarray(img), [int(cv2.IMWRITE_JPEG_QUALITY), int(quality)])
    if not ok:
        raise RecorderError("JPEG encoding failed for a %dx%d %s image" % (width, height, encoding))
    return jpeg.tobytes()
