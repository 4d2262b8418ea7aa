"""Command tables for the GeneralCmd/ControlService interfaces, and strict argument parsing.

Every device node (cloud_terrace, robot_arm, camera_node, infrared_imager, robot_control ...)
answers ``cmd``/``data`` strings with ``ack``/``data`` strings. This module owns the parts they
share: dispatch by name, the failure reply for unknown commands, and parsers that turn malformed
input into a clear reason instead of an exception deep inside a driver.
"""
import json
import math
from collections import namedtuple

from inspection_robot.interface import ACK_FAILED, ACK_SUCCESS

Reply = namedtuple("Reply", "ack data")

# Longest number text the parsers look at. Python's str -> int is quadratic in the digit count
# (Python 3.8 has no limit), so a 10 MB run of digits from a careless client would stall a node.
MAX_NUMBER_CHARS = 64
# Longest part of a caller's unknown name echoed in a reply: an ack goes to every subscriber of the
# topic, so a 100 kB name must not come back 100 kB to each of them.
MAX_ECHO_CHARS = 40


def echoed(text, limit=MAX_ECHO_CHARS):
    """``text`` as a reply may quote it: its first ``limit`` characters, then ``...`` when it was longer."""
    text = str(text)
    return text if len(text) <= limit else text[:limit] + "..."


class CommandError(Exception):
    """A request that cannot be carried out; the message is the reason sent back to the caller."""


def success(data=""):
    return Reply(ACK_SUCCESS, str(data))


def failed(reason):
    return Reply(ACK_FAILED, str(reason))


class CommandTable(object):
    """Maps command names to handlers ``handler(data) -> Reply | str | None``.

    A handler returning a string (or None) succeeds with that data; raising CommandError fails
    with the reason. Anything else a handler raises is a bug and propagates to the node boundary.
    """

    def __init__(self, handlers=None):
        self._handlers = dict(handlers or {})

    def register(self, name, handler):
        self._handlers[name] = handler

    @property
    def names(self):
        return tuple(sorted(self._handlers))

    def __contains__(self, name):
        return name in self._handlers

    def dispatch(self, cmd, data):
        handler = self._handlers.get(cmd)
        if handler is None:
            return failed("unknown command '%s'" % (echoed(cmd),))
        try:
            result = handler(data)
        except CommandError as err:
            return failed(err)
        if isinstance(result, Reply):
            return result
        return success("" if result is None else result)


def no_data(handler):
    """Wrap the handler of a command without arguments: non-empty data fails instead of being ignored
    (``get_zoom_level 4`` is a mistake the caller should hear about)."""
    def checked(data):
        if data != "":
            raise CommandError("this command takes no data, got '%s'" % (data,))
        return handler(data)
    return checked


def split_fields(data, count, name="data"):
    """Split comma-separated ``data`` into exactly ``count`` fields (no spaces allowed)."""
    fields = str(data).split(",")
    if len(fields) != count or any(f == "" for f in fields):
        raise CommandError("%s must be %d comma-separated values, got '%s'" % (name, count, data))
    for field in fields:
        if field != field.strip():
            raise CommandError("%s must not contain spaces, got '%s'" % (name, data))
    return fields


def parse_int(text, name, low=None, high=None):
    """Parse a decimal integer within [low, high]; anything else raises CommandError."""
    text = str(text)
    if text != text.strip():
        raise CommandError("%s must not contain spaces, got '%s'" % (name, text))
    _check_length(text, name)
    try:
        value = int(text, 10)
    except ValueError:
        raise CommandError("%s must be an integer, got '%s'" % (name, text))
    _check_range(value, name, low, high)
    return value


def parse_float(text, name, low=None, high=None):
    """Parse a finite decimal number within [low, high]; NaN, inf and junk raise CommandError."""
    text = str(text)
    if text != text.strip():
        raise CommandError("%s must not contain spaces, got '%s'" % (name, text))
    _check_length(text, name)
    try:
        value = float(text)
    except ValueError:
        raise CommandError("%s must be a number, got '%s'" % (name, text))
    if not math.isfinite(value):
        raise CommandError("%s must be finite, got '%s'" % (name, text))
    _check_range(value, name, low, high)
    return value


def parse_choice(text, name, choices):
    """Return ``text`` if it is one of ``choices`` (compared as strings)."""
    text = str(text)
    allowed = [str(c) for c in choices]
    if text not in allowed:
        raise CommandError("%s must be one of %s, got '%s'" % (name, "|".join(allowed), text))
    return text


def _check_length(text, name):
    if len(text) > MAX_NUMBER_CHARS:
        raise CommandError("%s is too long (%d characters, at most %d): '%s...'"
                           % (name, len(text), MAX_NUMBER_CHARS, text[:20]))


class _NotFinite(str):
    """Stands in for a NaN, Infinity or overflowing number while decoding, so the error can name where it was."""


def _json_float(text):
    value = float(text)
    return value if math.isfinite(value) else _NotFinite(text)


def _json_int(text):
    if len(text) > MAX_NUMBER_CHARS:
        raise ValueError("a number of %d digits is too long (at most %d)" % (len(text), MAX_NUMBER_CHARS))
    return int(text)


def _first_not_finite(value, path):
    """(path, text) of the first _NotFinite inside ``value``, or None."""
    if isinstance(value, _NotFinite):
        return path, str(value)
    items = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else ()
    for key, item in items:
        where = "%s[%d]" % (path, key) if isinstance(key, int) else ("%s.%s" % (path, key) if path else key)
        found = _first_not_finite(item, where)
        if found:
            return found
    return None


def parse_json(data, name="data"):
    """Decode JSON text; malformed, too deeply nested or non-text data raises CommandError, and so do
    NaN, Infinity and numbers too large for a float (Python's json accepts them; no command has a use
    for them and they slip through range checks) or longer than MAX_NUMBER_CHARS digits."""
    try:
        value = json.loads(data, parse_constant=_NotFinite, parse_float=_json_float, parse_int=_json_int)
        found = _first_not_finite(value, name if isinstance(value, list) else "")
    except (TypeError, ValueError, RecursionError) as err:
        raise CommandError("%s is not valid JSON: %s" % (name, err))
    if found:
        raise CommandError("%s must be a finite number, got %s" % (found[0] or name, found[1]))
    return value


def refuse_unknown_keys(obj, what, allowed):
    """CommandError naming the keys of the dict ``obj`` that are not in ``allowed`` (listed in their
    order), so a misspelt or invented key (``speed``) is refused instead of silently ignored."""
    unknown = sorted(set(obj) - set(allowed))
    if unknown:
        raise CommandError("%s: unknown key(s) %s (allowed: %s)" % (what, ", ".join(unknown), ", ".join(allowed)))
    return obj


def _check_range(value, name, low, high):
    if (low is not None and value < low) or (high is not None and value > high):
        raise CommandError("%s out of range [%s, %s]: %s" % (name, low, high, value))
