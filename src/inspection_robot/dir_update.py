"""Several files of one folder changed at once (a preset's calibration): ``DirUpdate(folder)``.

The changes go into a hard-linked copy beside the folder that replaces it in one atomic rename
(renameat2 RENAME_EXCHANGE, two renames where the file system cannot exchange), so a reader or a
crash sees all of them or none. Apart from files.py, whose single-file writes (``write_atomic``,
``fsync_dir``) and FileError it builds on, because the swap of a whole folder brings its own
machinery (the C library's renameat2 through ctypes, a tree of hard links).
"""
import ctypes
import errno
import os
import shutil
import stat
import tempfile

from inspection_robot.files import FileError, fsync_dir

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
