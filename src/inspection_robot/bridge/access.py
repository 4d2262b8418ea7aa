"""Who may open the backend link: the start-up checks of rosbridge_websocket's listening address.

A bridge reachable from the station network without authentication lets anyone there take backend
control and drive the robot (threat model: docs/deployment.md, "Backend link security"). So a
non-loopback bind needs an auth token or TLS client certificates, unless explicitly ``insecure``.
The token may come from a file only the robot's user can read (not the command line, where ``ps``
shows it).

Once listening, :class:`Authenticator` checks each client's ``auth`` op: the token itself only over
TLS or from this machine (a secret sent in clear on the station network could be replayed forever),
otherwise a rosauth-style MAC over a single-use nonce the bridge issued to that connection, so a
captured auth message opens nothing. Failed attempts are counted per peer address and a peer that
keeps failing is refused for a while (:class:`FailureLimiter`). :func:`origin_allowed` keeps web
pages of other sites from using an operator's browser to drive the robot. Pure module: the node
passes parameters in and logs what comes back.
"""
import collections
import hashlib
import hmac
import ipaddress
import math
import os
import secrets
import socket
from urllib.parse import urlsplit

from inspection_robot.bridge.surface import SURFACES
from inspection_robot.files import read_secret_file

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
    """The token in ``path`` (files.read_secret_file); AccessError when the file is readable or
    writable by group or others, or empty."""
    try:
        return read_secret_file(path, "~auth_token_file", stat_fn, open_fn)
    except ValueError as err:
        raise AccessError(str(err))


def listen_check(address, authenticated, client_certificates, insecure):
    """None when listening on ``address`` is acceptable, the warning to repeat when only ``insecure``
    allows it; AccessError otherwise."""
    if is_loopback(address) or authenticated or client_certificates:
        return None
    shown = address or "0.0.0.0"
    if insecure:
        return INSECURE_WARNING % shown
    raise AccessError("refusing to listen on %s without authentication: set ~auth_token_file (a file readable only "
                      "by the robot's user; see docs/deployment.md) or ~certfile/~keyfile with ~client_ca (TLS "
                      "client certificates), or bind to 127.0.0.1; insecure:=true overrides (never on a station "
                      "network)" % shown)


class Peer(collections.namedtuple("Peer", "address secure path")):
    """Who is on the other end of a connection: ``address`` (IP text), ``secure`` (the link is TLS),
    ``path`` (the websocket's URL path, which chooses the client's role: bridge.surface.role_of_path)."""

    def __new__(cls, address, secure, path="/"):
        return super(Peer, cls).__new__(cls, address, secure, path)

    @property
    def private(self):
        """True when nobody else on the network can read what this peer sends (TLS or loopback)."""
        return self.secure or is_loopback(self.address)


def _seconds(value):
    """Whole seconds of an auth op's time field: a number or a ROS time object {secs, nsecs}."""
    if isinstance(value, dict):
        secs = value.get("secs", 0)
        return secs if isinstance(secs, int) and not isinstance(secs, bool) else 0
    if isinstance(value, float) and not math.isfinite(value):
        raise ValueError("not a finite number")
    return int(value)


class FailureLimiter(object):
    """Counts failed authentications per peer address; ``max_failures`` within ``period`` s block that
    address for ``period`` s from its last failure."""

    def __init__(self, clock, max_failures=5, period=60.0):
        self._clock = clock
        self._max = int(max_failures)
        self._period = float(period)
        self._failures = {}  # address -> deque of failure times within the period

    def _recent(self, address):
        times = self._failures.get(address)
        if times is None:
            return None
        horizon = self._clock() - self._period
        while times and times[0] < horizon:
            times.popleft()
        if not times:
            del self._failures[address]
            return None
        return times

    def blocked_for(self, address):
        """Seconds until ``address`` may try again (0.0 when it may now)."""
        times = self._recent(address)
        if times is None or len(times) < self._max:
            return 0.0
        return max(0.0, times[-1] + self._period - self._clock())

    def failed(self, address):
        times = self._recent(address)
        if times is None:
            times = self._failures[address] = collections.deque(maxlen=self._max)
        times.append(self._clock())


class Authenticator(object):
    """Checks an ``auth`` op against the shared secret.

    Accepted: ``mac`` equal to the secret, from a :attr:`Peer.private` peer only; or rosauth's MAC,
    the hex SHA-512 of secret + client + dest + rand + str(t) + level + str(end) (t, end in whole
    seconds), where ``rand`` is the nonce :meth:`challenge` issued to this connection, ``end`` is
    not in the past and ``t`` is within ``window`` s of ``clock()`` (wall seconds).
    """

    def __init__(self, secret, clock, window=60.0, limiter=None):
        if not secret:
            raise ValueError("an empty secret would accept anyone")
        self._secret = secret
        self._clock = clock
        self._window = float(window)
        self.limiter = limiter or FailureLimiter(clock)

    def challenge(self):
        """A fresh nonce and the current time (seconds) to build the MAC with."""
        return secrets.token_hex(16), int(self._clock())

    def refusal(self, args, peer, nonce):
        """None when ``args`` (an auth op's fields) authenticate ``peer``, else the reason it does not.
        ``nonce``: the challenge issued to this connection (None when it asked for none)."""
        secret = self._secret.encode("utf-8")
        mac = args["mac"].encode("utf-8")
        if hmac.compare_digest(mac, secret):
            if peer.private:
                return None
            return ("the token itself is accepted only over TLS (wss) or from the robot: send the MAC of an "
                    "auth_challenge nonce")
        if nonce is None or not hmac.compare_digest(args["rand"].encode("utf-8"), nonce.encode("utf-8")):
            return "rand must be the nonce of this connection's auth_challenge (each nonce is accepted once)"
        try:
            t, end = _seconds(args["t"]), _seconds(args["end"])
        except ValueError:
            return "t and end must be finite numbers of seconds"
        text = "%s%s%s%s%d%s%d" % (self._secret, args["client"], args["dest"], args["rand"], t, args["level"], end)
        expected = hashlib.sha512(text.encode("utf-8")).hexdigest().encode("utf-8")
        if not hmac.compare_digest(mac, expected):
            return "wrong mac"
        now = self._clock()
        if end < now:
            return "end is in the past"
        if abs(now - t) > self._window:
            return "t is more than %g s away from the robot's clock" % self._window
        return None


def _default_port(scheme):
    return {"http": 80, "ws": 80, "https": 443, "wss": 443}.get(scheme)


def _origin_key(url):
    """(scheme, host, port) of an origin or URL, lowercase, default ports filled; None if unparsable."""
    try:
        parts = urlsplit(url.strip().lower())
        port = parts.port or _default_port(parts.scheme)
    except ValueError:
        return None
    if not parts.scheme or not parts.hostname:
        return None
    return parts.scheme, parts.hostname, port


def _is_ip(host):
    try:
        ipaddress.ip_address(host)
        return True
    except ValueError:
        return False


def origin_allowed(origin, host, scheme, allowed=(), local_names=()):
    """Whether a browser page from ``origin`` may open the websocket reached as ``scheme``://``host``.

    Allowed: an origin in ``allowed`` (exact scheme://host[:port]), or the bridge's own pages (the
    console: same scheme, host and port) when the host is an IP address, ``localhost`` or one of
    ``local_names``, so a foreign DNS name rebound to the robot's address does not pass as the console.
    Clients that send no Origin (not browsers) are not checked here.
    """
    key = _origin_key(origin)
    if key is None:
        return False
    if any(key == _origin_key(entry) for entry in allowed):
        return True
    own = _origin_key("%s://%s" % (scheme, host))
    if own is None or key != own:
        return False
    name = own[1].strip("[]")
    return _is_ip(name) or name == "localhost" or name in {n.lower() for n in local_names}


def local_names():
    """This machine's own host names (lowercase), under which its console may be opened."""
    names = {socket.gethostname().lower()}
    try:
        names.add(socket.getfqdn().lower())
    except OSError:
        pass
    return tuple(sorted(n for n in names if n))


def check_fixed(settings):
    """Raise AccessError unless the bridge's security settings (fixed_settings.FIXED_KEYS) can start it:
    the one check of rosbridge_websocket at start-up and of check_site while robot.launch parses, so a
    site file the bridge would refuse at every respawn is refused before anything starts."""
    for key in ("address", "certfile", "keyfile", "client_ca", "auth_token", "auth_token_file"):
        if key in settings and not isinstance(settings[key], str):
            raise AccessError("~%s must be a string, not %r" % (key, settings[key]))
    if "insecure" in settings and not isinstance(settings["insecure"], bool):
        raise AccessError("~insecure must be true or false, not %r" % (settings["insecure"],))
    origins = settings.get("allowed_origins", [])
    if not isinstance(origins, list) or not all(isinstance(o, str) and "://" in o for o in origins):
        raise AccessError("~allowed_origins must be a list of origins like 'https://backend.example:8443', not %r"
                          % (origins,))
    if settings.get("surface", "robot") not in SURFACES:
        raise AccessError("~surface must be one of %s, not %r" % (", ".join(SURFACES), settings.get("surface")))
    if settings.get("keyfile") and not settings.get("certfile"):
        raise AccessError("~keyfile given without ~certfile")
    if settings.get("client_ca") and not settings.get("certfile"):
        raise AccessError("~client_ca needs ~certfile/~keyfile (client certificates are checked over TLS)")
    if settings.get("auth_token_file") and settings.get("auth_token"):
        raise AccessError("set ~auth_token_file or ~auth_token, not both")
