"""Node start-up shared by every node: rospy.init_node behind a guard on inbound TCPROS handshakes,
with rospy's lost-publisher-update race repaired (compat_rospy.merge_publisher_updates says how).

rospy accepts inbound topic and service connections on one thread and reads each connection's
handshake header there with no timeout (rospy/impl/tcpros_base.py, TCPROSServer). One client
that connects and then sends nothing, or something that is not TCPROS (an HTTP or websocket
client on a reused port, a port scanner), blocks that thread forever: the node takes no new
subscriber and answers no new service call again while it looks alive. The guard bounds the
handshake with a socket timeout, so such a connection is dropped (one warning from rospy) and the
next one is served. The timeout bounds each read, not the whole header: a loaded subscriber whose
header trickles in is served; one silent for a whole HANDSHAKE_TIMEOUT_S after connecting is
dropped, and rospy's subscriber does not retry a refused handshake (its connection closes for good
until the publisher re-registers). No such drop (`Inbound TCP/IP connection failed: timed out`)
appears in any stored test run; the subscription that did not connect in a failed patrol_sim run
had not got as far as a handshake (compat_rospy.merge_publisher_updates).

:func:`renice` gives a latency-critical node (the backend link) a larger share of a busy CPU; the
environment variable ``INSPECTION_ROBOT_NICE`` (:data:`NICE_ENV`) renices every node of this package at
start-up (a test machine's suites yielding to the chaos soak's robot, or a site's robot beside
weightier work).

:class:`NodeSettings` reads a node's settings: the parameter server's value, else config/<node>.yaml's
(settings.py), the one place each default is written.
"""
import errno
import os
import random
import threading
import time

import rospy

from inspection_robot import settings
from inspection_robot.ros import compat_rospy, data_root
from inspection_robot.ros.package_share import share_file

HANDSHAKE_TIMEOUT_S = 5.0   # a TCPROS client sends its header right after connecting
NICE_ENV = "INSPECTION_ROBOT_NICE"   # niceness every node of this package takes at start-up (init_node)
AUTOGROUP_FILE = "/proc/self/autogroup"
# Linux takes one autogroup change every 100 ms, system-wide, from a process without CAP_SYS_ADMIN:
# a launch's nodes starting together queue for it
AUTOGROUP_RETRY_S = 30.0


def guard_inbound_handshakes(timeout_s=HANDSHAKE_TIMEOUT_S):
    """Bound every inbound handshake of this process to ``timeout_s`` (idempotent; before init_node).
    The patch itself is rospy-internal and lives in compat_rospy; False when this rospy cannot take it."""
    return compat_rospy.guard_inbound_handshakes(timeout_s)


def renice(niceness):
    """Set the scheduling niceness of every thread of this process to ``niceness`` (-20..19), and of its
    session's autogroup when this process leads its session. Threads made later inherit it from the
    thread that makes them. Returns None, or why it failed (a value below the current one needs
    CAP_SYS_NICE or an RLIMIT_NICE that allows it, e.g. systemd's LimitNICE). Linux: each thread has
    its own niceness, hence every one in /proc/self/task; the autogroup: see :func:`renice_session`."""
    if not -20 <= niceness <= 19:
        raise ValueError("niceness must be -20..19, not %d" % niceness)
    try:
        threads = [int(tid) for tid in os.listdir("/proc/self/task")]
    except OSError:
        threads = [0]  # no /proc: this thread (and those it makes) only
    for tid in threads:
        try:
            os.setpriority(os.PRIO_PROCESS, tid, niceness)
        except ProcessLookupError:
            continue  # the thread ended meanwhile
        except PermissionError as exc:
            return "cannot set niceness %d: %s" % (niceness, exc.strerror)
    return renice_session(niceness)


def renice_session(niceness):
    """With autogroup scheduling (on by default in kernels built with it, as Ubuntu's) Linux shares the CPU
    between sessions first and by niceness only inside one, and roslaunch starts every node in a
    session of its own: a thread niceness alone then changes nothing against the other nodes. So the
    autogroup takes the niceness too when this process leads its session (as every node under
    roslaunch does); started from a shell, the session is the shell's and is left alone. Returns None,
    or why it failed; nothing to do without autogroup support. When the kernel's rate limit says
    "not now" (EAGAIN) it is tried again beside the node's start-up, which it does not hold up; a
    warning is logged if that fails too."""
    if os.getsid(0) != os.getpid():
        return None
    error = _write_autogroup(niceness, AUTOGROUP_FILE)
    if error is None or error.errno != errno.EAGAIN:
        return _autogroup_failure(niceness, error)
    threading.Thread(target=_renice_session_later, args=(niceness,), name="autogroup_nice", daemon=True).start()
    return None


def _renice_session_later(niceness):
    failed = set_autogroup_niceness(niceness, AUTOGROUP_FILE)
    if failed:
        rospy.logwarn(failed)


def set_autogroup_niceness(niceness, autogroup_file, retry_s=AUTOGROUP_RETRY_S):
    """Write ``niceness`` to a session's autogroup file (/proc/PID/autogroup of any process in it),
    trying again for ``retry_s`` while the kernel's rate limit refuses (EAGAIN, at jittered times so
    that nodes starting together do not keep colliding): None, or why it failed; None when the
    kernel has no autogroup scheduling (no such file)."""
    deadline = time.monotonic() + retry_s
    error = _write_autogroup(niceness, autogroup_file)
    while error is not None and error.errno == errno.EAGAIN and time.monotonic() < deadline:
        time.sleep(random.uniform(0.05, 0.3))
        error = _write_autogroup(niceness, autogroup_file)
    return _autogroup_failure(niceness, error)


def _write_autogroup(niceness, autogroup_file):
    """None when written, or when the kernel has no autogroup scheduling; else the OSError."""
    try:
        with open(autogroup_file, "w") as handle:
            handle.write("%d" % niceness)
    except FileNotFoundError:
        return None  # the thread niceness is all there is
    except OSError as exc:
        return exc
    return None


def _autogroup_failure(niceness, error):
    return None if error is None else "cannot set the session's autogroup niceness %d: %s" % (niceness, error.strerror)


def niceness_from_environment():
    """(niceness, None) from :data:`NICE_ENV`, (None, None) when it is not set, (None, why) when bad."""
    value = os.environ.get(NICE_ENV, "").strip()
    if not value:
        return None, None
    try:
        niceness = int(value)
    except ValueError:
        niceness = None
    if niceness is None or not -20 <= niceness <= 19:
        return None, "%s=%r is not a niceness (-20..19): ignored" % (NICE_ENV, value)
    return niceness, None


def renice_from_environment():
    """Apply :data:`NICE_ENV` when it is set: None, or why not (a bad value, or what renice says)."""
    niceness, bad = niceness_from_environment()
    if niceness is None:
        return bad
    failed = renice(niceness)
    return "%s=%d not applied: %s" % (NICE_ENV, niceness, failed) if failed else None


def init_node(name, **kwargs):
    """rospy.init_node with inbound handshakes bounded and no publisher update lost (see the module's docstring)."""
    guarded = guard_inbound_handshakes()
    merged = compat_rospy.merge_publisher_updates()
    rospy.init_node(name, **kwargs)
    not_reniced = renice_from_environment()
    if not_reniced:
        rospy.logwarn(not_reniced)
    if not guarded:
        rospy.logwarn("inbound TCPROS handshakes are not bounded: %s", compat_rospy.describe())
    if not merged:
        rospy.logwarn("a subscription may miss a publisher that starts with it: %s", compat_rospy.describe())


def site_param(name):
    """A site setting (map, localizer topic, poses, dock): it has no package default, so a node never
    falls back on the simulated yard's. ValueError naming it and where it is set when missing."""
    if not rospy.has_param(name):
        raise ValueError("%s is not set: a site setting with no default; the site file sets it "
                         "(config/robot.example.yaml), sim.launch config/sim_site.yaml" % rospy.resolve_name(name))
    return rospy.get_param(name)


class NodeSettings(object):
    """One node's settings, read in its main(): ``get("~rate")`` is the parameter server's ``~rate`` when
    set, else config/<node>.yaml's ``rate`` (a mapping: the parameter server's keys over the file's, as a
    launch merges them). The file is found in the source tree or the installed package, so a node a test
    starts without loading it runs with the same values as under a launch. A name the file does not
    define raises settings.SettingsError: every setting and its default live in that file, nowhere else
    (site settings without a default: :func:`site_param`; the data root: ros/data_root.py).

    ``node_type``: the node's module (nodes/<node_type>.py), whatever name the launch gives it.
    ``defaults``: a settings.NodeDefaults (tests), else read from config/.
    """

    def __init__(self, node_type, defaults=None):
        if defaults is None:
            directory = settings.source_config_dir() or settings.config_dir(share_file())
            defaults = settings.node_defaults(node_type, directory)
        self.defaults = defaults

    @staticmethod
    def _private(name):
        if not name.startswith("~"):
            raise ValueError("NodeSettings reads private settings (~name), not %r" % name)
        return name

    def default(self, name):
        """config/<node>.yaml's value of ``~name``."""
        return self.defaults.default(self._private(name))

    def get(self, name):
        """The value the node runs with (see the class)."""
        default = self.default(name)
        return settings.merged(default, rospy.get_param(name)) if rospy.has_param(name) else default

    def path(self, name, root):
        """A path setting fixed at launch (ros/data_root.py), relative to ``root`` unless absolute."""
        return data_root.path_param(name, self.default(name), root)

    def path_list(self, name, root):
        """A list of path settings fixed at launch, each relative to ``root`` unless absolute."""
        return data_root.path_list_param(name, self.default(name), root)

    def fixed_list(self, name):
        """A list setting fixed at launch like the paths (relative as given)."""
        return data_root.fixed_list(name, self.default(name))
