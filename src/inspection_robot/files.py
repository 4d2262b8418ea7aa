"""Files on the robot: path confinement, atomic writes, JSON state files. One error type.

Every module that takes a path from a caller or saves a file other code may read goes through here:

- ``confine_path(path, roots)``: resolve a caller's path (after symlinks and ``..``) and require it
  to lie inside one of the allowed roots, so a command can never read or write elsewhere;
- ``write_atomic(path, data)``: the data goes to a hidden temporary file in the target's folder, is
  flushed and fsynced, and is renamed over the target; the folder is fsynced so the rename survives
  a power cut. A reader or a crash sees the old file or the new one, never half of one; a failed
  write leaves no temporary file behind;
- ``write_json_atomic`` / ``read_json``: small JSON state files (virtual obstacles, last pose).

Every failure raises :class:`FileError` (a CommandError, so a command handler that lets it pass
fails that one request with the message as the reason).
"""
import json
import os
import tempfile

from inspection_robot.command import CommandError


class FileError(CommandError):
    """A path outside the roots, or a file that cannot be read or written; the message says which."""


def confine_path(path, roots):
    """Resolve ``path`` and require it to lie inside one of ``roots`` (after symlinks and ``..``).

    Returns the absolute real path. Relative paths are taken relative to the first root.
    """
    if not isinstance(path, str) or not path:
        raise FileError("empty path")
    if "\x00" in path:
        raise FileError("path contains a NUL byte")
    if not roots:
        raise FileError("no allowed roots configured")
    real_roots = [os.path.realpath(os.path.expanduser(r)) for r in roots]
    candidate = os.path.expanduser(path)
    if not os.path.isabs(candidate):
        candidate = os.path.join(real_roots[0], candidate)
    resolved = os.path.realpath(candidate)
    for root in real_roots:
        if resolved == root or resolved.startswith(root + os.sep):
            return resolved
    raise FileError("path '%s' is outside the allowed roots (%s)" % (path, ", ".join(real_roots)))


def write_atomic(path, data):
    """Write ``data`` (str or bytes) to ``path``, creating its folder; FileError (nothing changed) on failure."""
    if not isinstance(data, (str, bytes)):
        raise TypeError("write_atomic needs str or bytes, got %s" % type(data).__name__)
    folder = os.path.dirname(os.path.abspath(path))
    try:
        os.makedirs(folder, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", suffix=".tmp", dir=folder)
    except OSError as err:
        raise FileError("cannot write '%s': %s" % (path, err.strerror or err))
    try:
        with os.fdopen(fd, "wb" if isinstance(data, bytes) else "w") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError as err:
        _remove_quietly(tmp)
        raise FileError("cannot write '%s': %s" % (path, err.strerror or err))
    except BaseException:
        _remove_quietly(tmp)
        raise
    try:  # make the rename itself durable
        dir_fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(dir_fd)
    except OSError:
        pass  # the data is in place; only the folder's durability is not confirmed
    finally:
        os.close(dir_fd)


def _remove_quietly(path):
    try:
        os.unlink(path)
    except OSError:
        pass


def write_json_atomic(path, value):
    write_atomic(path, json.dumps(value, sort_keys=True))


def read_json(path):
    """The parsed file, or None when it does not exist. FileError on a corrupt or unreadable file."""
    try:
        with open(path) as f:
            return json.load(f)
    except FileNotFoundError:
        return None
    except OSError as err:
        raise FileError("cannot read '%s': %s" % (path, err.strerror or err))
    except ValueError as err:
        raise FileError("'%s' is not valid JSON: %s" % (path, err))


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
