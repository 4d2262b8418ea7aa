#!/usr/bin/env python3
"""Benchmark of the backend link: the project's bridge against a plain websocket echo server.

Starts its own roscore and rosbridge_websocket (port 0), plus an in-process tornado echo server
that answers each publish / call_service frame with the same frame / an empty service_response.
The same clients (a raw tornado websocket client and roslibpy) measure, against both:
publish->subscribe round trip (p50/p99), one-way throughput client->ROS and ROS->client (msgs/s),
call_service latency to a ROS ControlService and to /rosapi/get_time. One JSON line per figure;
``ratio`` = bridge / echo (latency) or bridge / echo (throughput). Runs in well under 90 s.
"""
import asyncio
import concurrent.futures
import json
import os
import queue
import socket
import subprocess
import sys
import threading
import time

N_RTT = 1000
N_THROUGHPUT = 5000
N_CALLS = 300
WINDOW = 200


def free_port():
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    port = sock.getsockname()[1]
    sock.close()
    return port


def percentile(values, q):
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(q * (len(ordered) - 1))))]


def report(**fields):
    print(json.dumps(fields), flush=True)


def start_echo_server():
    """A plain websocket server doing the least a rosbridge peer must: echo publish, answer calls."""
    import tornado.ioloop
    import tornado.web
    import tornado.websocket

    class Echo(tornado.websocket.WebSocketHandler):
        def check_origin(self, origin):
            return True

        def open(self):
            self.set_nodelay(True)

        def on_message(self, message):
            msg = json.loads(message)
            if msg.get("op") == "publish":
                self.write_message(message)
            elif msg.get("op") == "call_service":
                self.write_message(json.dumps({"op": "service_response", "service": msg["service"], "values": {},
                                               "result": True, "id": msg.get("id")}))

    ready = concurrent.futures.Future()

    def run():
        asyncio.set_event_loop(asyncio.new_event_loop())
        app = tornado.web.Application([(r"/.*", Echo)])
        server = app.listen(0, "127.0.0.1")
        ready.set_result(next(iter(server._sockets.values())).getsockname()[1])
        tornado.ioloop.IOLoop.current().start()
    thread = threading.Thread(target=run)
    thread.daemon = True
    thread.start()
    return ready.result(5)


def raw_rtt(client, topic, n):
    client.send({"op": "subscribe", "topic": topic, "type": "std_msgs/String"})
    client.send({"op": "advertise", "topic": topic, "type": "std_msgs/String"})
    deadline = time.monotonic() + 10
    while True:  # until the ROS loopback connection is up
        client.send({"op": "publish", "topic": topic, "msg": {"data": "warmup"}})
        try:
            client.recv_message(lambda m: m.get("op") == "publish", timeout=0.2)
            break
        except queue.Empty:
            if time.monotonic() > deadline:
                raise
    drain(client)
    samples = []
    for i in range(n):
        t0 = time.perf_counter()
        client.send('{"op":"publish","topic":"%s","msg":{"data":"%d"}}' % (topic, i))
        client.recv_message(lambda m: m.get("op") == "publish" and m["msg"]["data"] == str(i), timeout=5)
        samples.append((time.perf_counter() - t0) * 1000.0)
    return samples


def drain(client):
    try:
        while True:
            client.recv(0.2)
    except queue.Empty:
        pass


def raw_throughput_loopback(client, topic, n):
    """Publish n messages with at most WINDOW in flight; msgs/s until the last came back."""
    t0 = time.perf_counter()
    sent = received = 0
    while received < n:
        while sent < n and sent - received < WINDOW:
            client.send('{"op":"publish","topic":"%s","msg":{"data":"%d"}}' % (topic, sent))
            sent += 1
        frame = client.recv(5)
        if isinstance(frame, str) and frame.startswith('{"op":"publish"'):
            received += 1
    return n / (time.perf_counter() - t0)


def raw_calls(client, service, args, n):
    samples = []
    for i in range(n):
        t0 = time.perf_counter()
        client.send({"op": "call_service", "id": "c%d" % i, "service": service, "args": args})
        reply = client.recv_message(lambda m: m.get("op") == "service_response" and m.get("id") == "c%d" % i, 5)
        if not reply["result"]:
            raise RuntimeError("call failed: %s" % reply)
        samples.append((time.perf_counter() - t0) * 1000.0)
    return samples


def roslibpy_rtt(port, topic, n):
    import roslibpy
    ros = roslibpy.Ros("127.0.0.1", port)
    ros.run(timeout=10)
    got = queue.Queue()
    listener = roslibpy.Topic(ros, topic, "std_msgs/String")
    listener.subscribe(lambda m: got.put(m["data"]))
    talker = roslibpy.Topic(ros, topic, "std_msgs/String")
    deadline = time.monotonic() + 10
    while True:
        talker.publish(roslibpy.Message({"data": "warmup"}))
        try:
            got.get(timeout=0.2)
            break
        except queue.Empty:
            if time.monotonic() > deadline:
                raise
    while not got.empty():
        got.get()
    samples = []
    for i in range(n):
        t0 = time.perf_counter()
        talker.publish(roslibpy.Message({"data": str(i)}))
        while got.get(timeout=5) != str(i):
            pass
        samples.append((time.perf_counter() - t0) * 1000.0)
    ros.close()
    return samples


def latency_line(name, bridge, echo, **extra):
    report(bench=name, p50_ms=round(percentile(bridge, 0.5), 3), p99_ms=round(percentile(bridge, 0.99), 3),
           n=len(bridge), echo_p50_ms=round(percentile(echo, 0.5), 3), echo_p99_ms=round(percentile(echo, 0.99), 3),
           ratio_p50=round(percentile(bridge, 0.5) / percentile(echo, 0.5), 2), **extra)


def main():
    master_port = free_port()
    os.environ["ROS_MASTER_URI"] = "http://127.0.0.1:%d" % master_port
    env = dict(os.environ)
    procs = [subprocess.Popen(["roscore", "-p", str(master_port)], stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL, env=env)]
    try:
        import rospy
        from std_msgs.msg import String

        from inspection_robot.bridge.client import RawClient
        from inspection_robot.srv import ControlService, ControlServiceResponse

        import rosgraph
        deadline = time.monotonic() + 20
        while not rosgraph.is_master_online():
            if time.monotonic() > deadline:
                raise RuntimeError("roscore did not start")
            time.sleep(0.1)
        procs.append(subprocess.Popen(
            [sys.executable, "-c", "from inspection_robot.nodes.rosbridge_websocket import main; main()",
             "__name:=bench_bridge", "_port:=0", "_address:=127.0.0.1", "_send_queue_size:=10000"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env))
        rospy.init_node("bench_bridge_client", disable_signals=True)
        rospy.Service("/bench_control", ControlService,
                      lambda req: ControlServiceResponse(trans_id=req.trans_id, ack="success", data=req.data))
        counter = {"n": 0}
        rospy.Subscriber("/bench/to_ros", String, lambda m: counter.__setitem__("n", counter["n"] + 1),
                         queue_size=10000)
        deadline = time.monotonic() + 20
        while not rospy.has_param("/bench_bridge/actual_port"):
            if time.monotonic() > deadline:
                raise RuntimeError("bridge did not start")
            time.sleep(0.1)
        bridge_url = "ws://127.0.0.1:%d" % rospy.get_param("/bench_bridge/actual_port")
        echo_port = start_echo_server()
        echo_url = "ws://127.0.0.1:%d" % echo_port

        bridge, echo = RawClient(bridge_url), RawClient(echo_url)
        latency_line("bridge_rtt", raw_rtt(bridge, "/bench/echo", N_RTT), raw_rtt(echo, "/bench/echo", N_RTT),
                     client="raw_tornado", path="client->bridge->ROS->bridge->client")
        drain(bridge)
        bridge_loop = raw_throughput_loopback(bridge, "/bench/echo", N_THROUGHPUT)
        echo_loop = raw_throughput_loopback(echo, "/bench/echo", N_THROUGHPUT)
        report(bench="bridge_throughput_loopback", msgs_s=round(bridge_loop), n=N_THROUGHPUT,
               echo_msgs_s=round(echo_loop), ratio=round(bridge_loop / echo_loop, 2), window=WINDOW,
               path="client->bridge->ROS->bridge->client")
        bridge.send({"op": "unsubscribe", "topic": "/bench/echo"})
        drain(bridge)

        # one way, client -> ROS (counted by a ROS subscriber)
        bridge.send({"op": "advertise", "topic": "/bench/to_ros", "type": "std_msgs/String"})
        deadline = time.monotonic() + 10
        while counter["n"] == 0 and time.monotonic() < deadline:
            bridge.send({"op": "publish", "topic": "/bench/to_ros", "msg": {"data": "warmup"}})
            time.sleep(0.05)
        start_count = counter["n"]
        t0 = time.perf_counter()
        for i in range(N_THROUGHPUT):
            bridge.send('{"op":"publish","topic":"/bench/to_ros","msg":{"data":"%d"}}' % i)
            if i % WINDOW == WINDOW - 1:
                while counter["n"] - start_count < i - WINDOW and time.perf_counter() - t0 < 30:
                    time.sleep(0.0005)
        while counter["n"] - start_count < N_THROUGHPUT and time.perf_counter() - t0 < 30:
            time.sleep(0.0005)
        to_ros = (counter["n"] - start_count) / (time.perf_counter() - t0)
        report(bench="bridge_throughput_to_ros", msgs_s=round(to_ros), n=N_THROUGHPUT,
               received=counter["n"] - start_count, echo_msgs_s=round(echo_loop), ratio=round(to_ros / echo_loop, 2),
               path="client->bridge->ROS subscriber")

        # one way, ROS -> client
        pub = rospy.Publisher("/bench/from_ros", String, queue_size=10000)
        bridge.send({"op": "subscribe", "topic": "/bench/from_ros", "type": "std_msgs/String"})
        deadline = time.monotonic() + 10
        while True:  # until a warm-up message made it through
            pub.publish(String(data="warmup"))
            try:
                bridge.recv(0.1)
                break
            except queue.Empty:
                if time.monotonic() > deadline:
                    raise
        drain(bridge)
        received = 0
        t0 = time.perf_counter()
        for i in range(N_THROUGHPUT):
            pub.publish(String(data=str(i)))
            if i % 50 == 49:  # rospy's publisher must not outrun the bridge's ROS queue
                while received < i - WINDOW:
                    bridge.recv(5)
                    received += 1
        try:
            while received < N_THROUGHPUT:
                bridge.recv(1.0)
                received += 1
        except queue.Empty:
            pass
        from_ros = received / (time.perf_counter() - t0)
        report(bench="bridge_throughput_from_ros", msgs_s=round(from_ros), n=N_THROUGHPUT, received=received,
               echo_msgs_s=round(echo_loop), ratio=round(from_ros / echo_loop, 2), path="ROS publisher->bridge->client")
        bridge.send({"op": "unsubscribe", "topic": "/bench/from_ros"})
        drain(bridge)

        args = {"sender": "bench", "trans_id": 1, "cmd": "noop", "data": "x"}
        echo_calls = raw_calls(echo, "/bench_control", args, N_CALLS)
        latency_line("bridge_call_service", raw_calls(bridge, "/bench_control", args, N_CALLS), echo_calls,
                     service="/bench_control (inspection_robot/ControlService, rospy server)")
        latency_line("bridge_call_service", raw_calls(bridge, "/rosapi/get_time", {}, N_CALLS), echo_calls,
                     service="/rosapi/get_time (in-process)")
        bridge.close()
        echo.close()

        latency_line("bridge_rtt", roslibpy_rtt(int(bridge_url.rsplit(":", 1)[1]), "/bench/roslibpy", 300),
                     roslibpy_rtt(echo_port, "/bench/roslibpy", 300), client="roslibpy")
    finally:
        for proc in reversed(procs):
            proc.terminate()
        for proc in reversed(procs):
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
    os._exit(0)  # roslibpy's twisted reactor thread cannot be restarted or joined cleanly


if __name__ == "__main__":
    main()
