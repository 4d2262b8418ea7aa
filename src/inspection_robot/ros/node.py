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

:func:`renice` gives a latency-critical node (the backend link) a larger share of a busy CPU.
"""
import os

import rospy

from inspection_robot.ros import compat_rospy

HANDSHAKE_TIMEOUT_S = 5.0   # a TCPROS client sends its header right after connecting


def guard_inbound_handshakes(timeout_s=HANDSHAKE_TIMEOUT_S):
    """Bound every inbound handshake of this process to ``timeout_s`` (idempotent; before init_node).
    The patch itself is rospy-internal and lives in compat_rospy; False when this rospy cannot take it."""
    return compat_rospy.guard_inbound_handshakes(timeout_s)


def renice(niceness):
    """Set the scheduling niceness of every thread of this process to ``niceness`` (-20..19); threads
    made later inherit it from the thread that makes them. Returns None, or why it failed (a value
    below the current one needs CAP_SYS_NICE or an RLIMIT_NICE that allows it, e.g. systemd's
    LimitNICE). Linux: each thread has its own niceness, hence every one in /proc/self/task."""
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
    return None


def init_node(name, **kwargs):
    """rospy.init_node with inbound handshakes bounded and no publisher update lost (see the module's docstring)."""
    guarded = guard_inbound_handshakes()
    merged = compat_rospy.merge_publisher_updates()
    rospy.init_node(name, **kwargs)
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
