#!/usr/bin/env python3
"""rostest: task_manager as an action (task_action) over ROS and over the websocket, and its
reachability check against move_base's virtual obstacles (task_action.test).

1. A stop fenced off or covered by a virtual obstacle is refused at submission; the robot does
   not move; once the obstacle is deleted the same stop is accepted again.
2. Over ROS (actionlib): a bad goal is rejected with ret_code "3"; a one-stop task gets feedback
   (running, stop 1 of 1, preset 1 of 1) and ends aborted with ret_code "1", "every preset failed"
   (no find_scale runs in this launch), with the counts and the report path.
3. Over the websocket (roslibpy): a routine goal is pre-empted by a special goal sent over ROS and
   stays active (feedback "suspended", who pre-empted it); the special goal ends; the routine
   resumes; cancelling its goal cancels the task (ret_code "2", goal preempted).
4. return_home: task_status shows the cancelled task's end in last_ended while returning_home,
   then idle (task id "") once the robot is home.
5. order shortest: the same order and planned length as the pure planning on the same map.
6. plan, routine and schedule: plan answers the ordered stops and the path without submitting;
   a routine saved and scheduled for the next minute (~schedule_check_s 1 s in this launch) is
   submitted by task_manager itself as <routine>_<YYYYMMDD_HHMM>; schedule_list shows the run.
"""
import json
import math
import os
import time
import unittest

import actionlib
import roslibpy
import roslibpy.actionlib
import rospy
import rostest
from actionlib_msgs.msg import GoalStatus

from inspection_robot.msg import GeneralAck, GeneralAction, GeneralCmd, GeneralGoal, GeneralTopic, RobotStatus
from inspection_robot.task.checks import Reachability
from inspection_robot.task.route import plan_route
from inspection_robot.task.spec import ORDER_SHORTEST, Task
from inspection_robot_testing.fixtures import make_lamp_preset
from rostest_helpers import GroundTruth, Latest, TwinClient, localizer_tolerance, pose_error, wait_for, wait_subscribed

PRESET = "act_lamp"
FAR_STOPS = [(20.0, 21.4), (10.0, 5.0)]
HOME = (5.0, 5.0)   # config/sim_site.yaml task_manager/home_pose
MAP = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "config", "maps", "substation.yaml")


def task(task_id, stops, priority="routine", order="given"):
    return json.dumps({"id": task_id, "priority": priority, "retries": 0, "order": order,
                       "stops": [{"name": "s%d" % i, "pose": {"x": x, "y": y, "yaw": 0.0}, "presets": [PRESET]}
                                 for i, (x, y) in enumerate(stops)]})


class TaskActionTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_task_action")
        make_lamp_preset(rospy.get_param("/data_root"), PRESET)
        cls.status = Latest("task_status", GeneralTopic, queue_size=500)
        # robot_status carries the localizer's pose: what task_manager plans from (test 5)
        cls.robot = Latest("robot_status", RobotStatus, queue_size=10)
        cls.true_pose = GroundTruth()   # where the robot is
        cls.vo_acks = Latest("virtual_obstacle_ack", GeneralAck)
        cls.vo_cmd = rospy.Publisher("virtual_obstacle_cmd", GeneralCmd, queue_size=10)
        wait_subscribed(cls.vo_cmd, 60.0)
        # the replies' publishers must have added this node before the first request (Latest.wait_connected)
        cls.vo_acks.wait_connected(60.0)
        cls.tasks = TwinClient("task_control", "task_cmd", "task_ack", "task_manager", timeout=60.0)
        cls.robot.wait(lambda m: len(m.position) == 2, 60.0, "robot_status with a pose")
        cls.action = actionlib.ActionClient("task_action", GeneralAction)
        assert cls.action.wait_for_server(rospy.Duration(30.0)), "task_action server"
        port = int(wait_for(lambda: rospy.get_param("/rosbridge_websocket/actual_port", None), 60.0, "bridge port"))
        cls.ros = roslibpy.Ros("127.0.0.1", port)
        cls.ros.run(timeout=20)

    @classmethod
    def tearDownClass(cls):
        cls.ros.terminate()

    def virtual(self, cmd, obstacle):
        trans_id = int(rospy.get_time() * 1000) % 1000000
        self.vo_cmd.publish(GeneralCmd(sender="rostest", cmd=cmd, trans_id=trans_id, data=json.dumps(obstacle)))
        ack = self.vo_acks.wait(lambda m: m.trans_id == trans_id, 10.0, "virtual_obstacle_ack")
        self.assertEqual(ack.ack, "success", ack.data)

    def wait_virtual(self, reason, what):
        """Wait until task_manager checks stops against the changed virtual layer (move_base
        republishes it after acknowledging the change; task_manager hears it a moment later).
        The probe can never be accepted: its second stop is outside the map, so the answer names
        the fenced stop while the obstacle is known and the second stop once it is not."""
        probe = task("probe", [(20.0, 21.4), (500.0, 5.0)])
        replies = []

        def answered():
            replies.append(self.tasks.call("submit", probe))
            self.assertEqual(replies[-1].ack, "failed", replies[-1].data)
            return reason in replies[-1].data
        try:
            wait_for(answered, 15.0, what, period=0.2)
        except AssertionError:
            self.fail("%s; last answer %s" % (what, replies[-1].data if replies else None))

    def wait_idle(self):
        self.status.wait(lambda m: json.loads(m.data)["state"] in ("idle", "done", "failed", "cancelled"), 60.0,
                         "no task running")

    # --- 1 --------------------------------------------------------------------------------------
    def test_1_stops_in_or_behind_virtual_obstacles_are_refused_before_the_robot_moves(self):
        self.wait_idle()
        start = self.true_pose.pose()
        fence = {"id": "fence", "points": [[18.5, 20.0], [21.5, 20.0], [21.5, 23.0], [18.5, 23.0]], "closed": True}
        self.virtual("add", fence)
        self.wait_virtual("stop 1 (s0): pose (20.00, 21.40) is unreachable: cut off", "the fence known")
        reply = self.tasks.call("submit", task("fenced", [(20.0, 21.4)]))
        self.assertEqual((reply.ack, reply.data), ("failed", "stop 1 (s0): pose (20.00, 21.40) is unreachable: "
                                                             "cut off from the home pose by virtual obstacles"))
        self.virtual("modify", {"id": "fence", "points": [[19.0, 21.4], [21.0, 21.4]], "closed": False})
        self.wait_virtual("stop 1 (s0): pose (20.00, 21.40) is unreachable: inside", "the wall known")
        reply = self.tasks.call("submit", task("covered", [(20.0, 21.4)]))
        self.assertEqual((reply.ack, reply.data), ("failed", "stop 1 (s0): pose (20.00, 21.40) is unreachable: "
                                                             "inside a virtual obstacle or too close to one"))
        now = self.true_pose.pose()
        self.assertLess(pose_error(now, start)[0], 0.05, "the robot moved from %s to %s" % (start, now))
        self.assertEqual(self.tasks.call("query_tasks").data, "[]")   # nothing was stored either
        self.virtual("delete", {"id": "fence"})
        self.wait_virtual("stop 2 (s1): pose (500.00, 5.00) is unreachable: outside the map", "the wall gone")
        reply = self.tasks.call("submit", task("free_again", [(20.0, 21.4)]))
        self.assertEqual((reply.ack, json.loads(reply.data)["task_id"]), ("success", "free_again"))
        self.assertEqual(self.tasks.call("cancel", "free_again").ack, "success")

    # --- 2 --------------------------------------------------------------------------------------
    def test_2_a_task_as_an_action_over_ros_feedback_and_result(self):
        self.wait_idle()
        bad = self.action.send_goal(GeneralGoal(sender="rostest", type="patrol", data=task("bad", [(500.0, 5.0)])))
        wait_for(lambda: bad.get_comm_state() == actionlib.CommState.DONE, 10.0, "bad goal done")
        self.assertEqual(bad.get_goal_status(), GoalStatus.REJECTED)
        self.assertEqual((bad.get_result().ret_code, json.loads(bad.get_result().data)), (
            "3", {"reason": "stop 1 (s0): pose (500.00, 5.00) is unreachable: outside the map"}))
        wrong = self.action.send_goal(GeneralGoal(sender="rostest", type="move", data=task("wrong", [(7.0, 5.0)])))
        wait_for(lambda: wrong.get_comm_state() == actionlib.CommState.DONE, 10.0, "wrong goal done")
        self.assertEqual(json.loads(wrong.get_result().data)["reason"], "goal type must be 'patrol', got 'move'")

        feedback = []
        handle = self.action.send_goal(GeneralGoal(sender="rostest", type="patrol", data=task("short", [(7.0, 5.0)])),
                                       feedback_cb=lambda _h, f: feedback.append((f.event_code, json.loads(f.data))))
        wait_for(lambda: handle.get_comm_state() == actionlib.CommState.DONE, 90.0, "short task done")
        self.assertEqual(handle.get_goal_status(), GoalStatus.ABORTED)
        result = handle.get_result()
        data = json.loads(result.data)
        self.assertEqual((result.ret_code, data["task_id"], data["state"], data["reason"]),
                         ("1", "short", "failed", "every preset failed"))
        self.assertEqual(data["counts"], {"readings": 1, "read": 0, "uncertain": 0, "needs_review": 0, "failed": 1,
                                          "alarms": 0, "checks": 0, "warnings": 0, "trends": 0})
        self.assertEqual(data["report"], "tasks/reports/short/report.html")   # data-root-relative
        ended = json.loads(self.status.wait(lambda m: json.loads(m.data)["task_id"] == "short"
                                            and json.loads(m.data)["state"] == "failed", 10.0, "short ended").data)
        self.assertEqual((ended["stop"], ended["stops"], ended["done"], ended["total"], ended["report"]),
                         (1, 1, 1, 1, "tasks/reports/short/report.html"))   # the final progress stays
        self.assertTrue(os.path.isfile(os.path.join(rospy.get_param("/data_root"), data["report"])), data["report"])
        running = [d for code, d in feedback if code == "0"]
        self.assertTrue(running, feedback)
        self.assertEqual([(d["task_id"], d["state"], d["stop"], d["stops"], d["preset"], d["presets"], d["total"])
                          for d in running[:1]], [("short", "running", 1, 1, 1, 1, 1)])
        self.assertGreater(running[0]["eta_s"], 0.0)

    # --- 3 --------------------------------------------------------------------------------------
    def test_3_over_the_websocket_preempted_by_a_special_task_then_cancelled(self):
        self.wait_idle()
        client = roslibpy.actionlib.ActionClient(self.ros, "/task_action", "inspection_robot/GeneralAction")
        self.addCleanup(client.dispose)
        feedback = []
        goal = roslibpy.actionlib.Goal(client, roslibpy.Message({"sender": "backend", "type": "patrol",
                                                                 "data": task("routine_ws", FAR_STOPS)}))
        goal.on("feedback", lambda f: feedback.append((f["event_code"], json.loads(f["data"]))))
        goal.send()
        # only cleanup: a failure below must not leave the routine running into the next test
        self.addCleanup(lambda: goal.is_finished or goal.cancel())
        wait_for(lambda: any(d["state"] == "running" for _c, d in feedback), 30.0, "routine running")

        special_feedback = []
        special = self.action.send_goal(
            GeneralGoal(sender="rostest", type="patrol", data=task("special_ros", [(7.0, 5.0)], "special")),
            feedback_cb=lambda _h, f: special_feedback.append(json.loads(f.data)))
        wait_for(lambda: any(c == "2" for c, _d in feedback), 30.0, "routine feedback: suspended")
        suspended = [d for c, d in feedback if c == "2"][-1]
        self.assertEqual((suspended["task_id"], suspended["state"], suspended["reason"]),
                         ("routine_ws", "suspended", "pre-empted by special task 'special_ros'"))
        # task_status comes straight from task_manager, the feedback through the bridge: either may be first
        self.status.wait(lambda m: json.loads(m.data)["task_id"] == "special_ros", 10.0, "task_status special_ros")
        wait_for(lambda: special.get_comm_state() == actionlib.CommState.DONE, 90.0, "special task done")
        self.assertEqual(special.get_result().ret_code, "1")
        self.assertTrue(goal.is_active, goal.status)   # the routine goal stayed active all along

        def resumed():
            codes = [c for c, _d in feedback]
            last_suspended = len(codes) - 1 - codes[::-1].index("2")
            return any(d["state"] == "running" for _c, d in feedback[last_suspended:])
        wait_for(resumed, 30.0, "routine resumed")

        goal.cancel()
        result = goal.wait(30)
        data = json.loads(result["data"])
        self.assertEqual((result["ret_code"], data["task_id"], data["state"], data["reason"]),
                         ("2", "routine_ws", "cancelled", "cancelled by the action client"))
        wait_for(lambda: goal.status is not None and goal.status["status"] == GoalStatus.PREEMPTED, 10.0,
                 "goal preempted")
        self.status.wait(lambda m: json.loads(m.data)["state"] == "cancelled", 10.0, "task_status cancelled")

    # --- 4 --------------------------------------------------------------------------------------
    def test_4_return_home_then_idle(self):
        self.wait_idle()
        self.assertEqual(self.tasks.call("submit", task("far", FAR_STOPS)).ack, "success")
        self.status.wait(lambda m: json.loads(m.data)["task_id"] == "far" and json.loads(m.data)["state"] == "running",
                         30.0, "far task running")
        reply = self.tasks.call("return_home")
        self.assertEqual((reply.ack, json.loads(reply.data)["state"]), ("success", "returning_home"))
        ended = {"task_id": "far", "state": "cancelled", "reason": "return home"}
        self.assertEqual(json.loads(reply.data)["last_ended"], ended)
        home = self.status.wait(lambda m: json.loads(m.data)["state"] == "idle", 120.0, "idle at home")
        status = json.loads(home.data)
        self.assertEqual((status["task_id"], status["reason"], status["last_ended"]), ("", "", ended))
        home = self.true_pose.pose()
        rospy.loginfo("test_task_action: home %.4f m off in ground truth", pose_error(home, HOME + (home[2],))[0])
        self.assertLess(pose_error(home, HOME + (home[2],))[0], 0.5, home)   # ~home_pose

    # --- 5 --------------------------------------------------------------------------------------
    def test_5_shortest_order_planned_with_the_planners_lengths(self):
        """task_manager orders the stops by move_base's path lengths from the robot to home, and
        reports the planned length: the same answer as the pure planning on the same map."""
        self.wait_idle()
        stops = [(36.0, 14.5), (15.5, 10.0), (26.0, 21.4), (20.0, 15.0)]   # far, near, middle, near-middle
        pose = self.robot.wait(lambda m: len(m.position) == 2, 10.0, "robot pose").position
        reach = Reachability(MAP, rospy.get_param("/move_base/robot_radius"), HOME)
        expected = plan_route(Task("x", "routine", 0, [{"name": "s%d" % i, "x": x, "y": y}
                                                       for i, (x, y) in enumerate(stops)], ORDER_SHORTEST),
                              tuple(pose), HOME, reach.path_length)
        self.assertEqual(self.tasks.call("submit", task("shortest", stops, order=ORDER_SHORTEST)).ack, "success")
        status = json.loads(self.status.wait(lambda m: json.loads(m.data)["task_id"] == "shortest", 30.0,
                                             "shortest task status").data)
        self.assertEqual(status["stop_name"], expected.stops[0]["name"])
        self.assertAlmostEqual(status["planned_length_m"], expected.planned_length_m, delta=1.0)
        given = sum(reach.path_length(a, b) for a, b in zip([tuple(pose)] + stops, stops + [HOME]))
        self.assertLess(status["planned_length_m"], given - 10.0)   # the typed order is much longer
        self.assertEqual(self.tasks.call("cancel", "shortest").ack, "success")
        self.wait_idle()

    # --- 6 --------------------------------------------------------------------------------------
    def test_6_plan_then_a_routine_scheduled_for_the_next_minute_runs_by_itself(self):
        self.wait_idle()
        stops = [(36.0, 14.5), (15.5, 10.0)]
        planned = json.loads(task("x", stops, order=ORDER_SHORTEST))
        del planned["id"]
        plan = self.tasks.call("plan", json.dumps(planned))
        self.assertEqual(plan.ack, "success", plan.data)
        plan = json.loads(plan.data)
        self.assertEqual(([s["name"] for s in plan["stops"]], plan["order"]), (["s1", "s0"], "shortest"))
        self.assertEqual(plan["stops"][0]["presets"], ["presets/%s/20260101_000000" % PRESET])
        # path[0] is the localizer's pose when plan ran, robot_status's another sample of it: two noisy
        # poses of a robot that may still be braking after test 5's cancel
        pose = self.robot.last.position
        self.assertLess(math.hypot(plan["path"][0][0] - pose[0], plan["path"][0][1] - pose[1]),
                        0.05 + math.sqrt(2.0) * localizer_tolerance()[0])
        self.assertEqual(plan["path"][-1], list(HOME))
        self.assertIn([15.5, 10.0], plan["path"])
        self.assertGreater(plan["planned_length_m"], 2 * 31.0)   # home -> (36, 14.5) and back at least
        self.assertNotIn("x", [t["task_id"] for t in json.loads(self.tasks.call("query_tasks").data)])

        routine = json.loads(task("x", [(7.0, 5.0)]))
        del routine["id"]
        saved = self.tasks.call("routine_save", json.dumps({"name": "yard_rt", "task": routine}))
        self.assertEqual(saved.ack, "success", saved.data)
        bad = self.tasks.call("schedule_set", json.dumps({"name": "s", "routine": "nope", "time": "08:00",
                                                          "weekdays": ["mon"]}))
        self.assertEqual((bad.ack, bad.data), ("failed", "unknown routine 'nope'"))
        soon = time.localtime(time.time() + 60)
        reply = self.tasks.call("schedule_set", json.dumps({"name": "every_day", "routine": "yard_rt",
                                                            "time": time.strftime("%H:%M", soon),
                                                            "weekdays": ["mon", "tue", "wed", "thu", "fri", "sat",
                                                                         "sun"]}))
        self.assertEqual(reply.ack, "success", reply.data)
        next_run = json.loads(reply.data)["next_run"]
        self.assertLess(next_run - time.time(), 61.0)
        task_id = "yard_rt_" + time.strftime("%Y%m%d_%H%M", time.localtime(next_run))
        refused = self.tasks.call("routine_delete", "yard_rt")
        self.assertEqual((refused.ack, refused.data), ("failed", "routine 'yard_rt' is used by schedule(s) every_day"))
        upcoming = json.loads(self.tasks.call("query_status").data)["next_scheduled"]
        self.assertEqual(upcoming, {"at": next_run, "schedule": "every_day", "routine": "yard_rt"})

        self.status.wait(lambda m: json.loads(m.data)["task_id"] == task_id, next_run - time.time() + 30.0,
                         "the scheduled run submitted")
        listed = json.loads(self.tasks.call("schedule_list").data)
        self.assertEqual([(s["name"], s["last_run"]["task_id"], s["missed"]) for s in listed],
                         [("every_day", task_id, [])])
        self.assertGreater(listed[0]["next_run"], next_run + 86000)   # tomorrow
        self.assertEqual(self.tasks.call("schedule_delete", "every_day").ack, "success")
        self.assertEqual(self.tasks.call("routine_delete", "yard_rt").ack, "success")
        self.tasks.call("cancel", task_id)
        self.wait_idle()


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_task_action", TaskActionTest)
