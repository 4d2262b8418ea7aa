"""task_manager's hands: runs one patrol step (task.patrol.Step) on the robot.

move / home: move_action goal; inspect: find_scale_action (find_scale, or find_both when foreign
objects are asked) then read_scale_cmd (with find's second picture as the second look: every pointer
read twice, inspection.looks) and its read_scale_ack (matched by trans_id): ``success`` and
``uncertain: box <i>: <why>`` are readings (the Inspection carries each box's doubt), anything else
fails the step with read_scale's reason. Each wait polls ``interrupted()`` every 0.1 s and cancels
the running goal when it says so. A drive hands the share of its path already driven (move_action
feedback, task.drive_progress) to ``progress``. Returns (outcome, detail, timings) where timings =
{"find": s, "read": s} for inspections.
"""
import itertools
import threading
import time

import actionlib
import rospy
from actionlib.action_client import CommState

from inspection_robot.inspection.reading import request_filenames, uncertain_reasons
from inspection_robot.inspection.find_goal import find_goal_data, parse_find_result, reason_of
from inspection_robot.interface import (ACK_FAILED, ACK_SUCCESS, FIND_GOAL_BOTH, FIND_GOAL_SCALE, FIND_RESULT_SUCCESS,
                                        MOVE_GOAL_TYPE, MOVE_RESULT_SUCCESS)
from inspection_robot.nav.goal import move_goal_data
from inspection_robot.ros.actions import server_unavailable
from inspection_robot.msg import GeneralAction, GeneralGoal, ReadScaleAck, ReadScaleCmd
from inspection_robot.task.drive_progress import DriveProgress
from inspection_robot.task.patrol import (OUTCOME_FAILED, OUTCOME_INTERRUPTED, OUTCOME_OK, STEP_INSPECT,
                                          Inspection, turns_to_yaw)

POLL_S = 0.1
FOREIGN_DETECT_BOTH = 2


def _sources(targets, cmd):
    """Per target the picture read_scale read and its box: {"picture", "roi": 8 numbers}."""
    thermal = iter(range(0, len(cmd.roi_vertex_thermal), 8))
    sources = []
    for k, target in enumerate(targets):
        if target["kind"] == "thermal":
            start = next(thermal, None)
            roi = list(cmd.roi_vertex_thermal[start:start + 8]) if start is not None else []
            sources.append({"picture": cmd.filename[-1], "roi": roi})
        else:
            sources.append({"picture": cmd.filename[0], "roi": list(cmd.roi_vertex[8 * k:8 * k + 8])})
    return sources


def wait_for_server(client, name, interrupted, timeout):
    """None once ``client``'s server is up; (outcome, reason) when task_manager interrupts the step,
    rospy shuts down, or ``timeout`` s pass first. A server that is not up yet (move_base loading its
    map after a start-up, a node respawning) is waited for rather than failing the stop."""
    deadline = time.monotonic() + timeout
    while not client.wait_for_server(rospy.Duration(POLL_S)):
        if rospy.is_shutdown():
            return OUTCOME_INTERRUPTED, "shutdown"
        if interrupted():
            return OUTCOME_INTERRUPTED, "cancelled by task_manager"
        if time.monotonic() > deadline:
            return OUTCOME_FAILED, server_unavailable(name, client, timeout)
    return None


class StepRunner(object):
    def __init__(self, node_name, velocity_x, velocity_yaw, timeouts, pose, turn_at_stops=True):
        """``timeouts``: {"move", "find", "read", "server"} s; ``pose()``: latest (x, y, yaw) or None;
        ``turn_at_stops``: drives to stops end turned to the stop's yaw (task.patrol.turns_to_yaw)."""
        self._node_name = node_name
        self._turn_at_stops = turn_at_stops
        self._velocity = (velocity_x, velocity_yaw)
        self._timeouts = timeouts
        self._pose = pose
        # ActionClient, not SimpleActionClient: the simple client drops the result of a goal that ends
        # before send_goal has returned ("transition callback on a goal handle that we're not
        # tracking", e.g. a goal refused at once) and then waits forever
        self.move = actionlib.ActionClient("move_action", GeneralAction)
        self.find = actionlib.ActionClient("find_scale_action", GeneralAction)
        self._read_pub = rospy.Publisher("read_scale_cmd", ReadScaleCmd, queue_size=10)
        self._acks = {}
        self._acks_changed = threading.Condition()
        self._read_sub = rospy.Subscriber("read_scale_ack", ReadScaleAck, self._on_read_ack, queue_size=50)
        # a respawned task_manager must not take an old ack for its own request
        self._trans_ids = itertools.count(int(time.time() * 10) % 1000000000)

    def run(self, step, interrupted, progress=lambda fraction: None):
        """``progress(fraction)``: called from actionlib's thread as a drive advances (0..1)."""
        if step.kind == STEP_INSPECT:
            return self._inspect(step, interrupted)
        return self._move(step, interrupted, progress) + ({},)

    # --- move ----------------------------------------------------------------------------------
    def _move(self, step, interrupted, progress):
        data = move_goal_data(step.x, step.y, step.yaw, precision=step.precision, velocity_x=self._velocity[0],
                              velocity_yaw=self._velocity[1],
                              with_direction=turns_to_yaw(step, self._turn_at_stops))
        drive = DriveProgress()

        def on_feedback(_handle, feedback):
            fraction = drive.feed(feedback.event_code, feedback.data)
            if fraction is not None:
                progress(fraction)
        result = self._goal(self.move, "move_action", MOVE_GOAL_TYPE, data, self._timeouts["move"], interrupted,
                            on_feedback)
        if isinstance(result, tuple):
            return result
        if result.ret_code == MOVE_RESULT_SUCCESS:
            return OUTCOME_OK, ""
        return OUTCOME_FAILED, "move_action %s: %s" % (result.ret_code, reason_of(result.data))

    # --- inspect -------------------------------------------------------------------------------
    def _inspect(self, step, interrupted):
        preset = step.preset
        started = time.monotonic()
        goal_type = FIND_GOAL_BOTH if preset["foreign"] else FIND_GOAL_SCALE
        result = self._goal(self.find, "find_scale_action", goal_type, find_goal_data(preset["directory"]),
                            self._timeouts["find"], interrupted)
        timings = {"find": time.monotonic() - started}
        if isinstance(result, tuple):
            return result + (timings,)
        if result.ret_code != FIND_RESULT_SUCCESS:
            return OUTCOME_FAILED, "find_scale: %s" % reason_of(result.data), timings
        try:
            found = parse_find_result(result.data)
            files = request_filenames([t["kind"] for t in preset["targets"]], found["filename"],
                                      found["infrared_filename"], found["second_filename"])
            cmd = ReadScaleCmd(sender=self._node_name, trans_id=next(self._trans_ids), directory=preset["directory"],
                               foreign_detect=FOREIGN_DETECT_BOTH if preset["foreign"] else 0, filename=files,
                               foreign_filename=[found["foreign_filename"]] if preset["foreign"] else [],
                               roi_vertex=found["roi_vertex"], roi_vertex_thermal=found["infrared_roi_vertex"])
        except (ValueError, KeyError, TypeError) as err:
            return OUTCOME_FAILED, "find_scale answered unexpected data: %s" % err, timings
        started = time.monotonic()
        ack = self._read(cmd, interrupted)
        timings["read"] = time.monotonic() - started
        if isinstance(ack, tuple):
            return ack + (timings,)
        if len(ack.scale) != len(preset["targets"]) and ack.result != ACK_FAILED:
            return OUTCOME_FAILED, "read_scale answered %d values for %d targets" % (
                len(ack.scale), len(preset["targets"])), timings
        try:
            reasons = uncertain_reasons(ack.result, len(preset["targets"]), ACK_SUCCESS)
        except ValueError:   # failed: read_scale puts its reason in foreign_result
            return OUTCOME_FAILED, "read_scale %s: %s" % (ack.result, ack.foreign_result or "no reason given"), \
                timings
        foreign = None
        if preset["foreign"] and ack.foreign_scale:
            foreign = (ack.foreign_scale[0], ack.foreign_possibility[0] if ack.foreign_possibility else 0.0,
                       ack.foreign_picture_path[0] if ack.foreign_picture_path else "")
        return OUTCOME_OK, Inspection(list(ack.scale), list(ack.possibility), list(ack.picture_path), self._pose(),
                                      foreign, reasons, _sources(preset["targets"], cmd)), timings

    def _on_read_ack(self, msg):
        with self._acks_changed:
            self._acks[msg.trans_id] = msg
            if len(self._acks) > 100:
                self._acks.pop(min(self._acks))
            self._acks_changed.notify_all()

    def _read(self, cmd, interrupted):
        connect_deadline = time.monotonic() + 5.0
        while self._read_pub.get_num_connections() == 0:
            if time.monotonic() > connect_deadline or rospy.is_shutdown():
                return OUTCOME_FAILED, "read_scale: no subscriber on read_scale_cmd"
            rospy.sleep(POLL_S)
        self._read_pub.publish(cmd)
        deadline = time.monotonic() + self._timeouts["read"]
        with self._acks_changed:
            while cmd.trans_id not in self._acks:
                if rospy.is_shutdown():
                    return OUTCOME_INTERRUPTED, "shutdown"
                if time.monotonic() > deadline:
                    return OUTCOME_FAILED, "read_scale: no ack within %.0f s" % self._timeouts["read"]
                self._acks_changed.wait(POLL_S)
            return self._acks.pop(cmd.trans_id)

    # --- shared goal wait ------------------------------------------------------------------------
    def _goal(self, client, name, goal_type, data, timeout, interrupted, feedback=None):
        """The action's result, or (outcome, reason) when it did not finish normally."""
        not_up = wait_for_server(client, name, interrupted, self._timeouts["server"])
        if not_up is not None:
            return not_up
        handle = client.send_goal(GeneralGoal(type=goal_type, data=data), feedback_cb=feedback)
        deadline = time.monotonic() + timeout
        cancelled = None
        while handle.get_comm_state() != CommState.DONE:
            if rospy.is_shutdown():
                return OUTCOME_INTERRUPTED, "shutdown"
            if cancelled is None and interrupted():
                handle.cancel()
                cancelled = (OUTCOME_INTERRUPTED, "cancelled by task_manager", time.monotonic() + 5.0)
            elif cancelled is None and time.monotonic() > deadline:
                handle.cancel()
                cancelled = (OUTCOME_FAILED, "%s: no result within %.0f s" % (name, timeout), time.monotonic() + 5.0)
            if cancelled is not None and time.monotonic() > cancelled[2]:
                break   # the server did not confirm the cancel: give the goal up anyway
            rospy.sleep(POLL_S)
        if cancelled is not None:
            return cancelled[:2]
        result = handle.get_result()
        if result is None:
            return OUTCOME_FAILED, "%s ended (goal status %d) without a result" % (name, handle.get_goal_status())
        return result
