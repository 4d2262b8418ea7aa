"""file_control: list, stat and read the files the robot keeps under its data root (captures,
find and result pictures, thermal frames, preset directories with their calibration, task
results), in base64 chunks of bounded size.

Every command takes a JSON object. ``path`` is relative to the data root (``presets/p1``) or
absolute, and must resolve (after ``..`` and symlinks) inside one of the allowed roots; ``""``
lists the roots themselves. A read returns at most ``max_chunk_bytes`` bytes, read with one seek,
so the memory a request needs is bounded whatever the file's size; the client loops on
``offset`` until ``eof``. Hidden entries (in-progress writes: ``.name.*.tmp``, ``.tmp_*``,
``.staging``) are not listed. Nothing here writes. A live SQLite database (the results store,
whose latest commits sit in its ``-wal``) and its journal files are refused to ``read``: a copy
would be stale or torn; task_control ``export_results`` writes a consistent snapshot to read.

A listing never looks through a link that leaves the roots: an entry is lstat'ed, and a symbolic
link whose target resolves outside the roots (or nowhere) is listed as ``"type": "link"`` with
the link's own size and mtime; a link inside the roots is listed as what it points to. Error
messages name the path as the client gave it and the roots relative to the data root, never a
resolved absolute path (which would tell a client the robot's layout).
"""
import base64
import hashlib
import json
import os
from stat import S_ISDIR, S_ISLNK

from inspection_robot.command import CommandError, CommandTable, parse_json
from inspection_robot.data_layout import under
from inspection_robot.files import FileError, confine_path, inside, root_relative, shown

DEFAULT_MAX_CHUNK_BYTES = 262144
DEFAULT_MAX_ENTRIES = 1000
HASH_BLOCK_BYTES = 1 << 20


def _fields(data, allowed, required=("path",)):
    fields = parse_json(data)
    if not isinstance(fields, dict):
        raise CommandError('data must be a JSON object, e.g. {"path": "presets"}')
    unknown = sorted(set(fields) - set(allowed))
    if unknown:
        raise CommandError("unknown field(s) %s (allowed: %s)" % (", ".join(unknown), ", ".join(sorted(allowed))))
    for name in required:
        if name not in fields:
            raise CommandError("missing field '%s'" % name)
    if not isinstance(fields.get("path", ""), str):
        raise CommandError("path must be a string")
    return fields


def _count(fields, name, default, low, high):
    value = fields.get(name, default)
    if isinstance(value, bool) or not isinstance(value, int):
        raise CommandError("%s must be an integer, got %r" % (name, value))
    if not low <= value <= high:
        raise CommandError("%s out of range [%d, %d]: %d" % (name, low, high, value))
    return value


class FileCommands(object):
    """The file_control command table over ``data_root``; ``roots`` (relative to it unless absolute)
    are the folders a client may read."""

    def __init__(self, data_root, roots, max_chunk_bytes=DEFAULT_MAX_CHUNK_BYTES, max_entries=DEFAULT_MAX_ENTRIES):
        if max_chunk_bytes < 1 or max_entries < 1:
            raise ValueError("max_chunk_bytes and max_entries must be >= 1")
        self.data_root = os.path.realpath(os.path.expanduser(data_root))
        self.roots = [os.path.realpath(under(self.data_root, r)) for r in roots]
        if not self.roots:
            raise ValueError("file_control needs at least one root")
        self.root_names = [self.relative(r) for r in self.roots]
        self.max_chunk_bytes = int(max_chunk_bytes)
        self.max_entries = int(max_entries)
        self.table = CommandTable({"list": self.list, "stat": self.stat, "read": self.read})

    def resolve(self, path):
        """The absolute real path of a client's ``path``; FileError (naming ``path``) outside the roots."""
        return confine_path(path, self.roots, base=self.data_root, root_names=self.root_names)

    def relative(self, path):
        """How a client names ``path``: relative to the data root when inside it."""
        return root_relative(path, self.data_root)

    def _entry(self, path, shown_as, name=None):
        """{name, type, size, mtime} of ``path``; errors name it ``shown_as`` (the client's path).
        A link leaving the roots is not followed (type "link", the link's own size and mtime)."""
        try:
            info = os.lstat(path)
            if os.path.islink(path) and inside(os.path.realpath(path), self.roots):
                info = os.stat(path)
        except FileNotFoundError:
            raise FileError("no such file or directory: '%s'" % shown(shown_as))
        except OSError as err:
            raise FileError("cannot stat '%s': %s" % (shown(shown_as), err.strerror))
        kind = "dir" if S_ISDIR(info.st_mode) else "link" if S_ISLNK(info.st_mode) else "file"
        return {"name": name if name is not None else os.path.basename(path), "type": kind,
                "size": 0 if kind == "dir" else info.st_size, "mtime": round(info.st_mtime, 3)}

    def list(self, data):
        """{"path": dir, "offset": n} -> {"path", "entries": [{name, type, size, mtime}], "total", "offset",
        "truncated"}; entries sorted by name, at most max_entries from ``offset``."""
        fields = _fields(data, ("path", "offset"), required=())
        path = fields.get("path", "")
        offset = _count(fields, "offset", 0, 0, 1 << 31)
        if path == "":
            entries = [self._entry(root, name, name) for root, name in zip(self.roots, self.root_names)
                       if os.path.isdir(root)]
            return self._page("", entries, offset)
        folder = self.resolve(path)
        if not os.path.exists(folder):
            raise FileError("no such directory: '%s'" % shown(path))
        if not os.path.isdir(folder):
            raise FileError("not a directory: '%s' (use stat or read)" % shown(path))
        try:
            names = sorted(n for n in os.listdir(folder) if not n.startswith("."))
        except OSError as err:
            raise FileError("cannot list '%s': %s" % (shown(path), err.strerror))
        entries = []
        for name in names[offset:offset + self.max_entries]:
            try:
                entries.append(self._entry(os.path.join(folder, name), name))
            except FileError:
                continue  # removed while listing
        return self._page(self.relative(folder), entries, offset, total=len(names))

    def _page(self, path, entries, offset, total=None):
        total = len(entries) if total is None else total
        if path == "":
            entries = entries[offset:offset + self.max_entries]
        return _json({"path": path, "offset": offset, "total": total, "entries": entries,
                      "truncated": offset + len(entries) < total})

    def stat(self, data):
        """{"path"} -> {"path", "type", "size", "mtime", "sha256" (files)}."""
        given = _fields(data, ("path",))["path"]
        path = self.resolve(given)
        out = self._entry(path, given)
        out["path"] = self.relative(path)
        del out["name"]
        if out["type"] == "file":
            out["sha256"] = _sha256(path, given)
        return _json(out)

    def read(self, data):
        """{"path", "offset" (0), "length" (max_chunk_bytes)} -> {"path", "offset", "length", "size",
        "eof", "data" (base64)}."""
        fields = _fields(data, ("path", "offset", "length"))
        path = self.resolve(fields["path"])
        offset = _count(fields, "offset", 0, 0, 1 << 62)
        length = _count(fields, "length", self.max_chunk_bytes, 1, self.max_chunk_bytes)
        given = shown(fields["path"])
        if os.path.isdir(path):
            raise FileError("'%s' is a directory (use list)" % given)
        live = live_sqlite(path)
        if live:
            raise FileError("'%s' is %s: a copy would miss or tear recent commits; read a snapshot instead "
                            "(task_control export_results writes one under tasks/exports/)" % (given, live))
        try:
            with open(path, "rb") as f:
                size = os.fstat(f.fileno()).st_size
                if offset > size:
                    raise FileError("offset %d beyond the end of '%s' (%d bytes)" % (offset, given, size))
                f.seek(offset)
                chunk = f.read(length)
        except FileNotFoundError:
            raise FileError("no such file: '%s'" % given)
        except OSError as err:
            raise FileError("cannot read '%s': %s" % (given, err.strerror))
        return _json({"path": self.relative(path), "offset": offset, "length": len(chunk), "size": size,
                      "eof": offset + len(chunk) >= size, "data": base64.b64encode(chunk).decode("ascii")})


SQLITE_JOURNAL_SUFFIXES = ("-wal", "-shm", "-journal")


def live_sqlite(path):
    """Why ``path`` must not be copied as it is (a live SQLite database: its latest commits sit in a
    ``-wal`` beside it, or one of its journal files), or "" when it may."""
    if path.endswith(SQLITE_JOURNAL_SUFFIXES) and os.path.isfile(path[:path.rindex("-")]):
        return "the journal of a live SQLite database"
    if os.path.exists(path + "-wal"):
        return "a live SQLite database (its latest commits are in its -wal file)"
    return ""


def _sha256(path, given):
    digest = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(HASH_BLOCK_BYTES), b""):
                digest.update(block)
    except OSError as err:
        raise FileError("cannot read '%s': %s" % (shown(given), err.strerror))
    return digest.hexdigest()


def _json(value):
    return json.dumps(value, sort_keys=True)
