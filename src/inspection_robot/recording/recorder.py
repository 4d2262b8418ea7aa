"""Pure logic of bag_recorder: the recorded topic set, the ``rosbag record`` command line, the disk
budget (oldest closed bags go first, never the one being written) and the disk-full verdict.

Bags are written by Debian's/Noetic's ``rosbag record`` (a child process); this module only decides
what it is told and what is deleted. Every topic is named in full (interface.INTERFACE_TOPICS,
resolved in the robot's namespace): rosbag record then subscribes to each at its start, and the
master tells it about a publisher that appears later (a backend advertising server_status or
mode_cmd over the websocket) as it tells every other subscriber, so the recorder connects as soon
as the robot's own nodes do and misses nothing. In ``--regex`` mode it would only poll the master
(about once a second) and lose what a backend sends in its first second.
"""
import os

from inspection_robot.camera.jpeg import COMPRESSED_SUFFIX
from inspection_robot.interface import INTERFACE_TOPICS

# Raw images never go into a bag (about 1 MB each); with record_images they are recorded as the
# JPEG CompressedImage topics the camera and thermal nodes publish at ``<topic>/compressed``.
IMAGE_SUFFIX = COMPRESSED_SUFFIX
BAG_SUFFIX = ".bag"
ACTIVE_SUFFIX = ".bag.active"   # rosbag record's name for the file it is writing


class RecorderError(ValueError):
    """A recorder parameter that cannot work (negative size, empty directory...)."""


def recorded_topics(namespace, image_topics=(), extra_topics=()):
    """Absolute names of every recorded topic: the interface topics, ``extra_topics`` and the JPEG
    ``<topic>/compressed`` of each of ``image_topics``, all relative to ``namespace`` (a leading
    ``/`` is ignored, as for every interface topic), without duplicates, in that order."""
    ns = "/" + namespace.strip("/") + "/" if namespace.strip("/") else "/"
    names = list(INTERFACE_TOPICS) + list(extra_topics) + [t.rstrip("/") + IMAGE_SUFFIX for t in image_topics]
    out = []
    for name in names:
        relative = str(name).strip().strip("/")
        if not relative or any(c.isspace() for c in relative) or "//" in relative:
            raise RecorderError("topic name %r cannot be recorded" % (name,))
        full = ns + relative
        if full.endswith("image_raw"):
            raise RecorderError("%s: raw images are never recorded (set ~record_images, recorded as JPEG)" % full)
        if full not in out:
            out.append(full)
    return out


def record_command(directory, prefix, namespace, split_size_mb, min_free_mb, image_topics=(),
                   extra_topics=(), executable="record"):
    """argv of rosbag's ``record`` executable (``executable``: its path) for recorded_topics. The C++
    executable is run directly: the ``rosbag record`` wrapper cannot pass ``--min-space``, whose
    default (1 GB) would silently stop a bag."""
    if not directory:
        raise RecorderError("bag directory is empty")
    if split_size_mb <= 0:
        raise RecorderError("split_size_mb must be positive, got %r" % (split_size_mb,))
    if min_free_mb < 0:
        raise RecorderError("min_free_mb must not be negative, got %r" % (min_free_mb,))
    topics = recorded_topics(namespace, image_topics, extra_topics)
    return [executable, "--lz4", "--repeat-latched", "--split", "--size", str(int(split_size_mb)),
            "--min-space", "%dM" % int(min_free_mb),
            "-o", os.path.join(directory, prefix), "__name:=%s_record" % prefix] + topics


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
