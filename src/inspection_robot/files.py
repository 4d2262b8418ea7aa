"""Files on the robot: path confinement, atomic writes, JSON state files. One error type.

Every module that takes a path from a caller or saves a file other code may read goes through here:

- ``confine_path(path, roots)``: resolve a caller's path (after symlinks and ``..``) and require it
  to lie inside one of the allowed roots, so a command can never read or write elsewhere;
  ``new_file_path`` adds what a command that creates a file needs: no ``..``, not a folder, not
  an existing file;
- ``write_atomic(path, data)``: the data goes to a hidden temporary file in the target's folder, is
  flushed and fsynced, and is put in place with ``rename_durable`` (or, with ``replace=False``,
  hard-linked, which fails on an existing file); the folder is fsynced so the rename survives a
  power cut. A reader or a crash sees the old file or the new one, never half of one; a failed
  write leaves no temporary file behind;
- ``rename_durable(src, dst)``: the one rename of product data (preset commits, files set aside):
  the rename, then an fsync of the folder(s) it changed (``fsync_dir``);
- ``write_json_atomic`` / ``read_json``: small JSON state files (virtual obstacles, last pose);
- ``read_secret_file(path, setting)``: a token or password kept out of parameters and command lines
  (``ps`` shows those), in a file only the robot's user may read.

Beside it: dir_update.py (``DirUpdate``: several files of one folder changed at once) and
data_layout.py (the data root's folders, path parameters under it, the capture roots and their quota).

Every failure raises :class:`FileError` (a CommandError, so a command handler that lets it pass
fails that one request with the message as the reason). Messages name a path as the caller gave
it (control characters escaped, long paths shortened).
"""
import errno
import json
import os
import re
import stat
import tempfile
import uuid

from inspection_robot.command import CommandError

MAX_PATH_BYTES = 4095   # Linux PATH_MAX less the NUL: longer paths fail in the OS anyway, less clearly
MAX_NAME_BYTES = 255    # Linux NAME_MAX, per path component
SHOWN_PATH_CHARS = 120  # a path quoted in a message is cut after this many characters


class FileError(CommandError):
    """A path outside the roots, or a file that cannot be read or written; the message says which."""


def shown(path):
    """``path`` fit for a one-line message: control characters escaped, cut when very long."""
    text = "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(path))
    if len(text) > SHOWN_PATH_CHARS:
        text = "%s...(%d characters)" % (text[:SHOWN_PATH_CHARS], len(path))
    return text


def hide_root(text, data_root):
    """A failure reason fit for a client: ``data_root``'s location (as given and resolved) taken out.

    Paths inside it become data-root-relative, as file_control names them (``presets/p1/...``), the
    root itself ``.``. Every node's refusals pass through here (ros/twin.py and the action and topic
    nodes), so no reason, whatever it quotes (a resolved path, an OS error), tells a client on the
    station network where the robot keeps its files.
    """
    text = str(text)
    roots = set()
    if data_root:
        roots = {os.path.abspath(os.path.expanduser(data_root)), os.path.realpath(os.path.expanduser(data_root))}
    for root in sorted(roots - {os.sep}, key=len, reverse=True):
        text = re.sub(re.escape(root) + r"(?:/+|(?![\w-]))",
                      lambda match: "" if match.group(0).endswith("/") else ".", text)
    return text


def root_relative(path, root):
    """How a client names ``path`` (an absolute path): relative to ``root`` (the data root)
    when inside it (``presets/p1/20260101_120000``), else unchanged. "" stays "". One rule for
    every answer that names a robot file (file_control, calibration_control, task_manager)."""
    if not path or not os.path.isabs(path):
        return path
    for form in (os.path.abspath(root), os.path.realpath(root)):   # a root behind a symlink: either spelling
        rel = os.path.relpath(path, form)
        if rel != ".." and not rel.startswith("../"):
            return rel
    return path


def check_path_text(path):
    """Refuse what no file name of the robot contains: empty, NUL, control characters (a trailing
    newline included), more than MAX_PATH_BYTES, or a component longer than MAX_NAME_BYTES (UTF-8)."""
    if not isinstance(path, str) or not path:
        raise FileError("empty path")
    if "\x00" in path:
        raise FileError("path '%s' contains a NUL byte" % shown(path))
    if any(not c.isprintable() for c in path):
        raise FileError("path '%s' contains a control or unprintable character (newline, tab, ...)" % shown(path))
    size = len(_encoded(path))
    if size > MAX_PATH_BYTES:
        raise FileError("path '%s' is too long (%d bytes, at most %d)" % (shown(path), size, MAX_PATH_BYTES))
    longest = max(len(_encoded(part)) for part in path.split("/"))
    if longest > MAX_NAME_BYTES:
        raise FileError("path '%s' has a name of %d bytes (at most %d)" % (shown(path), longest, MAX_NAME_BYTES))


def _encoded(text):
    return text.encode("utf-8", "surrogateescape")


def confine_path(path, roots, base=None, root_names=None):
    """Resolve ``path`` and require it to lie inside one of ``roots`` (after symlinks and ``..``).

    Returns the absolute real path. A relative path is taken relative to ``base`` (default: the
    first root). Errors name ``path`` as given and the roots as ``root_names`` (default: ``roots``
    as given), never the resolved path.
    """
    check_path_text(path)
    if not roots:
        raise FileError("no allowed roots configured")
    real_roots = [os.path.realpath(os.path.expanduser(r)) for r in roots]
    candidate = os.path.expanduser(path)
    if not os.path.isabs(candidate):
        candidate = os.path.join(real_roots[0] if base is None else os.path.expanduser(base), candidate)
    resolved = os.path.realpath(candidate)
    if inside(resolved, real_roots):
        return resolved
    names = roots if root_names is None else root_names
    raise FileError("path '%s' is outside the allowed roots (%s)" % (shown(path), ", ".join(names)))


def confine_data_path(path, roots, data_root, root_names=None):
    """confine_path for a path a client names in either of the interface's two forms: relative to
    the data root (``presets/p1/20260101_120000``, the form every answer uses) or, the older form,
    relative to the first of ``roots`` (``p1/20260101_120000``); absolute paths as confine_path.
    A path whose data-root form lies inside ``roots`` is taken in that form, any other in the older
    one (``p1`` is ``presets/p1``; a preset id ``presets`` is only reached as ``presets/presets``).
    Errors name ``path`` as given."""
    check_path_text(path)
    if os.path.isabs(os.path.expanduser(path)) or not data_root:
        return confine_path(path, roots, root_names=root_names)
    try:
        return confine_path(path, roots, base=os.path.realpath(os.path.expanduser(data_root)), root_names=root_names)
    except FileError:
        return confine_path(path, roots, root_names=root_names)


def inside(resolved, real_roots):
    """Whether the real path ``resolved`` is one of ``real_roots`` or lies below one."""
    return any(resolved == root or resolved.startswith(root + os.sep) for root in real_roots)


STAGING_DIR = ".staging"   # a capture root's folder where preset_scale and find_scale take their pictures
_STAGED_NAME = re.compile(r"\.staging/[0-9a-f]{32}\.[A-Za-z0-9]{1,8}")


def staged_name(extension):
    """A fresh name in a capture root's STAGING_DIR (``.staging/<32 hex digits><extension>``): the one
    hidden name a capture command creates (new_file_path), for an owner that moves the file away."""
    return "%s/%s%s" % (STAGING_DIR, uuid.uuid4().hex, extension)


def is_staged_name(path):
    """Whether ``path`` (as a capture command got it) is a staged_name."""
    return bool(_STAGED_NAME.fullmatch(path))


def hidden_part(resolved, real_roots):
    """The first name starting with ``.`` in ``resolved`` below the root it lies in (a folder or file
    the robot keeps for itself: in-progress writes ``.name.*.tmp``, ``.tmp_*``, ``.<folder>.update.*``,
    ``.staging``), or "" when there is none."""
    for root in sorted(real_roots, key=len, reverse=True):
        if inside(resolved, [root]):
            for part in os.path.relpath(resolved, root).split(os.sep):
                if part.startswith(".") and part not in (".", ".."):
                    return part
            return ""
    return ""


def refuse_hidden(path, resolved, real_roots):
    """FileError naming ``path`` (as the client gave it) when ``resolved`` lies in a hidden folder or
    is a hidden file below its root: those are the robot's own, never a client's to write."""
    part = hidden_part(resolved, real_roots)
    if part:
        raise FileError("path '%s' has the hidden name '%s': names starting with '.' are the robot's own "
                        "(in-progress writes, staging); choose a name without a leading '.'"
                        % (shown(path), shown(part)))


def new_file_path(path, roots, root_names=None, staged=False):
    """confine_path for a file a command is about to create: no ``..`` component (a new file is
    named, not navigated to), no hidden name below the root (refuse_hidden; the only exception is a
    fresh ``staged_name`` when ``staged``: the device's staging service, which the backend surface
    does not offer), not a folder, and nothing there yet (files are never replaced)."""
    check_path_text(path)
    if ".." in path.split("/"):
        raise FileError("path '%s' contains '..' (name the file inside the roots directly)" % shown(path))
    resolved = confine_path(path, roots, root_names=root_names)
    real_roots = [os.path.realpath(os.path.expanduser(r)) for r in roots]
    if not (staged and is_staged_name(path)
            and os.path.dirname(resolved) == os.path.join(real_roots[0], STAGING_DIR)):
        refuse_hidden(path, resolved, real_roots)
    if os.path.isdir(resolved):
        raise FileError("path '%s' is a directory" % shown(path))
    if os.path.lexists(resolved):
        raise FileError("'%s' already exists (files are never replaced: choose a new name)" % shown(path))
    return resolved


PUBLIC_FILE_MODE = 0o644   # what a backend or another account fetches: reports, annotated pictures


def write_atomic(path, data, replace=True, mode=None):
    """Write ``data`` (str or bytes) to ``path``, creating its folder; FileError (nothing changed) on failure.

    ``replace=False``: an existing file at ``path`` fails the write (checked atomically: the new
    file is hard-linked into place, which refuses an existing name). ``mode``: the file's
    permissions (default 600, the temporary file's: state only the robot's user reads).
    """
    if not isinstance(data, (str, bytes)):
        raise TypeError("write_atomic needs str or bytes, got %s" % type(data).__name__)
    folder = os.path.dirname(os.path.abspath(path))
    try:
        os.makedirs(folder, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", suffix=".tmp", dir=folder)
    except OSError as err:
        raise FileError("cannot write '%s': %s" % (shown(path), err.strerror or err))
    try:
        with os.fdopen(fd, "wb" if isinstance(data, bytes) else "w") as f:
            if mode is not None:
                os.fchmod(f.fileno(), mode)
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
    except OSError as err:
        _remove_quietly(tmp)
        raise FileError("cannot write '%s': %s" % (shown(path), err.strerror or err))
    try:
        if replace:
            rename_durable(tmp, path)
        else:
            _link_new(tmp, path)
    except BaseException:
        _remove_quietly(tmp)
        raise


def _link_new(tmp, path):
    """Put ``tmp`` in place at ``path`` only if nothing is there, durably."""
    try:
        os.link(tmp, path)
    except FileExistsError:
        raise FileError("'%s' already exists (files are never replaced: choose a new name)" % shown(path))
    except OSError as err:
        if err.errno not in (errno.EPERM, errno.EOPNOTSUPP):
            raise FileError("cannot write '%s': %s" % (shown(path), err.strerror or err))
        # a filesystem without hard links (FAT): check, then rename (a narrow race, nothing better there)
        if os.path.lexists(path):
            raise FileError("'%s' already exists (files are never replaced: choose a new name)" % shown(path))
        rename_durable(tmp, path)
        return
    _remove_quietly(tmp)
    fsync_dir(os.path.dirname(os.path.abspath(path)))


def rename_durable(src, dst):
    """``os.replace(src, dst)``, then fsync the folder(s) it changed so the rename survives a power
    cut. FileError (nothing renamed) when the rename fails."""
    try:
        os.replace(src, dst)
    except OSError as err:
        raise FileError("cannot write '%s': %s" % (shown(dst), err.strerror or err))
    src_folder, dst_folder = (os.path.dirname(os.path.abspath(p)) for p in (src, dst))
    fsync_dir(dst_folder)
    if src_folder != dst_folder:
        fsync_dir(src_folder)


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


def move_file(src, dst):
    """Move the file ``src`` (another process's, maybe on another filesystem) to ``dst`` with
    write_atomic; ``src`` is removed once ``dst`` is in place. FileError on failure."""
    try:
        with open(src, "rb") as f:
            data = f.read()
    except OSError as err:
        raise FileError("cannot read '%s': %s" % (shown(src), err.strerror or err))
    write_atomic(dst, data)
    _remove_quietly(src)


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


def read_secret_file(path, setting, stat_fn=os.stat, open_fn=open):
    """The secret in ``path`` (surrounding whitespace stripped). ValueError naming ``setting`` (the
    parameter that gave the path) when the file is missing, readable or writable by group or
    others, or empty."""
    try:
        mode = stat_fn(path).st_mode
    except OSError as err:
        raise ValueError("%s %s: %s" % (setting, path, err.strerror))
    if mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise ValueError("%s %s is accessible by group/others (mode %03o): chmod 600 it, owned by "
                         "the robot's user" % (setting, path, stat.S_IMODE(mode)))
    try:
        with open_fn(path) as f:
            secret = f.read().strip()
    except (OSError, UnicodeDecodeError) as err:
        raise ValueError("%s %s: %s" % (setting, path, getattr(err, "strerror", None) or err))
    if not secret:
        raise ValueError("%s %s is empty" % (setting, path))
    return secret
