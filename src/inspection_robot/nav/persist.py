"""Atomic JSON files: write to a temporary file in the same folder, fsync, then rename over.

A crash or power cut leaves either the old file or the new one, never a half-written mix.
"""
import json
import os
import tempfile


def write_json_atomic(path, value):
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", suffix=".tmp", dir=folder)
    try:
        with os.fdopen(fd, "w") as f:
            json.dump(value, f, sort_keys=True)
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


def read_json(path):
    """The parsed file, or None when it does not exist. Raises ValueError on a corrupt file."""
    try:
        with open(path) as f:
            return json.load(f)
    except FileNotFoundError:
        return None
