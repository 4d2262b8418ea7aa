"""JSON state files of navigation (virtual obstacles, last pose), written atomically.

A crash or power cut leaves either the old file or the new one, never a half-written mix.
"""
import json

from inspection_robot.atomic_file import write_atomic


def write_json_atomic(path, value):
    write_atomic(path, json.dumps(value, sort_keys=True))


def read_json(path):
    """The parsed file, or None when it does not exist. Raises ValueError on a corrupt file."""
    try:
        with open(path) as f:
            return json.load(f)
    except FileNotFoundError:
        return None
