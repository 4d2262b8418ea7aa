"""The patrol state machine on a fake clock: order, retries, holds, pre-emption, cancel, return
home, restart recovery; with the real SQLite store in a temporary folder."""
import json
import os
import stat

import pytest

from inspection_robot.command import CommandError
from inspection_robot.task.patrol import (OUTCOME_FAILED, OUTCOME_INTERRUPTED, OUTCOME_OK, STEP_HOME, STEP_INSPECT,
                                          STEP_MOVE, Inspection, Patrol, PatrolConfig)
from inspection_robot.task.report import REPORT_FILES, write_reports
from inspection_robot.task.spec import ResolvedPreset, parse_task
from inspection_robot.task.store import ResultStore
from inspection_robot_testing.clock import FakeClock

CONFIG = PatrolConfig(retry_delay_s=5.0, home_pose=(5.0, 5.0, 0.0), move_estimate_s=20.0, preset_estimate_s=10.0,
                      uncertain_retries=1)
TARGETS = {"p_gauge": [{"name": "g", "kind": "pointer", "unit": "MPa"}],
           "p_lamp": [{"name": "lamp", "kind": "lamp", "unit": ""}, {"name": "sw", "kind": "switch", "unit": ""}]}


def resolve(name):
    base = name.split("/")[0]
    if base not in TARGETS:
        raise CommandError("unknown preset directory '%s'" % name)
    return ResolvedPreset("/presets/" + name, TARGETS[base], {})


def task(task_id, stops=2, priority="routine", retries=1):
    return parse_task(json.dumps({
        "id": task_id, "priority": priority, "retries": retries,
        "stops": [{"name": "s%d" % i, "pose": {"x": float(i), "y": 1.0, "yaw": 0.0},
                   "presets": [{"preset": "p_gauge", "alarms": {"g": [0.2, 0.8]}}, "p_lamp"]}
                  for i in range(stops)]}), resolve, lambda x, y: None, 1)


@pytest.fixture
def env(tmp_path):
    store = ResultStore(str(tmp_path / "results.sqlite"))
    clock = FakeClock(1000.0)
    finished = []
    patrol = Patrol(store, CONFIG, clock(), on_finished=finished.append)
    patrol.set_mode(0)
    return store, clock, patrol, finished


def reading_for(step, value=0.5):
    n = len(step.preset["targets"])
    pictures = ["/pic/%d_%d_%d.jpg" % (step.stop, step.preset_index, k) for k in range(n)]
    return Inspection([value] * n, [90.0] * n, pictures, (1.0, 2.0, 0.0))


def run_step(patrol, clock, outcome=OUTCOME_OK, value=0.5, seconds=3.0):
    step = patrol.next_step(clock())
    assert step is not None
    started = clock()
    clock.now += seconds
    detail = reading_for(step, value) if (outcome == OUTCOME_OK and step.kind == STEP_INSPECT) else (
        "" if outcome == OUTCOME_OK else "it broke")
    patrol.step_done(step, outcome, detail, started, clock())
    return step


def test_a_patrol_drives_then_inspects_each_preset_in_order(env):
    store, clock, patrol, finished = env
    patrol.submit(task("t1"), clock())
    kinds = [(s.kind, s.stop, s.preset_index) for s in (run_step(patrol, clock) for _ in range(6))]
    assert kinds == [(STEP_MOVE, 0, -1), (STEP_INSPECT, 0, 0), (STEP_INSPECT, 0, 1),
                     (STEP_MOVE, 1, -1), (STEP_INSPECT, 1, 0), (STEP_INSPECT, 1, 1)]
    assert patrol.next_step(clock()) is None
    assert finished == ["t1"]
    assert patrol.status()["state"] == "done"
    rows = store.readings(task_id="t1")
    assert len(rows) == 6 and all(r["status"] == "read" for r in rows)
    assert [r["alarm"] for r in rows if r["target_name"] == "g"] == ["normal", "normal"]
    assert store.task("t1")["state"] == "done"


def test_out_of_band_value_is_an_alarm(env):
    store, clock, patrol, _ = env
    patrol.submit(task("t1", stops=1), clock())
    run_step(patrol, clock)
    run_step(patrol, clock, value=0.95)
    assert patrol.status()["last_result"]["alarms"] == 1
    row = store.readings(task_id="t1")[0]
    assert (row["alarm"], row["low"], row["high"], row["value"]) == ("alarm", 0.2, 0.8, 0.95)


def test_failed_step_is_retried_after_the_delay_then_recorded_failed(env):
    store, clock, patrol, _ = env
    patrol.submit(task("t1", stops=1, retries=1), clock())
    run_step(patrol, clock)                              # drive
    run_step(patrol, clock, OUTCOME_FAILED)              # inspect fails once
    assert patrol.next_step(clock()) is None             # waiting retry_delay_s
    clock.now += 5.0
    step = run_step(patrol, clock, OUTCOME_FAILED)       # the retry fails: recorded as failed
    assert (step.kind, step.preset_index) == (STEP_INSPECT, 0)
    rows = store.readings(task_id="t1")
    assert [(r["status"], r["alarm"], r["reason"]) for r in rows] == [("failed", "failed", "it broke")]
    step = run_step(patrol, clock)                       # the patrol goes on with the next preset
    assert step.preset_index == 1


def test_unreachable_stop_fails_its_presets_and_the_patrol_goes_on(env):
    store, clock, patrol, _ = env
    patrol.submit(task("t1", stops=2, retries=0), clock())
    run_step(patrol, clock, OUTCOME_FAILED)
    step = patrol.next_step(clock())
    assert (step.kind, step.stop) == (STEP_MOVE, 1)
    rows = store.readings(task_id="t1")
    assert len(rows) == 3 and all(r["reason"] == "stop unreachable: it broke" for r in rows)


def test_every_preset_failing_fails_the_task(env):
    store, clock, patrol, _ = env
    patrol.submit(task("t1", stops=1, retries=0), clock())
    run_step(patrol, clock, OUTCOME_FAILED)
    assert patrol.status()["state"] == "failed"
    assert store.task("t1")["reason"] == "every preset failed"


def test_pause_finishes_the_preset_and_resume_drives_back_to_the_stop(env):
    store, clock, patrol, _ = env
    patrol.submit(task("t1"), clock())
    run_step(patrol, clock)
    step = patrol.next_step(clock())
    assert step.kind == STEP_INSPECT
    patrol.pause("")
    assert not patrol.interrupt_wanted(step)             # never mid-preset
    assert patrol.status()["state"] == "running"
    patrol.step_done(step, OUTCOME_OK, reading_for(step), clock(), clock())
    assert patrol.status()["state"] == "paused" and patrol.status()["holds"] == ["operator"]
    clock.now += 36000.0                                   # ten hours paused: nothing times out
    assert patrol.next_step(clock()) is None
    patrol.resume("")
    step = patrol.next_step(clock())
    assert (step.kind, step.stop) == (STEP_MOVE, 0)      # back to the stop, then the next preset
    patrol.step_done(step, OUTCOME_OK, "", clock(), clock())
    assert (patrol.next_step(clock()).preset_index) == 1


def test_a_hold_cancels_a_drive_which_is_driven_again_without_counting_a_retry(env):
    store, clock, patrol, _ = env
    patrol.submit(task("t1", retries=0), clock())
    step = patrol.next_step(clock())
    patrol.pause("charge")
    assert patrol.interrupt_wanted(step)
    patrol.step_done(step, OUTCOME_INTERRUPTED, "cancelled", clock(), clock())
    assert patrol.status()["state"] == "paused"
    patrol.resume("charge")
    assert patrol.next_step(clock()).kind == STEP_MOVE
    assert store.readings(task_id="t1") == []


def test_charge_and_operator_holds_are_released_only_by_their_own_reason(env):
    store, clock, patrol, _ = env
    patrol.submit(task("t1"), clock())
    patrol.pause("charge")
    patrol.pause("")
    patrol.resume("")
    assert patrol.status()["holds"] == ["charge"] and patrol.next_step(clock()) is None
    patrol.pause("")
    patrol.resume("charge")
    assert patrol.status()["holds"] == ["operator"] and patrol.next_step(clock()) is None
    patrol.resume("")
    assert patrol.next_step(clock()) is not None
    with pytest.raises(CommandError, match="operator.*charge"):
        patrol.pause("battery")


def test_charge_hold_without_a_task_is_kept_for_the_next_one(env):
    store, clock, patrol, _ = env
    patrol.pause("charge")
    with pytest.raises(CommandError, match="no task to pause"):
        patrol.pause("")
    patrol.submit(task("t1"), clock())
    assert patrol.next_step(clock()) is None and patrol.status()["state"] == "paused"
    patrol.resume("charge")
    assert patrol.next_step(clock()).kind == STEP_MOVE


def test_mode_change_pauses_and_task_mode_resumes_at_the_same_place(env):
    store, clock, patrol, _ = env
    patrol.submit(task("t1"), clock())
    run_step(patrol, clock)
    run_step(patrol, clock)
    step = patrol.next_step(clock())                     # inspecting preset 2 of stop 1
    patrol.set_mode(1)                                   # the backend takes over
    patrol.step_done(step, OUTCOME_OK, reading_for(step), clock(), clock())
    assert patrol.status()["state"] == "paused" and patrol.status()["holds"] == ["mode"]
    clock.now += 600.0
    patrol.set_mode(0)
    step = run_step(patrol, clock)
    assert (step.kind, step.stop) == (STEP_MOVE, 1)      # stop 1 is complete: on to stop 2
    step = run_step(patrol, clock)
    assert (step.kind, step.stop, step.preset_index) == (STEP_INSPECT, 1, 0)


def test_no_robot_status_yet_is_a_mode_hold(tmp_path):
    store = ResultStore(str(tmp_path / "r.sqlite"))
    patrol = Patrol(store, CONFIG, 0.0)
    patrol.submit(task("t1"), 0.0)
    assert patrol.next_step(0.0) is None and patrol.status()["holds"] == ["mode"]


def test_a_failed_drive_while_held_is_an_interruption_not_a_failure(env):
    store, clock, patrol, _ = env
    patrol.submit(task("t1", retries=0), clock())
    step = patrol.next_step(clock())
    patrol.set_mode(2)
    patrol.step_done(step, OUTCOME_FAILED, "robot_control in joy mode: goal given up", clock(), clock())
    patrol.set_mode(0)
    assert patrol.next_step(clock()).kind == STEP_MOVE
    assert store.readings(task_id="t1") == []


def test_special_task_preempts_after_the_preset_and_routine_resumes_at_its_stop(env):
    store, clock, patrol, finished = env
    patrol.submit(task("routine", stops=2), clock())
    for _ in range(4):
        run_step(patrol, clock)                          # stop 1 done, drove to stop 2
    step = patrol.next_step(clock())                     # inspecting stop 2 preset 1
    patrol.submit(task("urgent", stops=1, priority="special"), clock())
    assert not patrol.interrupt_wanted(step)
    patrol.step_done(step, OUTCOME_OK, reading_for(step), clock(), clock())
    assert patrol.status()["task_id"] == "urgent" and patrol.status()["suspended"] == "routine"
    assert store.task("routine")["state"] == "suspended"
    for _ in range(3):
        assert run_step(patrol, clock).task_id == "urgent"
    assert finished == ["urgent"]
    assert patrol.status()["last_ended"] == {"task_id": "urgent", "state": "done", "reason": ""}
    assert patrol.status()["task_id"] == "routine"
    step = run_step(patrol, clock)
    assert (step.task_id, step.kind, step.stop) == ("routine", STEP_MOVE, 1)
    step = run_step(patrol, clock)
    assert (step.kind, step.stop, step.preset_index) == (STEP_INSPECT, 1, 1)   # not from the beginning
    assert finished == ["urgent", "routine"]
    assert len(store.readings(task_id="routine")) == 6


def test_special_task_cancels_a_running_drive_of_the_routine(env):
    store, clock, patrol, _ = env
    patrol.submit(task("routine"), clock())
    step = patrol.next_step(clock())
    patrol.submit(task("urgent", stops=1, priority="special"), clock())
    assert patrol.interrupt_wanted(step)
    patrol.step_done(step, OUTCOME_INTERRUPTED, "cancelled", clock(), clock())
    assert patrol.next_step(clock()).task_id == "urgent"


def test_busy_refusals(env):
    store, clock, patrol, _ = env
    patrol.submit(task("r1"), clock())
    with pytest.raises(CommandError, match="busy: task 'r1' is running"):
        patrol.submit(task("r2"), clock())
    patrol.submit(task("s1", priority="special"), clock())
    with pytest.raises(CommandError, match="busy: task 's1' is running"):
        patrol.submit(task("s2", priority="special"), clock())
    with pytest.raises(CommandError, match="duplicate task id 'r1'"):
        patrol.submit(task("r1"), clock())


def test_cancel_ends_the_task_and_interrupts_its_step(env):
    store, clock, patrol, finished = env
    patrol.submit(task("t1"), clock())
    run_step(patrol, clock)
    step = patrol.next_step(clock())
    patrol.cancel("", clock())
    assert patrol.interrupt_wanted(step)
    patrol.step_done(step, OUTCOME_INTERRUPTED, "cancelled", clock(), clock())
    assert patrol.status()["state"] == "cancelled" and finished == ["t1"]
    assert store.task("t1")["state"] == "cancelled"
    with pytest.raises(CommandError, match="no task to cancel"):
        patrol.cancel("", clock())
    with pytest.raises(CommandError, match="no running or suspended task 'zz'"):
        patrol.cancel("zz", clock())


def test_return_home_cancels_tasks_and_drives_home(env):
    store, clock, patrol, finished = env
    patrol.submit(task("r"), clock())
    patrol.submit(task("s", priority="special"), clock())
    patrol.pause("")
    patrol.return_home(clock())
    assert sorted(finished) == ["r", "s"]
    assert patrol.status()["state"] == "returning_home"
    step = patrol.next_step(clock())
    assert (step.kind, step.x, step.y) == (STEP_HOME, 5.0, 5.0)
    assert patrol.status()["last_ended"]["state"] == "cancelled"
    patrol.step_done(step, OUTCOME_OK, "", clock(), clock())
    status = patrol.status()
    assert (status["state"], status["task_id"], status["reason"]) == ("idle", "", "")
    assert status["last_ended"] == {"task_id": "r", "state": "cancelled", "reason": "return home"}
    patrol.submit(task("n", stops=1), clock())   # the next task shows again, and so does its end
    patrol.cancel("n", clock())
    assert (patrol.status()["state"], patrol.status()["task_id"]) == ("cancelled", "n")


def test_a_task_ending_without_return_home_keeps_its_end_state(env):
    store, clock, patrol, finished = env
    patrol.submit(task("t", stops=1), clock())
    for _ in range(3):
        run_step(patrol, clock)
    status = patrol.status()
    assert (status["state"], status["task_id"]) == ("done", "t")


def test_failed_return_home_says_why_and_is_idle(env):
    store, clock, patrol, finished = env
    patrol.return_home(clock())
    run_step(patrol, clock, OUTCOME_FAILED)
    status = patrol.status()
    assert (status["state"], status["reason"]) == ("idle", "return home failed: it broke")


def test_restart_resumes_the_interrupted_task_without_repeating_a_reading(env, tmp_path):
    store, clock, patrol, _ = env
    patrol.submit(task("t1"), clock())
    patrol.pause("charge")
    patrol.resume("charge")
    run_step(patrol, clock)
    run_step(patrol, clock)
    patrol.next_step(clock())                            # killed while inspecting stop 1 preset 2
    store.close()
    store2 = ResultStore(store.path)
    again = Patrol(store2, CONFIG, clock())
    assert again.status()["holds"] == ["mode"]           # until robot_status is heard again
    again.set_mode(0)
    step = run_step(again, clock)
    assert (step.task_id, step.kind, step.stop) == ("t1", STEP_MOVE, 0)
    step = run_step(again, clock)
    assert (step.kind, step.stop, step.preset_index) == (STEP_INSPECT, 0, 1)
    for _ in range(3):
        run_step(again, clock)
    rows = store2.readings(task_id="t1")
    keys = [(r["stop"], r["preset_index"], r["target"]) for r in rows]
    assert len(keys) == len(set(keys)) == 6
    assert store2.task("t1")["state"] == "done"


def test_restart_keeps_a_suspended_routine_behind_the_special_task(env):
    store, clock, patrol, _ = env
    patrol.submit(task("routine"), clock())
    patrol.submit(task("urgent", stops=1, priority="special"), clock())
    patrol.pause("charge")
    again = Patrol(ResultStore(store.path), CONFIG, clock())
    again.set_mode(0)
    assert again.status()["holds"] == ["charge"]
    again.resume("charge")
    assert again.status()["task_id"] == "urgent" and again.status()["suspended"] == "routine"


def test_eta_and_progress(env):
    store, clock, patrol, _ = env
    patrol.submit(task("t1", stops=2), clock())
    status = patrol.status()
    assert (status["stop"], status["stops"], status["preset"], status["presets"]) == (1, 2, 1, 2)
    assert status["eta_s"] == 2 * 20.0 + 4 * 10.0
    run_step(patrol, clock, seconds=30.0)
    run_step(patrol, clock, seconds=6.0)
    status = patrol.status()
    assert (status["preset"], status["done"], status["total"]) == (2, 1, 4)
    assert status["eta_s"] == 30.0 + 3 * 6.0


def test_reports_have_every_reading_and_highlight_alarms(env, tmp_path):
    store, clock, patrol, _ = env
    patrol.submit(task("t1", stops=1), clock())
    run_step(patrol, clock)
    run_step(patrol, clock, value=0.99)
    run_step(patrol, clock)
    status = patrol.status()   # ended: the final progress stays (a full progress bar), no time left
    assert (status["state"], status["stop"], status["stops"], status["preset"], status["presets"], status["done"],
            status["total"], status["priority"], status["eta_s"]) == ("done", 1, 1, 2, 2, 2, 2, "routine", 0.0)
    # the fake pictures and presets lie under /: the data root "/" makes them data-root-relative
    folder = str(tmp_path / "rep")
    paths = write_reports(folder, store.task("t1"), store.readings(task_id="t1"), store.steps("t1"), "/",
                          "v1.2-3-gabcdef0")
    assert sorted(os.path.basename(p) for p in paths.values()) == sorted(REPORT_FILES)
    with open(paths["report.csv"]) as f:
        assert len(f.read().strip().splitlines()) == 1 + 3
    with open(paths["report.json"]) as f:
        data = json.load(f)
    assert data["summary"]["counts"] == {"readings": 3, "read": 3, "uncertain": 0, "needs_review": 0, "failed": 0,
                                         "alarms": 1, "checks": 0, "warnings": 0, "trends": 0}
    assert data["summary"]["software_version"] == "v1.2-3-gabcdef0"
    with open(paths["report.html"]) as f:
        page = f.read()
    assert "robot software v1.2-3-gabcdef0" in page
    assert page.index('<tr class="alarm">') < page.index('<tr class="none">')
    link = os.path.relpath("/pic/0_0_0.jpg", os.path.realpath(folder))   # relative to the report, no file://
    assert '<img src="%s"' % link in page and "file://" not in page
    assert [(r["preset"], r["picture"]) for r in data["readings"]][0] == ("presets/p_gauge", "pic/0_0_0.jpg")
    for name in REPORT_FILES:   # fetched by a backend: readable by others
        assert os.stat(paths[name]).st_mode & 0o777 == 0o644


def test_the_results_store_and_its_journal_files_are_the_robot_users_only(tmp_path):
    old_umask = os.umask(0o022)   # the usual umask: SQLite alone would create 644 files
    try:
        store = ResultStore(str(tmp_path / "results.sqlite"))
        store.save_routine("r", {"stops": []}, 0.0)  # a write: the -wal and -shm are there
        modes = {name: stat.S_IMODE(os.stat(str(tmp_path / name)).st_mode) for name in os.listdir(str(tmp_path))}
        assert modes == {"results.sqlite": 0o600, "results.sqlite-wal": 0o600, "results.sqlite-shm": 0o600}
        store.close()
        os.chmod(str(tmp_path / "results.sqlite"), 0o644)   # a store made before: put right when opened
        ResultStore(str(tmp_path / "results.sqlite")).close()
        assert stat.S_IMODE(os.stat(str(tmp_path / "results.sqlite")).st_mode) == 0o600
        (tmp_path / "plain.txt").write_text("x")               # positive control: the umask was 022
        assert stat.S_IMODE(os.stat(str(tmp_path / "plain.txt")).st_mode) == 0o644
    finally:
        os.umask(old_umask)
