"""Files on the robot: path confinement, atomic writes, JSON state files. One error type.

Every module that takes a path from a caller or saves a file other code may read goes through here:

- ``confine_path(path, roots)``: resolve a caller's path (after symlinks and ``..``) and require it
  to lie inside one of the allowed roots, so a command can never read or write elsewhere;
- ``write_atomic(path, data)``: the data goes to a hidden temporary file in the target's folder, is
  flushed and fsynced, and is renamed over the target; the folder is fsynced so the rename survives
  a power cut. A reader or a crash sees the old file or the new one, never half of one; a failed
  write leaves no temporary file behind;
- ``DirUpdate(folder)``: several files of one folder changed at once (a preset's calibration): the
  changes go into a hard-linked copy beside it that replaces the folder in one atomic rename, so
  a reader or a crash sees all of them or none;
- ``write_json_atomic`` / ``read_json``: small JSON state files (virtual obstacles, last pose).

Every failure raises :class:`FileError` (a CommandError, so a command handler that lets it pass
fails that one request with the message as the reason).
"""
import ctypes
import errno
import json
import os
import shutil
import stat
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
    fsync_dir(folder)   # make the rename itself durable (best effort: the data is in place)


def fsync_dir(folder, strict=False):
    """fsync a folder so the names in it (a rename, a new file) survive a power cut.

    ``strict``: an OSError is raised; otherwise a failure returns False (the folder's durability is
    not confirmed, the data is in place).
    """
    try:
        dir_fd = os.open(folder, os.O_RDONLY)
    except OSError:
        if strict:
            raise
        return False
    try:
        os.fsync(dir_fd)
    except OSError:
        if strict:
            raise
        return False
    finally:
        os.close(dir_fd)
    return True


_RENAME_EXCHANGE = 2      # linux/fs.h
_AT_FDCWD = -100


def _exchange(a, b):
    """Swap two paths in one atomic step (renameat2 RENAME_EXCHANGE, Linux >= 3.15, glibc >= 2.28).
    OSError ENOSYS when the C library lacks it, EINVAL when the file system does."""
    libc = ctypes.CDLL(None, use_errno=True)
    renameat2 = getattr(libc, "renameat2", None)
    if renameat2 is None:
        raise OSError(errno.ENOSYS, "renameat2 not available")
    renameat2.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    if renameat2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) != 0:
        code = ctypes.get_errno()
        raise OSError(code, os.strerror(code), a)


class DirUpdate(object):
    """Changes to a folder made all at once: nobody ever sees some of them without the others.

    A hidden sibling (``.<name>.update.<random>``) is filled with hard links to the folder's
    entries (copies where a link is refused); the changes are written into it (``file(name)``,
    with write_atomic, which fsyncs each file); ``commit()`` fsyncs it and swaps it with the folder
    in one atomic rename (renameat2 RENAME_EXCHANGE), fsyncs the parent, and removes the old
    content. Leaving the block without commit (an exception) removes the sibling: the folder is
    untouched. Where the file system cannot exchange, the folder is first renamed aside and the
    copy renamed in, and the old one renamed back if that fails (a power cut between the two
    renames leaves the old folder under the hidden ``.<name>.old.<random>`` name). Files in the
    folder are replaced, never written in place, so a link shared with the old content is safe.

        with DirUpdate(path) as update:
            write_atomic(update.file("a.ini"), text)
            update.commit()
    """

    def __init__(self, folder):
        self.folder = os.path.abspath(folder)
        parent, name = os.path.split(self.folder)
        if not os.path.isdir(self.folder):
            raise FileError("no such directory: '%s'" % folder)
        self.path = None
        self.committed = False
        try:
            self.path = tempfile.mkdtemp(prefix=".%s.update." % name, dir=parent)
            os.chmod(self.path, stat.S_IMODE(os.stat(self.folder).st_mode))
            _link_tree(self.folder, self.path)
        except OSError as err:
            self.abort()
            raise FileError("cannot stage a copy of '%s': %s" % (folder, err.strerror or err))

    def file(self, name):
        return os.path.join(self.path, name)

    def commit(self):
        try:
            fsync_dir(self.path, strict=True)
            try:
                _exchange(self.path, self.folder)
            except OSError as err:
                if err.errno not in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP):
                    raise
                self._two_renames()
        except OSError as err:
            raise FileError("cannot replace '%s': %s (it is unchanged)" % (self.folder, err.strerror or err))
        self.committed = True
        fsync_dir(os.path.dirname(self.folder))
        shutil.rmtree(self.path, ignore_errors=True)   # now the old content

    def _two_renames(self):
        aside = self.path.replace(".update.", ".old.", 1)
        os.rename(self.folder, aside)
        try:
            os.rename(self.path, self.folder)
        except OSError:
            os.rename(aside, self.folder)
            raise
        self.path = aside

    def abort(self):
        if self.path and not self.committed:
            shutil.rmtree(self.path, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if not self.committed:
            self.abort()
        return False


def _link_tree(source, target):
    for entry in os.scandir(source):
        destination = os.path.join(target, entry.name)
        if entry.is_symlink():
            os.symlink(os.readlink(entry.path), destination)
        elif entry.is_dir():
            os.mkdir(destination)
            shutil.copystat(entry.path, destination)
            _link_tree(entry.path, destination)
        else:
            try:
                os.link(entry.path, destination)
            except OSError:   # hard links refused (fs.protected_hardlinks, a file system without them)
                shutil.copy2(entry.path, destination)


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
