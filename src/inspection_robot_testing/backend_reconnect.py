"""A backend that disconnects and a new one that acquires at once (issue #44 item 2), over the websocket.

Used by client_examples.test, bench/bench_backend_reconnect.py and the chaos soak. Backend A beats,
acquires server mode and drops its connection; backend B connects, beats and acquires at once, then
watches robot_status until A's last heartbeat has expired (``hold_s``): control is kept when B's
acquire was granted and every robot_status meanwhile says mode 1 and online.

``numbered=True`` is the documented sequence (docs/interface.md, "Heartbeat and status",
**Sessions**): the heartbeat's trans_id is the backend's session number, the backend waits for a
robot_status that names it (offline_warn 0, trans_id = session) and acquires with trans_id =
session. ``numbered=False`` is the sequence before it: heartbeat trans_id 0, wait for offline_warn 0,
acquire (what the examples did, first beat one period after connecting, and what a backend on
main's code can do). B connects ``gap_s`` after A left (a restarted backend: 0 to the heartbeat
timeout), so A's last heartbeat may still hold the robot online when B acquires.

Test harness (RawClient, no rospy).
"""
import queue
import random
import threading
import time

from inspection_robot_testing.bridge_client import RawClient

SENDER = "server"
GRANT_SHOWN_S = 5.0   # robot_status shows a grant at once (published on change); 5 s covers a loaded machine


class WsBackend(object):
    """One backend connection: a heartbeat thread (``period`` s), robot_status and mode_ack read."""

    def __init__(self, url, numbered=True, period=0.3, rng=random):
        self.session = rng.randint(1, 2 ** 32 - 1) if numbered else 0
        self.client = RawClient(url, timeout=20.0)
        self._stop = threading.Event()
        for topic, msg_type in (("/server_status", "inspection_robot/GeneralTopic"),
                                ("/mode_cmd", "inspection_robot/GeneralCmd")):
            self.client.send({"op": "advertise", "topic": topic, "type": msg_type})
        for topic, msg_type in (("/robot_status", "inspection_robot/RobotStatus"),
                                ("/mode_ack", "inspection_robot/GeneralAck")):
            self.client.send({"op": "subscribe", "topic": topic, "type": msg_type})
        if numbered:
            self._beat()
        self._thread = threading.Thread(target=self._beats, args=(period,), name="backend_heartbeat")
        self._thread.daemon = True
        self._thread.start()

    def _beat(self):
        self.client.send({"op": "publish", "topic": "/server_status",
                          "msg": {"sender": SENDER, "trans_id": self.session, "data": ""}})

    def _beats(self, period):
        while not self._stop.wait(period):
            try:
                self._beat()
            except Exception:  # boundary: the connection is going away; the heartbeat just ends
                return

    def status(self, predicate, timeout):
        """The first robot_status (its msg dict) for which ``predicate`` holds; queue.Empty on timeout."""
        return self.client.recv_message(lambda m: m.get("topic") == "/robot_status" and predicate(m["msg"]),
                                        timeout)["msg"]

    def online(self, timeout=10.0):
        """Wait until the robot says online: on this backend's own heartbeat when numbered."""
        return self.status(lambda s: s["offline_warn"] == 0 and (not self.session or s["trans_id"] == self.session),
                           timeout)

    def mode(self, cmd, data, trans_id, timeout=10.0):
        """A mode_cmd and its mode_ack: (ack, data)."""
        self.client.send({"op": "publish", "topic": "/mode_cmd",
                          "msg": {"sender": SENDER, "trans_id": trans_id, "cmd": cmd, "data": data}})
        ack = self.client.recv_message(lambda m: m.get("topic") == "/mode_ack" and m["msg"]["trans_id"] == trans_id,
                                       timeout)["msg"]
        return ack["ack"], ack["data"]

    def acquire(self, tries=5, timeout=2.0):
        """acquire server until answered: the bridge's new subscription to mode_ack may connect after
        the first answer went out (an acquire of the mode held is answered success again)."""
        for _ in range(tries - 1):
            try:
                return self.mode("acquire", "server", self.session or 7, timeout)
            except queue.Empty:
                continue
        return self.mode("acquire", "server", self.session or 7, timeout)

    def close(self):
        self._stop.set()
        self._thread.join(2.0)
        self.client.close()


def reconnect_trial(url, hold_s, gap_s=0.0, numbered=True, rng=random):
    """One try: returns {"kept": bool, "why": text, "held": (from, to)}. ``hold_s``: how long B watches
    after its grant (more than the heartbeat timeout, so A's last heartbeat expires meanwhile);
    ``held``: the wall-clock span B watched (a caller with ROS access can tell whether the robot went
    offline in it: no heartbeat at all reached status_control, B's included)."""
    a = WsBackend(url, numbered, rng=rng)
    try:
        a.online()
        ack, data = a.acquire()
        if ack != "success":
            return {"kept": False, "why": "A's acquire: %s %s" % (ack, data)}
    finally:
        a.close()   # abrupt: its heartbeat stops with it
    time.sleep(gap_s)
    b = WsBackend(url, numbered, rng=rng)
    try:
        b.online()
        ack, data = b.acquire()
        if ack != "success":
            return {"kept": False, "why": "B's acquire: %s %s" % (ack, data)}
        # robot_status and mode_ack travel on two connections: a status published before the grant may
        # arrive after its ack (seen beside two CPU hogs: mode 0 0.3 s after the grant). Watch from the
        # first status that shows the grant; one that never comes is a loss.
        try:
            b.status(lambda s: s["mode"] == 1 and s["offline_warn"] == 0, GRANT_SHOWN_S)
        except queue.Empty:
            return {"kept": False, "why": "B's grant never showed in robot_status within %.0f s" % GRANT_SHOWN_S}
        held = (time.time(), time.time() + hold_s)
        deadline = time.monotonic() + hold_s
        while time.monotonic() < deadline:
            try:
                lost = b.status(lambda s: s["mode"] != 1 or s["offline_warn"] != 0,
                                max(0.05, deadline - time.monotonic()))
            except queue.Empty:   # nothing but mode 1 online until the deadline
                break
            return {"kept": False, "why": "B lost control: mode %d, offline_warn %d" % (lost["mode"],
                                                                                        lost["offline_warn"]),
                    "held": (held[0], time.time())}
        b.mode("release", "", 3, timeout=5.0)
        return {"kept": True, "why": "", "held": held}
    finally:
        b.close()
