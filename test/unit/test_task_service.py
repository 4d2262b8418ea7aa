"""task_manager's task life without a roscore (task/service.py): commands through its table, the
patrol loop one step at a time with a scripted step runner, pre-emption, the schedule tick, a
finished task's report and goal, task_status; real store, preset, map and planner, fake clocks."""
import datetime
import json
import os

import pytest

from inspection_robot_testing.fixtures import make_lamp_preset
from inspection_robot.task.action import END_CANCELED, END_SUCCEEDED
from inspection_robot.task.checks import Reachability
from inspection_robot.task.patrol import OUTCOME_FAILED, OUTCOME_OK, STEP_INSPECT, STEP_MOVE, Inspection
from inspection_robot.task.rows import reading_rows
from inspection_robot.task.schedule import Scheduler
from inspection_robot.task.service import ServiceConfig, TaskService
from inspection_robot.task.store import ResultStore, StoreError
from inspection_robot_testing.clock import FakeClock
from test_task_patrol import CONFIG

UTC = datetime.timezone.utc
NOW = datetime.datetime(2026, 11, 27, 12, 0, tzinfo=UTC).timestamp()   # a Friday
MAP = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "config", "maps", "substation.yaml")
HOME = CONFIG.home_pose   # (5, 5): the simulated yard's home pose
STOPS = [(20.0, 21.4), (10.0, 5.0)]
PRESET = "lamp"


def task(task_id, stops=STOPS, priority="routine"):
    return json.dumps({"id": task_id, "priority": priority, "retries": 0,
                       "stops": [{"name": "s%d" % i, "pose": {"x": x, "y": y, "yaw": 0.0}, "presets": [PRESET]}
                                 for i, (x, y) in enumerate(stops)]})


class ScriptedRunner(object):
    """The step runner: every step succeeds (an inspection reads 1.0 in 1 s find + 2 s read) unless
    ``outcomes`` scripts another; ``during(step)`` runs inside a step (commands arriving meanwhile)."""

    def __init__(self, current_pose):
        self.current_pose = current_pose
        self.steps = []
        self.outcomes = []
        self.during = None

    def run(self, step, interrupted, progress):
        self.steps.append((step.task_id, step.kind, step.stop))
        if self.during is not None:
            self.during(step)
        if self.outcomes:
            return self.outcomes.pop(0)
        if step.kind == STEP_INSPECT:
            n = len(step.preset["targets"])
            return OUTCOME_OK, Inspection([1.0] * n, [90.0] * n, ["/p.jpg"] * n, self.current_pose()), \
                {"find": 1.0, "read": 2.0}
        return OUTCOME_OK, "", {}


class Goal(object):
    """A task_action goal as the node hands it in (task/ros_goal.py), recording what it was told."""

    class Request(object):
        def __init__(self, goal_type, data, sender="backend"):
            self.type, self.data, self.sender = goal_type, data, sender

    def __init__(self, goal_id, data, goal_type="patrol"):
        self.id = goal_id
        self.request = Goal.Request(goal_type, data)
        self.accepted = False
        self.feedbacks = []
        self.ended = None
        self.refused = None

    def accept(self):
        self.accepted = True

    def feedback(self, event_code, data):
        self.feedbacks.append((event_code, json.loads(data)))

    def end(self, end, ret_code, data, text):
        self.ended = (end, ret_code, json.loads(data), text)

    def refuse(self, ret_code, data, text):
        self.refused = (ret_code, json.loads(data), text)


class Rig(object):
    def __init__(self, tmp_path):
        self.root = str(tmp_path / "data")
        make_lamp_preset(self.root, PRESET)
        os.makedirs(os.path.join(self.root, "tasks"))
        self.store = ResultStore(os.path.join(self.root, "tasks", "results.sqlite"))
        self.clock, self.monotonic = FakeClock(1000.0), FakeClock(1000.0)
        self.clock.now = NOW
        self.published, self.logs = [], []
        self.service = TaskService(
            ServiceConfig(CONFIG, self.root, os.path.join(self.root, "presets"), 1, 1.0), self.store,
            Scheduler(self.store, 600.0, NOW, UTC), Reachability(MAP, 0.45, HOME[:2]), self.make_runner,
            self.published.append, lambda level, text: self.logs.append((level, text)), self.clock, self.monotonic)
        self.service.on_robot_status(HOME, 0)   # task mode: nothing holds the patrol

    def make_runner(self, current_pose):
        self.runner = ScriptedRunner(current_pose)
        return self.runner

    def call(self, cmd, data=""):
        reply = self.service.table.dispatch(cmd, data)
        return reply.ack, (json.loads(reply.data) if reply.ack == "success" else reply.data)

    def status(self):
        return self.call("query_status")[1]

    def run_steps(self, count=None):
        """Run the loop one step at a time, ``count`` steps or until no task is left."""
        done = 0
        while self.service.patrol.active is not None and (count is None or done < count):
            self.clock.now += 5.0
            self.service.once()
            done += 1


@pytest.fixture
def rig(tmp_path):
    return Rig(tmp_path)


def test_a_task_runs_stop_by_stop_and_its_report_is_written_when_it_ends(rig):
    ack, status = rig.call("submit", task("t1"))
    assert ack == "success" and (status["task_id"], status["state"], status["stops"]) == ("t1", "running", 2)
    rig.run_steps()
    assert rig.runner.steps == [("t1", STEP_MOVE, 0), ("t1", STEP_INSPECT, 0), ("t1", STEP_MOVE, 1),
                                ("t1", STEP_INSPECT, 1)]
    assert [(s["kind"], s["ended"] - s["started"]) for s in rig.store.steps("t1")
            if s["kind"] in ("find", "read")] == [("find", 1.0), ("read", 2.0)] * 2
    status = rig.status()
    assert (status["state"], status["done"], status["report"]) == ("done", 2, "tasks/reports/t1/report.html")
    report = os.path.join(rig.root, "tasks", "reports", "t1", "report.html")
    assert os.path.isfile(report) and ("info", "task t1 ended, report %s" % report) in rig.logs
    ack, files = rig.call("report", "t1")
    assert ack == "success" and files["report.html"] == "tasks/reports/t1/report.html"
    assert [r["value"] for r in rig.call("query_results", json.dumps({"task_id": "t1"}))[1]] == [1.0, 1.0]


def test_one_routine_at_a_time_and_a_special_task_preempts_it_after_the_preset(rig):
    assert rig.call("submit", task("routine"))[0] == "success"
    assert rig.call("submit", task("second")) == ("failed", "busy: task 'routine' is running (cancel it first)")
    assert rig.call("submit", task("routine")) == ("failed", "duplicate task id 'routine' (ids are never reused)")
    rig.run_steps(1)   # the drive to stop 1
    rig.runner.during = lambda step: rig.call("submit", task("urgent", [(10.0, 5.0)], "special"))
    rig.run_steps(1)   # stop 1's preset, during which the special task comes
    rig.runner.during = None
    tasks = dict((t["task_id"], t["state"]) for t in rig.call("query_tasks")[1])
    assert tasks == {"routine": "suspended", "urgent": "running"}
    assert (rig.status()["task_id"], rig.status()["suspended"]) == ("urgent", "routine")
    rig.run_steps()
    assert rig.runner.steps[2:] == [("urgent", STEP_MOVE, 0), ("urgent", STEP_INSPECT, 0),
                                    ("routine", STEP_MOVE, 1), ("routine", STEP_INSPECT, 1)]
    assert dict((t["task_id"], t["state"]) for t in rig.call("query_tasks")[1]) == {"routine": "done", "urgent": "done"}


def test_a_failing_or_raising_step_is_recorded_and_the_loop_goes_on(rig):
    rig.call("submit", task("t1"))
    rig.runner.outcomes = [(OUTCOME_FAILED, "move_action: blocked", {})]
    rig.run_steps(1)
    assert ("warn", "t1 move stop 1: failed: move_action: blocked") in rig.logs

    def broken(step):
        raise RuntimeError("bug")
    rig.runner.during = broken
    rig.run_steps(1)
    assert ("warn", "t1 move stop 2: failed: internal error: bug") in rig.logs
    assert any(level == "error" and text.startswith("move step raised bug\n") for level, text in rig.logs)
    assert rig.status()["state"] == "failed"   # no retries: both stops failed


def test_status_json_is_published_on_change_and_every_status_period(rig):
    status = rig.status()
    assert (status["state"], status["task_id"], status["holds"]) == ("idle", "", [])
    assert (status["store"], status["overhead_s"], status["missed_runs"], status["last_missed"],
            status["next_scheduled"]) == ("tasks/results.sqlite", 0.0, 0, None, None)
    assert len(rig.published) == 1 and json.loads(rig.published[-1]) == status   # task mode came: a change
    rig.service.publish_status()
    rig.service.status_tick()
    assert len(rig.published) == 1   # nothing changed within status_period
    rig.monotonic.now += 1.01          # status_period passed: the same text again
    rig.service.status_tick()
    rig.service.publish_status(force=True)
    assert len(rig.published) == 3
    rig.call("pause", "charge")
    assert json.loads(rig.published[-1])["holds"] == ["charge"] and len(rig.published) == 4


def test_a_due_schedule_starts_its_routine_and_a_busy_one_is_missed_after_its_grace(rig):
    routine = {"retries": 0, "stops": json.loads(task("", STOPS[:1]))["stops"]}   # a task without id
    ack, saved = rig.call("routine_save", json.dumps({"name": "r1", "task": routine}))
    assert ack == "success" and saved["name"] == "r1" and ("info", "routine 'r1' saved (1 stops)") in rig.logs
    ack, row = rig.call("schedule_set", json.dumps({"name": "s1", "routine": "r1", "time": "12:01",
                                                    "weekdays": ["fri"]}))
    assert ack == "success" and row["next_run"] == NOW + 60
    assert rig.status()["next_scheduled"] == {"at": NOW + 60, "schedule": "s1", "routine": "r1"}
    rig.clock.now = NOW + 65
    rig.service.schedule_tick(rig.clock())
    assert (rig.status()["task_id"], rig.status()["state"]) == ("r1_20261127_1201", "running")
    assert ("info", "schedule 's1' started task r1_20261127_1201") in rig.logs
    assert rig.call("schedule_list")[1][0]["last_run"] == {"at": NOW + 60, "task_id": "r1_20261127_1201",
                                                           "state": "running"}
    assert rig.call("routine_delete", "r1") == ("failed", "routine 'r1' is used by schedule(s) s1")
    week = NOW + 7 * 86400   # next Friday, the first run still going all through the grace
    rig.service.schedule_tick(week + 61)
    rig.service.schedule_tick(week + 661)
    reason = "task 'r1_20261127_1201' was running past the grace of 600 s"
    assert [m["reason"] for m in rig.call("schedule_list")[1][0]["missed"]] == [reason]
    assert (rig.status()["missed_runs"], rig.status()["last_missed"]["reason"]) == (1, reason)
    assert any(level == "warn" and text.startswith("schedule 's1' missed its run of ") and
               text.endswith("(task r1_20261204_1201): " + reason) for level, text in rig.logs)


def test_a_goal_is_accepted_with_its_task_gets_feedback_and_ends_with_it(rig):
    goal = Goal("g1", task("t1"))
    rig.service.action_request(("goal", goal))
    assert goal.accepted and goal.feedbacks[-1][1]["task_id"] == "t1"
    rig.run_steps()
    end, ret_code, data, text = goal.ended
    assert (end, ret_code, data["state"], data["report"], text) == (END_SUCCEEDED, "0", "done",
                                                                    "tasks/reports/t1/report.html", "done")
    cancelled = Goal("g2", task("t2"))
    rig.service.action_request(("goal", cancelled))
    rig.service.action_request(("cancel", Goal("g2", "")))
    assert cancelled.ended[0] == END_CANCELED and cancelled.ended[3] == "cancelled by the action client"


def test_bad_commands_and_goals_fail_with_their_reason(rig):
    assert rig.call("nope") == ("failed", "unknown command 'nope'")
    assert rig.call("query_status", "x") == ("failed", "this command takes no data, got 'x'")
    assert rig.call("report", "zz") == ("failed", "unknown task 'zz'")
    assert rig.call("cancel", "zz") == ("failed", "no running or suspended task 'zz'")
    assert rig.call("schedule_delete", "s9") == ("failed", "unknown schedule 's9'")
    ack, reason = rig.call("submit", task("t1", [(20.0, 10.0)]))
    assert ack == "failed" and "inside an obstacle or too close to one" in reason
    wrong = Goal("g1", task("t1"), goal_type="move")
    rig.service.action_request(("goal", wrong))
    assert wrong.refused == ("3", {"reason": "goal type must be 'patrol', got 'move'"},
                             "goal type must be 'patrol', got 'move'")
    assert ("warn", "task_action goal from backend refused: goal type must be 'patrol', got 'move'") in rig.logs
    crowded = Goal("g2", task("t1"))
    rig.service.action_refused(("goal", crowded))
    assert crowded.refused[2] == "busy: too many task_action requests waiting"


def test_a_virtual_map_of_another_size_is_refused_and_logged_once_per_period(rig):
    for _ in range(3):
        rig.service.on_virtual_map(3, 2, 0.05, [0] * 6)
    errors = [text for level, text in rig.logs if level == "error"]
    assert len(errors) == 1 and errors[0].startswith("virtual_obstacle_map is 3x2 at 0.050 m, the map ")
    rig.monotonic.now += 30.0
    rig.service.on_virtual_map(3, 2, 0.05, [0] * 6)
    assert len([level for level, _ in rig.logs if level == "error"]) == 2


def test_the_loop_outlives_a_store_failure(rig, monkeypatch):
    rounds, pauses = iter([True, True, False]), []

    def full_disk():
        raise StoreError("disk full")
    monkeypatch.setattr(rig.service, "once", full_disk)
    rig.service.spin(lambda: next(rounds), pauses.append)
    assert pauses == [1.0, 1.0] and [t for level, t in rig.logs if level == "error"] == ["disk full"]


def test_open_alarms_are_listed_acknowledged_and_counted_in_the_status(rig):
    preset = {"preset": "p", "directory": "/d/presets/p/1", "foreign": False, "alarms": {"oil": [0.0, 85.0]},
              "targets": [{"name": "oil", "kind": "pointer", "unit": "C", "decimals": 1}]}
    assert rig.status()["open_alarms"] == 0
    rig.store.add_readings(reading_rows("t0", 0, "s1", 0, preset, Inspection([118.0], [90.0], [""], HOME), "", NOW))
    assert rig.status()["open_alarms"] == 1
    ack, rows = rig.call("alarms")
    assert ack == "success" and [(r["target_name"], r["display"]) for r in rows] == [("oil", "118.0 C")]
    ack, row = rig.call("acknowledge", json.dumps({"id": rows[0]["id"], "by": "li"}))
    assert ack == "success" and (row["ack_by"], row["ack_time"]) == ("li", rig.clock.now)
    assert ("info", "alarm of reading %d (oil, alarm) acknowledged by li" % row["id"]) in rig.logs
    assert rig.status()["open_alarms"] == 0 and rig.call("alarms")[1] == []
    assert rig.call("alarms", '{"acknowledged": true}')[1][0]["ack_by"] == "li"
    assert rig.call("acknowledge", json.dumps({"id": row["id"], "by": "wang"})) == (
        "failed", "reading %d was already acknowledged by li" % row["id"])


def test_the_status_names_the_time_zone_schedules_run_in(rig):
    """A backend turns a schedule's HH:MM (robot local time) into a moment with it (issue #41)."""
    assert rig.status()["time_zone"] == {"name": "UTC", "utc_offset_s": 0}
