#!/usr/bin/env python3
"""rostest: the backend link driven by roslibpy (unmodified client) and a raw websocket client."""
import hashlib
import json
import queue
import threading
import time
import unittest

import actionlib
import roslibpy
import roslibpy.actionlib
import rosgraph
import rospy
import rostest
from std_msgs.msg import Int32, String

from inspection_robot.bridge import cbor
from inspection_robot_testing.bridge_client import CLOSED, RawClient
from inspection_robot.bridge.compression import png_decode
from inspection_robot.interface import BACKEND_ACK_TYPES, BACKEND_TOPIC_TYPES
from inspection_robot.msg import GeneralAck, GeneralAction, GeneralCmd, GeneralFeedback, GeneralResult, GeneralTopic
from inspection_robot.srv import ControlService, ControlServiceResponse
from rostest_helpers import Latest, wait_for, wait_subscribed

NS = "/bridge_test/"


def wait_port(param):
    return int(wait_for(lambda: rospy.get_param(param, None), 10.0, param))


def topic_nodes(topic, kind):
    pubs, subs, _srvs = rospy.get_master().getSystemState()[2]
    table = pubs if kind == "pub" else subs
    return next((nodes for name, nodes in table if name == topic), [])


def publish_until(topic, values, sink, timeout=5.0):
    """Publish through the bridge until the ROS sink got it (TCPROS connects asynchronously)."""
    def attempt():
        topic.publish(roslibpy.Message(values))
        return sink.wait(timeout=0.3)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            return attempt()
        except AssertionError:
            continue
    raise AssertionError("nothing arrived on %s" % topic.name)


class BridgeLinkTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_bridge_link")
        cls.port = wait_port("/rosbridge_websocket/actual_port")
        cls.secured_port = wait_port("/secured/rosbridge_websocket/actual_port")
        cls.url = "ws://127.0.0.1:%d" % cls.port
        cls.ros = roslibpy.Ros("127.0.0.1", cls.port)
        cls.ros.run(timeout=10)
        cls.control_calls = []
        rospy.Service(NS + "test_control", ControlService, cls._on_control)
        cls.count = Latest("/client_count", Int32)

    @classmethod
    def tearDownClass(cls):
        cls.ros.terminate()

    @classmethod
    def _on_control(cls, request):
        cls.control_calls.append(request)
        return ControlServiceResponse(trans_id=request.trans_id, ack="success", data=request.cmd + ":" + request.data)

    def raw(self, url=None):
        client = RawClient(url or self.url)
        self.addCleanup(client.close)
        return client

    # ------------------------------------------------------------------ topics, both directions
    def test_std_msgs_both_directions(self):
        received = queue.Queue()
        listener = roslibpy.Topic(self.ros, NS + "to_client", "std_msgs/String")
        listener.subscribe(received.put)
        self.addCleanup(listener.unsubscribe)
        pub = rospy.Publisher(NS + "to_client", String, queue_size=10)
        wait_for(lambda: "/rosbridge_websocket" in topic_nodes(NS + "to_client", "sub"), 5.0, "bridge subscriber")
        wait_subscribed(pub)
        pub.publish(String(data="from ros"))
        self.assertEqual(received.get(timeout=5.0), {"data": "from ros"})

        from_client = Latest(NS + "from_client", String)
        talker = roslibpy.Topic(self.ros, NS + "from_client", "std_msgs/String")
        talker.advertise()
        self.addCleanup(talker.unadvertise)
        from_client.wait_connected()
        publish_until(talker, {"data": "from client"}, from_client)
        self.assertEqual(from_client.last.data, "from client")

    def test_first_publish_after_advertise_is_not_lost(self):
        """As rosbridge does: a subscriber that connects just after the client's publish still gets it."""
        heard = Latest(NS + "first_publish", String)
        talker = roslibpy.Topic(self.ros, NS + "first_publish", "std_msgs/String")
        self.addCleanup(talker.unadvertise)
        talker.publish(roslibpy.Message({"data": "only once"}))  # advertises implicitly, publishes at once
        heard.wait(lambda m: m.data == "only once", 5.0, "the single early message")
        self.assertEqual([m.data for _t, m in heard.messages], ["only once"])

    def test_spec_messages_both_directions(self):
        acks = queue.Queue()
        listener = roslibpy.Topic(self.ros, NS + "camera_ack", "inspection_robot/GeneralAck")
        listener.subscribe(acks.put)
        self.addCleanup(listener.unsubscribe)
        pub = rospy.Publisher(NS + "camera_ack", GeneralAck, queue_size=10)
        wait_subscribed(pub)
        ack = GeneralAck(sender="camera_node", receiver="server", trans_id=77, ack="success", data="1,2")
        ack.header.stamp = rospy.Time(12, 345)
        pub.publish(ack)
        got = acks.get(timeout=5.0)
        self.assertEqual((got["trans_id"], got["ack"], got["data"]), (77, "success", "1,2"))
        self.assertEqual(got["header"]["stamp"], {"secs": 12, "nsecs": 345})

        cmds = Latest(NS + "camera_cmd", GeneralCmd)
        talker = roslibpy.Topic(self.ros, NS + "camera_cmd", "inspection_robot/GeneralCmd")
        talker.advertise()
        self.addCleanup(talker.unadvertise)
        cmds.wait_connected()
        before = rospy.Time.now()
        publish_until(talker, {"header": {"frame_id": ""}, "sender": "server", "trans_id": 5, "cmd": "zoom_to",
                               "data": "3"}, cmds)
        msg = cmds.last
        self.assertEqual((msg.sender, msg.trans_id, msg.cmd, msg.data), ("server", 5, "zoom_to", "3"))
        self.assertGreaterEqual(msg.header.stamp, before - rospy.Duration(1))  # stamped "now" by the bridge

    # ------------------------------------------------------------------ services
    def test_call_project_service_dict_and_list_args(self):
        service = roslibpy.Service(self.ros, NS + "test_control", "inspection_robot/ControlService")
        result = service.call(roslibpy.ServiceRequest({"sender": "server", "trans_id": 9, "cmd": "query",
                                                      "data": "x"}), timeout=5.0)
        self.assertEqual(dict(result), {"trans_id": 9, "ack": "success", "data": "query:x"})
        client = self.raw()
        client.send({"op": "call_service", "id": "list", "service": NS + "test_control",
                     "args": [{}, "s", "r", 4, "c", "d"]})
        reply = client.recv_message(lambda m: m["op"] == "service_response")
        self.assertEqual((reply["id"], reply["result"], reply["values"]["data"]), ("list", True, "c:d"))
        client.send({"op": "call_service", "id": "missing", "service": NS + "no_such_service"})
        reply = client.recv_message(lambda m: m["op"] == "service_response")
        self.assertFalse(reply["result"])
        self.assertIn("does not exist", reply["values"])

    def test_call_service_timeout(self):
        release = threading.Event()
        self.addCleanup(release.set)

        def stuck(request):
            release.wait(30.0)   # answers only after the test: a reply before that is the bridge's timeout
            return ControlServiceResponse(trans_id=request.trans_id, ack="success", data="late")
        service = rospy.Service(NS + "stuck_control", ControlService, stuck)
        self.addCleanup(service.shutdown)
        client = self.raw()
        client.send({"op": "call_service", "id": "slow", "service": NS + "stuck_control", "timeout": 0.3,
                     "args": {"sender": "s", "trans_id": 1, "cmd": "c", "data": "d"}})
        reply = client.recv_message(lambda m: m["op"] == "service_response", timeout=20.0)
        self.assertEqual((reply["id"], reply["result"]), ("slow", False))
        self.assertIn("Timeout", reply["values"])
        self.assertFalse(release.is_set())   # answered by the bridge's timeout, not by the service
        release.set()  # the late ROS response is dropped; the connection keeps serving
        client.send({"op": "call_service", "id": "after", "service": NS + "test_control", "timeout": 5,
                     "args": {"sender": "s", "trans_id": 2, "cmd": "c", "data": "d"}})
        reply = client.recv_message(lambda m: m["op"] == "service_response", timeout=5.0)
        self.assertEqual((reply["id"], reply["result"]), ("after", True))

    def test_client_advertised_service_called_from_ros(self):
        def handler(request, response):
            response["trans_id"] = request["trans_id"]
            response["ack"] = "success"
            response["data"] = "client saw " + request["cmd"]
            return True
        service = roslibpy.Service(self.ros, NS + "client_control", "inspection_robot/ControlService")
        service.advertise(handler)
        self.addCleanup(service.unadvertise)
        rospy.wait_for_service(NS + "client_control", timeout=5.0)
        proxy = rospy.ServiceProxy(NS + "client_control", ControlService)
        response = proxy(sender="ros", trans_id=3, cmd="ping", data="")
        self.assertEqual((response.trans_id, response.ack, response.data), (3, "success", "client saw ping"))

    # ------------------------------------------------------------------ actions
    def test_actionlib_goal_feedback_result(self):
        def execute(goal):
            server.publish_feedback(GeneralFeedback(event_code="progress", data=goal.data))
            rospy.sleep(0.2)
            server.set_succeeded(GeneralResult(ret_code="0", data=json.dumps({"done": goal.type})))
        server = actionlib.SimpleActionServer(NS + "move_action", GeneralAction, execute, auto_start=False)
        server.start()
        client = roslibpy.actionlib.ActionClient(self.ros, NS + "move_action", "inspection_robot/GeneralAction")
        inner = server.action_server
        wait_for(lambda: inner.goal_sub.get_num_connections() > 0, 5.0, "goal topic connected")
        wait_for(lambda: inner.result_pub.get_num_connections() > 0 and inner.feedback_pub.get_num_connections() > 0,
                 5.0, "result/feedback topics connected")
        feedback = []
        goal = roslibpy.actionlib.Goal(client, roslibpy.Message({"type": "move", "data": '{"x": 1}'}))
        goal.on("feedback", feedback.append)
        goal.send()
        result = goal.wait(10)
        self.assertEqual(json.loads(result["data"]), {"done": "move"})
        self.assertEqual(feedback[0]["event_code"], "progress")
        client.dispose()

    # ------------------------------------------------------------------ the backend's topics
    def test_backend_topics_are_advertised_before_any_client_and_shared(self):
        """Every topic a backend publishes has the bridge's publisher from its start, so the robot is
        subscribed before a client's first message; a client advertising it shares that publisher."""
        state = rosgraph.Master("/test_bridge_link").getSystemState()
        publishers, subscribers = ({topic: nodes for topic, nodes in part} for part in state[:2])
        for topic in BACKEND_TOPIC_TYPES:   # published by the bridge's own TCPROS publisher, a node of its own
            self.assertIn("/rosbridge_websocket/tcpros", publishers.get("/" + topic, []), topic)
        for topic in BACKEND_ACK_TYPES:   # and it listens to their answers from its start, for the clients to join
            self.assertIn("/rosbridge_websocket", subscribers.get("/" + topic, []), topic)
        received = Latest("/server_status", GeneralTopic)
        received.wait_connected(5.0)
        client = self.raw(self.url)
        client.send({"op": "advertise", "topic": "/server_status", "type": "inspection_robot/GeneralTopic"})
        client.send({"op": "publish", "topic": "/server_status", "msg": {"sender": "server", "data": "first"}})
        self.assertEqual(received.wait(lambda m: m.data == "first", 5.0, "the first heartbeat").data, "first")
        client.send({"op": "advertise", "topic": "/server_status", "type": "std_msgs/String"})
        self.assertIn("already established with type inspection_robot/GeneralTopic", client.recv_message()["msg"])
        client.send({"op": "unadvertise", "topic": "/server_status"})
        client.close()
        wait_for(lambda: "/rosbridge_websocket/tcpros" in dict(
            rosgraph.Master("/test_bridge_link").getSystemState()[0]).get("/server_status", []), 5.0,
            "the bridge still publishing /server_status after the client left")

    # ------------------------------------------------------------------ rosapi
    def test_rosapi(self):
        pub = rospy.Publisher(NS + "rosapi_topic", GeneralAck, queue_size=1)
        self.addCleanup(pub.unregister)
        wait_for(lambda: NS + "rosapi_topic" in self.ros.get_topics(), 5.0, "topic listed")
        self.assertEqual(self.ros.get_topic_type(NS + "rosapi_topic"), "inspection_robot/GeneralAck")
        self.assertIn(NS + "rosapi_topic", self.ros.get_topics_for_type("inspection_robot/GeneralAck"))
        services = self.ros.get_services()
        self.assertIn("/rosapi/get_time", services)
        self.assertIn(NS + "test_control", services)
        self.assertEqual(self.ros.get_service_type(NS + "test_control"), "inspection_robot/ControlService")
        self.assertEqual(self.ros.get_service_type("/rosapi/topics"), "rosapi/Topics")
        self.assertIn("/rosbridge_websocket", self.ros.get_nodes())
        details = self.ros.get_message_details("inspection_robot/GeneralAck")["typedefs"]
        self.assertEqual(details[0]["fieldnames"], ["header", "sender", "receiver", "trans_id", "ack", "data"])
        self.assertIn("std_msgs/Header", [d["type"] for d in details])
        request = self.ros.get_service_request_details("inspection_robot/ControlService")["typedefs"][0]
        self.assertEqual(request["fieldnames"][-2:], ["cmd", "data"])
        response = self.ros.get_service_response_details("inspection_robot/ControlService")["typedefs"][0]
        self.assertEqual(response["fieldnames"], ["trans_id", "ack", "data"])
        self.ros.set_param(NS + "param", {"a": [1, 2]})
        self.assertEqual(self.ros.get_param(NS + "param"), {"a": [1, 2]})
        self.assertIn(NS + "param/a", self.ros.get_params())
        self.ros.delete_param(NS + "param")
        self.assertFalse(rospy.has_param(NS + "param"))
        self.assertGreater(self.ros.get_time().secs, 0)
        for name, field, args in (("publishers", "publishers", {"topic": NS + "rosapi_topic"}),
                                  ("subscribers", "subscribers", {"topic": "/client_count"}),
                                  ("has_param", "exists", {"name": "/rosbridge_websocket/port"})):
            service = roslibpy.Service(self.ros, "/rosapi/" + name, "rosapi/X")
            result = service.call(roslibpy.ServiceRequest(args), timeout=5.0)
            self.assertTrue(result[field], name)

    # ------------------------------------------------------------------ encodings
    def test_fragments_cbor_png_both_ways(self):
        pub = rospy.Publisher(NS + "encoded", String, queue_size=10)
        client = self.raw()
        for sid, extra in (("frag", {"fragment_size": 20}), ("cbor", {"compression": "cbor"}),
                           ("png", {"compression": "png"})):
            client.send(dict({"op": "subscribe", "id": sid, "topic": NS + "encoded", "type": "std_msgs/String"},
                             **extra))
            wait_subscribed(pub)
            pub.publish(String(data="payload-" + sid + "-" + "z" * 30))
            if sid == "frag":
                parts = [client.recv_message(lambda m: m["op"] == "fragment")]
                parts += [client.recv_message(lambda m: m["op"] == "fragment") for _ in range(parts[0]["total"] - 1)]
                message = json.loads("".join(p["data"] for p in sorted(parts, key=lambda p: p["num"])))
            elif sid == "cbor":
                frame = client.recv(5.0)
                self.assertIsInstance(frame, bytes)
                message = cbor.loads(frame)
            else:
                message = json.loads(png_decode(client.recv_message(lambda m: m["op"] == "png")["data"]))
            self.assertEqual(message["msg"]["data"], "payload-" + sid + "-" + "z" * 30)
            client.send({"op": "unsubscribe", "id": sid, "topic": NS + "encoded"})
            wait_for(lambda: pub.get_num_connections() == 0, 5.0, "unsubscribed")
        # incoming: a fragmented publish and a CBOR publish
        sink = Latest(NS + "incoming", String)
        client.send({"op": "advertise", "topic": NS + "incoming", "type": "std_msgs/String"})
        sink.wait_connected()
        text = json.dumps({"op": "publish", "topic": NS + "incoming", "msg": {"data": "reassembled"}})
        for num in range(0, (len(text) + 9) // 10):
            client.send({"op": "fragment", "id": "in1", "data": text[num * 10:num * 10 + 10], "num": num,
                         "total": (len(text) + 9) // 10})
        sink.wait(lambda m: m.data == "reassembled", 5.0)
        client.send(cbor.dumps({"op": "publish", "topic": NS + "incoming", "msg": {"data": "cbor in"}}))
        sink.wait(lambda m: m.data == "cbor in", 5.0)

    def test_throttle_rate_and_queue_length(self):
        pub = rospy.Publisher(NS + "fast", Int32, queue_size=100)
        client = self.raw()
        client.send({"op": "subscribe", "topic": NS + "fast", "type": "std_msgs/Int32", "throttle_rate": 300})
        everything = self.raw()
        everything.send({"op": "subscribe", "topic": NS + "fast", "type": "std_msgs/Int32"})
        wait_for(lambda: pub.get_num_connections() > 0, 5.0, "bridge subscriber")
        # frames of two connections are not ordered: the bridge may take one client's subscribe after
        # the other's subscriber is connected, so both are in place once each has heard a 0
        heard = set()

        def both_hear_zero():
            pub.publish(Int32(0))
            for name, ws in (("throttled", client), ("everything", everything)):
                try:
                    while True:
                        if ws.recv_message(timeout=0.1)["msg"]["data"] == 0:
                            heard.add(name)
                except queue.Empty:
                    pass
            return len(heard) == 2
        wait_for(both_hear_zero, 10.0, "both subscriptions in place", period=0.0)
        rospy.sleep(0.3)  # the throttled client's 300 ms window since its last 0
        rate = rospy.Rate(50)
        for i in range(1, 31):  # 0.6 s at 50 Hz
            pub.publish(Int32(i))
            rate.sleep()
        all_values = []
        while len(all_values) < 30:   # a late 0 of the handshake is not counted
            all_values += [v for v in [everything.recv_message()["msg"]["data"]] if v]
        self.assertEqual(all_values, list(range(1, 31)))
        throttled = []
        try:
            while True:
                throttled += [v for v in [client.recv_message(timeout=0.5)["msg"]["data"]] if v]
        except queue.Empty:
            pass
        self.assertGreaterEqual(len(throttled), 2)
        self.assertLessEqual(len(throttled), 4)  # one per 300 ms
        self.assertEqual(throttled[0], 1)

    # ------------------------------------------------------------------ errors
    def test_bad_input_gets_error_status_and_others_keep_working(self):
        bystander = queue.Queue()
        listener = roslibpy.Topic(self.ros, NS + "bystander", "std_msgs/String")
        listener.subscribe(bystander.put)
        self.addCleanup(listener.unsubscribe)
        client = self.raw()
        cases = [("{oops", None), (json.dumps({"op": "nope", "id": "u1"}), "u1"),
                 (json.dumps({"op": "subscribe", "id": "m1"}), "m1"),
                 (json.dumps({"op": "subscribe", "id": "w1", "topic": 3}), "w1"),
                 (json.dumps({"op": "advertise", "id": "t1", "topic": NS + "x", "type": "nope/Nope"}), "t1"),
                 (json.dumps({"op": "advertise", "id": "c1", "topic": "/client_count", "type": "std_msgs/String"}),
                  "c1"),
                 (json.dumps({"op": "publish", "id": "p1", "topic": "/client_count", "msg": {"data": "x"}}), "p1")]
        for frame, mid in cases:
            client.send(frame)
            status = client.recv_message(lambda m: m["op"] == "status")
            self.assertEqual(status["level"], "error")
            self.assertEqual(status.get("id"), mid, status)
        pub = rospy.Publisher(NS + "bystander", String, queue_size=1)
        wait_subscribed(pub)
        pub.publish(String(data="still here"))
        self.assertEqual(bystander.get(timeout=5.0)["data"], "still here")
        client.send({"op": "call_service", "id": "ok", "service": "/rosapi/get_time"})
        self.assertTrue(client.recv_message(lambda m: m["op"] == "service_response")["result"])

    # ------------------------------------------------------------------ auth
    def test_auth_reject_and_accept(self):
        url = "ws://127.0.0.1:%d" % self.secured_port
        intruder = self.raw(url)
        intruder.send({"op": "subscribe", "topic": "/client_count", "type": "std_msgs/Int32"})
        self.assertIn("Not authenticated", intruder.recv_message()["msg"])
        self.assertIs(intruder.recv(5.0), CLOSED)
        guesser = self.raw(url)
        guesser.send({"op": "auth", "mac": "guess", "client": "c", "dest": "d", "rand": "r", "t": 0, "level": "",
                      "end": 0})
        self.assertIn("authentication failed", guesser.recv_message()["msg"])
        self.assertIs(guesser.recv(5.0), CLOSED)
        friend = self.raw(url)  # the token itself: from this machine (or over TLS) only
        friend.send({"op": "auth", "mac": "s3cret-token"})
        friend.send({"op": "call_service", "id": "t", "service": "/rosapi/get_time"})
        self.assertTrue(friend.recv_message()["result"])
        challenged = self.raw(url)  # rosauth's MAC over the nonce the bridge issued to this connection
        challenged.send({"op": "auth_challenge", "id": "c"})
        challenge = challenged.recv_message()
        self.assertEqual((challenge["op"], challenge["id"], len(challenge["nonce"])), ("auth_challenge", "c", 32))
        t = challenge["t"]
        auth = {"op": "auth", "mac": hashlib.sha512(("s3cret-token" + "c" + "d" + challenge["nonce"] + str(t) + "admin"
                                                     + str(t + 60)).encode()).hexdigest(),
                "client": "c", "dest": "d", "rand": challenge["nonce"], "t": t, "level": "admin", "end": t + 60}
        challenged.send(auth)
        challenged.send({"op": "call_service", "id": "t", "service": "/rosapi/get_time"})
        self.assertTrue(challenged.recv_message()["result"])
        replay = self.raw(url)  # the same auth message captured and sent again: refused
        replay.send(auth)
        self.assertIn("rand must be the nonce", replay.recv_message()["msg"])
        self.assertIs(replay.recv(5.0), CLOSED)
        ros = roslibpy.Ros("127.0.0.1", self.secured_port)  # roslibpy unchanged, the token on the robot
        ros.authenticate("s3cret-token", "", "", "", 0, "", 0)
        ros.run(timeout=10)
        self.assertGreater(ros.get_time().secs, 0)
        ros.close()
        ros = roslibpy.Ros("127.0.0.1", self.secured_port)  # and the challenge, as docs/interface.md shows
        answered = threading.Event()

        def on_ready(proto):
            def answer(challenge):
                t, nonce = challenge["t"], challenge["nonce"]
                mac = hashlib.sha512(("s3cret-token" + "backend" + "robot" + nonce + str(t) + "server"
                                      + str(t + 3600)).encode()).hexdigest()
                proto.send_ros_message(roslibpy.Message({"op": "auth", "mac": mac, "client": "backend", "dest": "robot",
                                                         "rand": nonce, "t": t, "level": "server", "end": t + 3600}))
                answered.set()
            proto.register_message_handlers("auth_challenge", answer)
            proto.send_ros_message(roslibpy.Message({"op": "auth_challenge"}))
        ros.factory.on_ready(on_ready)
        ros.run(timeout=10)
        self.assertTrue(answered.wait(5.0))
        self.assertGreater(ros.get_time().secs, 0)
        ros.close()

    # ------------------------------------------------------------------ lifecycle
    def test_disconnect_cleanup_and_client_count(self):
        start = self.count.wait(timeout=5.0).data
        client = RawClient(self.url)
        self.count.wait(lambda m: m.data == start + 1, 5.0, "count up")
        client.send({"op": "advertise", "topic": NS + "leaving_pub", "type": "std_msgs/String"})
        client.send({"op": "subscribe", "topic": NS + "leaving_sub", "type": "std_msgs/String"})
        client.send({"op": "advertise_service", "service": NS + "leaving_srv",
                     "type": "inspection_robot/ControlService"})
        wait_for(lambda: topic_nodes(NS + "leaving_pub", "pub") and topic_nodes(NS + "leaving_sub", "sub"), 5.0,
                 "registrations")
        rospy.wait_for_service(NS + "leaving_srv", timeout=5.0)
        client.close()
        self.count.wait(lambda m: m.data == start, 5.0, "count down")
        wait_for(lambda: not topic_nodes(NS + "leaving_pub", "pub") and not topic_nodes(NS + "leaving_sub", "sub"),
                 5.0, "registrations removed")
        wait_for(lambda: NS + "leaving_srv" not in [n for n, _ in rospy.get_master().getSystemState()[2][2]],
                 5.0, "service removed")

    def test_a_reconnecting_client_loses_nothing_and_leaves_one_publisher(self):
        """A backend that drops its link and comes straight back (no wait for the bridge to see it
        leave), advertising and publishing at once: every message of every connection reaches the ROS
        subscriber, the master lists one bridge publisher, and its subscription serves it again."""
        up, down = NS + "relink_up", NS + "relink_down"
        heard = Latest(up, String)
        wait_for(lambda: "/test_bridge_link" in topic_nodes(up, "sub"), 5.0, "the ROS subscriber listed")
        to_client = rospy.Publisher(down, String, queue_size=10)
        client = None
        for k in range(4):
            if client is not None:
                client.close()
            client = self.raw()
            client.send_many([{"op": "advertise", "topic": up, "type": "std_msgs/String"}]
                             + [{"op": "publish", "topic": up, "msg": {"data": "%d.%d" % (k, i)}} for i in range(10)]
                             + [{"op": "subscribe", "topic": down, "type": "std_msgs/String"}])
            sent = ["%d.%d" % (k, i) for i in range(10)]
            heard.wait(lambda m: m.data == sent[-1], 10.0, "connection %d's last message" % k)
            self.assertEqual([m.data for _t, m in heard.messages if m.data.startswith("%d." % k)], sent)
            self.assertEqual(topic_nodes(up, "pub"), ["/rosbridge_websocket/tcpros"])
            wait_for(lambda: "/rosbridge_websocket" in topic_nodes(down, "sub"), 5.0, "the bridge subscribed")

            def delivered():
                to_client.publish(String(data="down %d" % k))
                try:
                    return client.recv_message(lambda m: m.get("topic") == down, timeout=0.3)["msg"]["data"]
                except queue.Empty:
                    return None
            self.assertEqual(wait_for(delivered, 10.0, "a message on the subscription after reconnecting"),
                             "down %d" % k)
            self.assertEqual(topic_nodes(down, "sub").count("/rosbridge_websocket"), 1)
        client.close()
        wait_for(lambda: not topic_nodes(up, "pub"), 5.0, "the publisher gone with the last client")

    def test_many_clients_share_one_subscriber(self):
        pub = rospy.Publisher(NS + "shared", Int32, queue_size=10)
        clients = [self.raw() for _ in range(5)]
        for client in clients:
            client.send({"op": "subscribe", "topic": NS + "shared", "type": "std_msgs/Int32"})
        wait_for(lambda: pub.get_num_connections() == 1, 5.0, "one bridge subscriber")
        pub.publish(Int32(42))
        for client in clients:
            self.assertEqual(client.recv_message(timeout=5.0)["msg"]["data"], 42)
        self.assertEqual(pub.get_num_connections(), 1)


if __name__ == "__main__":
    threading.current_thread().name = "main"
    rostest.rosrun("inspection_robot", "test_bridge_link", BridgeLinkTest)
