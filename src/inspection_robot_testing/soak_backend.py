"""The chaos soak's backend: its websocket session (publish, call services, a heartbeat thread
under a session number of its own) and a client that subscribes and never reads.

No ROS: the soak reaches the robot here only over the bridge, as a backend does. ros/soak.py
drives one session through its patrol; the faults (ros/soak_faults.py) open more (a spoofing
client, a hundred clients and a silent one).
"""
import base64
import json
import os
import socket
import threading
import time

from inspection_robot.interface import SENDER_SERVER
from inspection_robot_testing.bridge_client import RawClient


class Backend(object):
    """The backend's websocket session: publish, call services, a heartbeat thread. Each connection
    beats under a session number of its own (docs/interface.md, "Heartbeat and status", **Sessions**)."""

    def __init__(self, port, rng):
        self._rng = rng
        self.session = 0
        self._url = "ws://127.0.0.1:%d" % port
        self._lock = threading.Lock()
        self._ids = 0
        self._heartbeat = None
        self.client = None
        self.connect()

    def connect(self):
        self.client = RawClient(self._url, timeout=20.0)
        self.session = self._rng.randint(1, 2 ** 32 - 1)
        for topic, msg_type in (("/server_status", "inspection_robot/GeneralTopic"),
                                ("/mode_cmd", "inspection_robot/GeneralCmd"),
                                ("/move_cmd", "inspection_robot/MoveCmd")):
            self.client.send({"op": "advertise", "topic": topic, "type": msg_type})

    def close(self):
        self.stop_heartbeat()
        self.client.close()

    def publish(self, topic, msg):
        self.client.send({"op": "publish", "topic": topic, "msg": msg})

    def call(self, service, cmd, data="", timeout=30.0):
        with self._lock:
            self._ids += 1
            call_id = "soak%d" % self._ids
            self.client.send({"op": "call_service", "id": call_id, "service": service,
                              "args": {"sender": SENDER_SERVER, "trans_id": self._ids, "cmd": cmd, "data": data}})
            reply = self.client.recv_message(lambda m: m.get("op") == "service_response" and m.get("id") == call_id,
                                             timeout)
        if not reply.get("result"):
            return "error", str(reply.get("values"))
        return reply["values"]["ack"], reply["values"]["data"]

    def start_heartbeat(self, period=0.3):
        self.stop_heartbeat()
        stop = threading.Event()

        def beat():
            while not stop.wait(period):
                self.publish("/server_status", {"sender": SENDER_SERVER, "trans_id": self.session, "data": ""})
        thread = threading.Thread(target=beat, name="soak_heartbeat")
        thread.daemon = True
        thread.start()
        self._heartbeat = (stop, thread)

    def stop_heartbeat(self):
        if self._heartbeat is not None:
            self._heartbeat[0].set()
            self._heartbeat[1].join(2.0)
            self._heartbeat = None

    def drive(self, velocity_mm_s, seconds):
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.publish("/move_cmd", {"sender": SENDER_SERVER, "velocity_x": velocity_mm_s, "velocity_yaw": 0.0,
                                       "wheel_control": 0})
            time.sleep(0.05)  # the backend's command rate (20 Hz)


def silent_client(port, topic, msg_type):
    """A websocket client that subscribes to ``topic`` and never reads (tiny receive buffer)."""
    sock = socket.create_connection(("127.0.0.1", port), timeout=10.0)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall(("GET / HTTP/1.1\r\nHost: 127.0.0.1:%d\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                  "Sec-WebSocket-Key: %s\r\nSec-WebSocket-Version: 13\r\n\r\n" % (port, key)).encode())
    sock.recv(1024)  # the 101 answer; nothing is read after this
    payload = json.dumps({"op": "subscribe", "topic": topic, "type": msg_type}).encode()
    mask = os.urandom(4)
    header = bytes([0x81, 0x80 | len(payload)]) if len(payload) < 126 else \
        bytes([0x81, 0x80 | 126]) + len(payload).to_bytes(2, "big")
    sock.sendall(header + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(payload)))
    return sock
