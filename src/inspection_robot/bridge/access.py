"""Who may open the backend link: the start-up checks of rosbridge_websocket's listening address.

A bridge reachable from the station network without authentication lets anyone there take backend
control and drive the robot (threat model: docs/operations.md, "Backend link security"). So a
non-loopback bind needs an auth token or TLS client certificates, unless explicitly ``insecure``.
The token may come from a file only the robot's user can read (not the command line, where ``ps``
shows it). Pure module: the node passes parameters in and logs what comes back.
"""
import ipaddress
import os
import stat

INSECURE_WARNING = ("INSECURE: the backend link listens on %s without authentication (insecure:=true): anyone "
                    "who can reach this port can take backend control and drive the robot")


class AccessError(ValueError):
    """A listening configuration the bridge refuses; the message says how to fix it."""


def is_loopback(address):
    """True for an address only this machine can reach ("" and 0.0.0.0 mean every interface)."""
    if address == "localhost":
        return True
    try:
        return ipaddress.ip_address(address).is_loopback
    except ValueError:
        return False


def read_token_file(path, stat_fn=os.stat, open_fn=open):
    """The token in ``path`` (surrounding whitespace stripped); AccessError when the file is readable
    or writable by group or others, or empty."""
    try:
        mode = stat_fn(path).st_mode
    except OSError as err:
        raise AccessError("~auth_token_file %s: %s" % (path, err.strerror))
    if mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise AccessError("~auth_token_file %s is accessible by group/others (mode %03o): chmod 600 it, owned by "
                          "the robot's user" % (path, stat.S_IMODE(mode)))
    with open_fn(path) as f:
        token = f.read().strip()
    if not token:
        raise AccessError("~auth_token_file %s is empty" % path)
    return token


def listen_check(address, authenticated, client_certificates, insecure):
    """None when listening on ``address`` is acceptable, the warning to repeat when only ``insecure``
    allows it; AccessError otherwise."""
    if is_loopback(address) or authenticated or client_certificates:
        return None
    shown = address or "0.0.0.0"
    if insecure:
        return INSECURE_WARNING % shown
    raise AccessError("refusing to listen on %s without authentication: set ~auth_token_file (a file readable only "
                      "by the robot's user; see docs/operations.md) or ~certfile/~keyfile with ~client_ca (TLS "
                      "client certificates), or bind to 127.0.0.1; insecure:=true overrides (never on a station "
                      "network)" % shown)
