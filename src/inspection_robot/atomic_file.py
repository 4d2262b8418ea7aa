"""Atomic, durable file writes: the one way every module saves a file other code may read.

The data goes to a hidden temporary file in the target's folder, is flushed and fsynced, and is
renamed over the target; the folder is fsynced so the rename survives a power cut. A reader or a
crash therefore sees the old file or the new one, never half of one; a failed write leaves no
temporary file behind. Used for presets, calibration, virtual obstacles, the last pose, arm
trajectories and result pictures.
"""
import os
import tempfile


def write_atomic(path, data):
    """Write ``data`` (str or bytes) to ``path``; raises OSError (nothing changed) on failure."""
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", suffix=".tmp", dir=folder)
    try:
        with os.fdopen(fd, "wb" if isinstance(data, bytes) else "w") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    try:  # make the rename itself durable
        dir_fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(dir_fd)
    finally:
        os.close(dir_fd)
