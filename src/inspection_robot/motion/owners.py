"""Owners of the safety inputs: a message that stops, clears or takes the robot counts only from the
node that owns it (docs/interface.md, "Motion and safety", **Owners**).

The rule looks at the publisher's caller id (the node name rospy reads from the TCPROS connection
header, ros/compat_rospy.caller_id), never at a message's ``sender`` string, which any client writes.
Every websocket client publishes through the bridge's own publisher, caller id
``<bridge node>/tcpros``, so a client is never an owner.

Keys of the owner table: a topic whose every message is owned (``obstacle_status``, ``robot_status``),
or a sender name whose claim on mode_cmd / move_cmd must be backed by that node (``joy_control``:
``acquire joy`` and the joystick's move_cmd; ``move_base``: task mode's move_cmd). A sender not in
the table (``server``, the backend through the bridge) is anyone's to use. Owner names are resolved
relative to the node's namespace, as ROS resolves a relative node name: a robot under ``/robot_7``
owns its inputs by ``/robot_7/obstacle_detector``.

Pure logic (no rospy); robot_control, move_base and charge_control wire it.
"""
import threading

OBSTACLE_STATUS = "obstacle_status"
ROBOT_STATUS = "robot_status"
DEFAULT_OWNERS = {
    OBSTACLE_STATUS: "obstacle_detector",
    ROBOT_STATUS: "status_control",
    "joy_control": "joy_control",
    "move_base": "move_base",
}


def resolve_node_name(namespace, name):
    """``name`` as a global node name: absolute names stay, relative ones join ``namespace``."""
    if not isinstance(name, str) or not name.strip("/") or name.startswith("~") or any(c.isspace() for c in name):
        raise ValueError("an owner must be a node name, got %r" % (name,))
    if name.startswith("/"):
        return name
    return "%s/%s" % (("/" + namespace.strip("/")).rstrip("/"), name)


class OwnerCheck(object):
    """``owners``: {key: node name} over DEFAULT_OWNERS' keys (a subset keeps the others' defaults);
    ``namespace``: the node's namespace (``/`` or ``/robot_7/``). Thread-safe: subscriber callbacks of
    several topics call ``allows`` at once."""

    def __init__(self, namespace, owners=None):
        table = dict(DEFAULT_OWNERS)
        for key, name in (owners or {}).items():
            if key not in DEFAULT_OWNERS:
                raise ValueError("unknown owner key %r (one of %s)" % (key, ", ".join(sorted(DEFAULT_OWNERS))))
            table[key] = name
        self.owners = {key: resolve_node_name(namespace, name) for key, name in table.items()}
        self._lock = threading.Lock()
        self._refused = {}

    def owner(self, key):
        """The owner's global node name, or None when ``key`` has none (anyone may send it)."""
        return self.owners.get(key)

    def allows(self, key, caller_id):
        """True when ``key`` has no owner or ``caller_id`` is its owner; otherwise counts a refusal.
        An unknown caller (None: this rospy does not say) is not the owner: the input is refused."""
        owner = self.owners.get(key)
        if owner is None or caller_id == owner:
            return True
        with self._lock:
            self._refused[key] = self._refused.get(key, 0) + 1
        return False

    def refusal(self, key, caller_id):
        """Why a message was refused: what, from whom, who owns it."""
        return ("%s from %s ignored: only %s may send it"
                % (key if key in (OBSTACLE_STATUS, ROBOT_STATUS) else "sender '%s'" % key,
                   caller_id or "an unknown caller", self.owners.get(key)))

    def refused(self):
        """{key: refused messages} so far (diagnostics, logs)."""
        with self._lock:
            return dict(self._refused)

    def total_refused(self):
        with self._lock:
            return sum(self._refused.values())
