"""recording/: the recorded topic set, the disk budget, the run summary and the replay comparison,
with real files and made-up runs (no ROS)."""
import math
import os
import re

import pytest

from inspection_robot.interface import INTERFACE_TOPICS, LIGHT_SOFT_ESTOP, MODE_SERVER, MODE_TASK, NAV_OBSTACLE_3D
from inspection_robot.recording.compare import compare_runs, rising_edges, status_difference
from inspection_robot.recording.recorder import (RecorderError, bags_to_delete, disk_verdict,
                                                 enforce_budget, list_bags, record_command)
from inspection_robot.recording.summary import OFFLINE_ALARM, RunAnalyzer, format_summary, mode_time, reading_text


def topics_of(argv):
    return argv[argv.index("__name:=run_record") + 1:]


@pytest.mark.parametrize("ns,prefix", [("/", "/"), ("/robot_7/", "/robot_7/")])
def test_record_command_names_every_interface_topic_in_the_namespace(ns, prefix):
    argv = record_command("/data/bags", "run", ns, 100, 500, executable="/usr/lib/rosbag/record")
    assert argv[0] == "/usr/lib/rosbag/record"
    assert argv[argv.index("--size") + 1] == "100" and "--split" in argv and "--repeat-latched" in argv
    assert argv[argv.index("--min-space") + 1] == "500M"
    assert argv[argv.index("-o") + 1] == "/data/bags/run"
    assert "--regex" not in argv   # by name: subscribed at start, nothing lost to the master polling
    topics = topics_of(argv)
    wanted = ["robot_status", "control_status", "nav_status", "robot_odom", "tf", "server_status", "plan",
              "map", "virtual_obstacle_map", "obstacle_status", "move_action/goal", "move_action/feedback",
              "find_scale_action/result", "task_action/goal", "task_action/feedback", "task_action/cancel",
              "control_cmd", "control_ack", "virtual_obstacle_cmd", "mode_cmd", "mode_ack", "preset_rotate",
              "move_cmd", "location_cmd", "task_status", "task_cmd", "task_ack", "read_scale_cmd", "read_scale_ack",
              "preset_scale_cmd", "preset_scale_ack", "virtual_obstacles", "virtual_obstacle_ack", "voice_cmd",
              "charge_status", "charge_cmd", "charge_ack", "diagnostics", "file_cmd", "calibration_ack"]
    for topic in wanted:
        assert prefix + topic in topics, topic
    assert len(set(topics)) == len(topics)
    assert all(t.startswith(prefix) for t in topics)
    for topic in ["camera/image_raw", "camera/camera_info", "obstacle_cloud", "sim/chassis_cmd", "sim/true_pose",
                  "rosout"]:
        assert prefix + topic not in topics, topic


def test_every_command_topic_of_the_interface_doc_is_recorded():
    """docs/interface.md's topic tables name the *_cmd/*_ack topics; each must be in INTERFACE_TOPICS."""
    doc = open(os.path.join(os.path.dirname(__file__), "..", "..", "docs", "interface.md")).read()
    named = set(re.findall(r"^\| ([a-z_]+_(?:cmd|ack))(?: / ([a-z_]+_(?:cmd|ack)))? \| topic", doc, re.M))
    documented = {n for pair in named for n in pair if n}
    assert len(documented) > 20
    assert documented - set(INTERFACE_TOPICS) == set()


def test_images_are_recorded_compressed_only_when_asked():
    plain = topics_of(record_command("/d", "run", "/", 100, 500))
    with_images = topics_of(record_command("/d", "run", "/", 100, 500, image_topics=["camera/image_raw"],
                                           extra_topics=["/sim/true_pose", "robot_status"]))
    assert "/camera/image_raw/compressed" not in plain
    assert with_images == plain + ["/sim/true_pose", "/camera/image_raw/compressed"]


@pytest.mark.parametrize("extra", [["camera/image_raw"], [""], ["a b"], ["/"]])
def test_a_topic_that_cannot_be_recorded_is_refused(extra):
    with pytest.raises(RecorderError, match="raw images|cannot be recorded"):
        record_command("/d", "run", "/", 100, 500, extra_topics=extra)


@pytest.mark.parametrize("kwargs,needle", [({"split_size_mb": 0}, "split_size_mb"),
                                           ({"min_free_mb": -1}, "min_free_mb"),
                                           ({"directory": ""}, "directory")])
def test_record_command_refuses_bad_settings(kwargs, needle):
    args = dict(directory="/d", prefix="run", namespace="/", split_size_mb=100, min_free_mb=500)
    args.update(kwargs)
    with pytest.raises(RecorderError, match=needle):
        record_command(**args)


def make_bag(folder, name, size, mtime):
    path = os.path.join(str(folder), name)
    with open(path, "wb") as f:
        f.write(b"\0" * size)
    os.utime(path, (mtime, mtime))
    return path


def test_budget_deletes_the_oldest_closed_bags_and_never_the_active_one(tmp_path):
    old = make_bag(tmp_path, "run_1_0.bag", 400, 1000)
    middle = make_bag(tmp_path, "run_1_1.bag", 400, 2000)
    newest = make_bag(tmp_path, "run_1_2.bag", 400, 3000)
    active = make_bag(tmp_path, "run_1_3.bag.active", 300, 4000)
    make_bag(tmp_path, "notes.txt", 5000, 500)           # not a bag: neither counted nor deleted
    assert [b[0] for b in list_bags(str(tmp_path))] == [old, middle, newest, active]
    deleted, errors = enforce_budget(str(tmp_path), 1000)
    assert deleted == [old, middle] and errors == []
    assert sorted(os.listdir(str(tmp_path))) == ["notes.txt", "run_1_2.bag", "run_1_3.bag.active"]
    assert enforce_budget(str(tmp_path), 1000) == ([], [])


def test_an_active_bag_over_budget_alone_stays():
    bags = [("/d/a.bag", 10, 1, False), ("/d/b.bag.active", 5000, 2, True)]
    assert bags_to_delete(bags, 1000) == ["/d/a.bag"]
    assert bags_to_delete(bags[1:], 1000) == []


def test_budget_reports_a_bag_it_cannot_delete(tmp_path):
    make_bag(tmp_path, "a.bag", 100, 1)

    def refuse(path):
        raise PermissionError(13, "Permission denied")
    deleted, errors = enforce_budget(str(tmp_path), 10, remove=refuse)
    assert deleted == [] and errors and "a.bag" in errors[0] and "Permission denied" in errors[0]


def test_a_missing_folder_holds_no_bags(tmp_path):
    assert list_bags(str(tmp_path / "nope")) == []


def test_disk_verdict():
    assert disk_verdict(600e6, 500e6) is None
    assert "disk full: 100 MB free, below the 500 MB minimum" == disk_verdict(100e6, 500e6)


def status(**changes):
    fields = dict(offline_warn=0, mode=MODE_TASK, velocity_x=0.0, velocity_yaw=0.0, position=[0.0, 0.0],
                  orientation=0.0, nav_status=0, sensor_status=0, wheel_status=1, light_status=0, stop_status=0,
                  circuit_status=0, other_status=[0], battery_voltage=250, battery_current=-10,
                  battery_quantity=80, battery_status=32, motor_status=[0] * 8, motor_info=[0] * 8,
                  temperature=[250] + [-1000] * 12)
    fields.update(changes)
    return fields


def made_up_run():
    """10 Hz: 3 s still, 5 s at 1 m/s along x, e-stop at 9 s, offline at 11 s, mode server 12-14 s."""
    run = []
    for i in range(160):
        t = 100.0 + i * 0.1
        rel = i * 0.1
        x = min(max(rel - 3.0, 0.0), 5.0)
        moving = 3.0 <= rel < 8.0
        run.append((t, status(velocity_x=1.0 if moving else 0.0, position=[x, 0.0],
                              light_status=LIGHT_SOFT_ESTOP if 9.0 <= rel < 10.0 else 0,
                              offline_warn=1 if rel >= 11.0 else 0,
                              nav_status=NAV_OBSTACLE_3D if 6.0 <= rel < 6.5 else 0,
                              mode=MODE_SERVER if 12.0 <= rel < 14.0 else MODE_TASK,
                              battery_quantity=80 - int(rel // 8))))
    return run


def test_run_summary_of_a_made_up_run():
    analyzer = RunAnalyzer()
    analyzer.add_goal(99.0, '{"goal_pose": {"position": {"x": 5, "y": 0}}}')   # before the first status
    assert "goal_pose" in analyzer.add_goal(99.5, '{"bad": 1}')
    for t, fields in made_up_run():
        analyzer.add_status(t, fields)
        if abs(t - 105.0) < 1e-6:
            analyzer.add_obstacle(t, True)
            analyzer.add_reading(t, "read_scale", [0.5, 1.25])
            analyzer.add_ack(t, "control_ack", "failed", "unknown command 'x'")
            analyzer.add_ack(t, "control_ack", "success", "")
            analyzer.add_action_result(t, "move_action", "3", '{"reason": "obstacle"}')
            analyzer.add_action_result(t, "move_action", "0", "{}")
    s = analyzer.finish()
    assert s.status_count == 160 and s.duration == pytest.approx(15.9)
    assert s.distance == pytest.approx(5.0, abs=1e-6) and s.max_speed == 1.0
    assert [(round(st.t, 1), st.x, round(st.duration, 1)) for st in s.stops] == [(0.0, 0.0, 3.0), (8.0, 5.0, 7.9)]
    assert [(round(a.t, 1), a.text) for a in s.alarms] == [(6.0, "3-D obstacle"), (9.0, "soft e-stop"),
                                                           (11.0, OFFLINE_ALARM)]
    assert [(g.t, g.x, g.y) for g in s.goals] == [(-1.0, 5.0, 0.0)]   # sent 1 s before the first status
    assert [reading_text(r) for r in s.readings] == ["backend: read_scale = 0.5, 1.25 (no limits)"]
    assert s.readings[0].x == pytest.approx(2.0)
    assert [f.text for f in s.faults] == ["control_ack failed: unknown command 'x'",
                                          "move_action ended with 3: obstacle"]
    assert len(s.obstacles) == 1
    spent = mode_time(s)
    assert spent["task"] == pytest.approx(13.9) and spent["server"] == pytest.approx(2.0)
    text = format_summary(s, "run_0.bag")
    for needle in ("run run_0.bag", "duration: 0:00:16 (15.9 s)", "distance: 5.0 m", "battery 80 % -> 79 %",
                   "stops: 2", "readings: 1 (0 alarm, 0 failed)", "alarms: 3", "faults: 2", "goals: 1", "server 2 s"):
        assert needle in text, needle


def task_status(task_id, state, result=None, reason=""):
    import json
    return json.dumps({"task_id": task_id, "state": state, "reason": reason, "last_result": result})


def test_task_readings_alarms_and_failures_from_task_status():
    oil = {"stop": 2, "preset": "/p/oil/1", "reason": "",
           "readings": [{"target": "t1/oil_temp", "value": 118.2, "unit": "C", "alarm": "alarm", "status": "read"}]}
    cab = {"stop": 3, "preset": "/p/cab/1", "reason": "find_scale ended with 1: meter not found",
           "readings": [{"target": "c1/ammeter", "value": None, "unit": "A", "alarm": "failed", "status": "failed"},
                        {"target": "c1/lamp", "value": None, "unit": "", "alarm": "failed", "status": "failed"}]}
    analyzer = RunAnalyzer()
    assert analyzer.add_task_status(99.0, task_status("p1", "running")) is None   # before the first status
    for t, fields in made_up_run():
        analyzer.add_status(t, fields)
        # task_status comes every second and again at the start of each split: one result counts once
        if abs(t - 103.0) < 1e-6 or abs(t - 104.0) < 1e-6:
            analyzer.add_task_status(t, task_status("p1", "running", oil))
        if abs(t - 106.0) < 1e-6 or abs(t - 107.0) < 1e-6:
            analyzer.add_task_status(t, task_status("p1", "failed", cab, reason="every preset failed"))
    assert "task_status" in analyzer.add_task_status(110.0, "{not json")
    assert "task_status" in analyzer.add_task_status(110.0, task_status("p1", "failed", dict(
        oil, readings=[dict(oil["readings"][0], value="hot")])))
    s = analyzer.finish()
    assert [(round(r.t), r.task, r.stop, r.target, r.value, r.unit, r.alarm, r.status) for r in s.readings] == [
        (3, "p1", 2, "t1/oil_temp", 118.2, "C", "alarm", "read"),
        (6, "p1", 3, "c1/ammeter", None, "A", "failed", "failed"),
        (6, "p1", 3, "c1/lamp", None, "", "failed", "failed")]
    assert reading_text(s.readings[0]) == "p1 stop 2: t1/oil_temp = 118.2 C (alarm)"
    assert reading_text(s.readings[1]) == "p1 stop 3: c1/ammeter = failed (find_scale ended with 1: meter not found)"
    assert "reading alarm: t1/oil_temp 118.2 C" in [a.text for a in s.alarms]
    assert [f.text for f in s.faults] == ["reading failed: c1/ammeter: find_scale ended with 1: meter not found",
                                          "reading failed: c1/lamp: find_scale ended with 1: meter not found",
                                          "task p1 failed: every preset failed"]
    assert dict(s.tasks) == {"p1": ("failed", "every preset failed")}
    text = format_summary(s)
    for needle in ("readings: 3 (1 alarm, 2 failed)", "tasks: 1", "p1 failed: every preset failed", "alarms: 4"):
        assert needle in text, needle


def test_relocalisation_jumps_and_jitter_are_not_distance():
    analyzer = RunAnalyzer(max_jump_m=5.0)
    for i, x in enumerate([0.0, 0.0005, 0.001, 1.0, 50.0, 51.0]):
        analyzer.add_status(float(i), status(position=[x, 0.0]))
    assert analyzer.finish().distance == pytest.approx(0.001 + 0.999 + 1.0)


def test_offline_from_the_start_is_an_alarm():
    analyzer = RunAnalyzer()
    analyzer.add_status(1.0, status(offline_warn=1))
    analyzer.add_status(1.1, status(offline_warn=1))
    assert [a.text for a in analyzer.finish().alarms] == [OFFLINE_ALARM]


def test_identical_runs_match_and_a_late_transition_within_tolerance_matches():
    live = made_up_run()
    checked, mismatches = compare_runs(live, live)
    assert checked > 100 and mismatches == []
    # The replay publishes 20 ms later and its e-stop edge falls between two live statuses.
    replay = [(t + 0.02, dict(f, position=[f["position"][0] + 0.01, 0.0])) for t, f in live]
    assert compare_runs(live, replay)[1] == []


def test_a_wrong_bit_or_position_is_a_mismatch():
    live = made_up_run()
    replay = [(t, dict(f, stop_status=1) if abs(t - 107.0) < 0.05 else f) for t, f in live]
    checked, mismatches = compare_runs(live, replay)
    assert len(mismatches) == 1 and "stop_status: live 0, replay 1" in mismatches[0][1]
    far = [(t, dict(f, position=[f["position"][0] + 0.5, 0.0])) for t, f in live]
    assert len(compare_runs(live, far)[1]) == compare_runs(live, far)[0]
    assert status_difference(status(), status(orientation=math.pi)).startswith("orientation")
    assert status_difference(status(orientation=math.pi), status(orientation=-math.pi)) is None
    assert status_difference(status(), status(velocity_x=0.2)).startswith("velocity_x")
    assert compare_runs([], live)[1][0][1].startswith("empty stream")


def test_rising_edges():
    assert [round(t - 100.0, 1) for t in rising_edges(made_up_run(), "offline_warn")] == [11.0]
    assert [round(t - 100.0, 1) for t in rising_edges(made_up_run(), "light_status")] == [9.0]


def test_a_mix_of_two_neighbouring_live_statuses_matches_field_by_field():
    before = status(velocity_x=0.0, light_status=LIGHT_SOFT_ESTOP)
    after = status(velocity_x=0.8, light_status=0)
    live = [(10.0 + i * 0.1, before) for i in range(20)] + [(12.0 + i * 0.1, after) for i in range(20)]
    mixed = status(velocity_x=0.8, light_status=LIGHT_SOFT_ESTOP)   # new odometry, old control_status
    replay = [(t, f) for t, f in live if t < 11.95] + [(11.99, mixed)] + [(t, f) for t, f in live if t >= 11.95]
    assert compare_runs(live, replay, time_tol=0.15)[1] == []
    far = [(t, f) for t, f in live if t < 11.5] + [(11.5, mixed)] + [(t, f) for t, f in live if t > 11.5]
    assert compare_runs(live, far, time_tol=0.15)[1][0][1].startswith("velocity_x")


def test_positions_before_the_first_nav_status_are_not_a_pose():
    from inspection_robot.status.merge import STALE_NAV_STATUS
    analyzer = RunAnalyzer()
    for i in range(30):
        fields = status(position=[0.0, 0.0], other_status=[STALE_NAV_STATUS]) if i < 10 else status(position=[4.0, 5.0])
        analyzer.add_status(i * 0.1, fields)
    s = analyzer.finish()
    assert s.distance == 0.0 and math.isnan(s.x[0]) and s.x[-1] == 4.0
    assert [(st.x, st.y) for st in s.stops] == [(4.0, 5.0)]


def test_record_is_off_in_simulation_and_on_on_the_robot():
    import xml.etree.ElementTree as ElementTree
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

    def record_default(name):
        tree = ElementTree.parse(os.path.join(root, "launch", name))
        return [a.get("default") for a in tree.getroot().iter("arg") if a.get("name") == "record"]
    assert record_default("sim.launch") == ["false"]
    assert record_default("robot.launch") == ["true"]
    core = ElementTree.parse(os.path.join(root, "launch", "core.launch")).getroot()
    assert any(i.get("file", "").endswith("/launch/include/record.launch") for i in core.iter("include"))


def test_transitions_of_offline_warn_and_mode_compare_field_by_field():
    from inspection_robot.recording.compare import transition_differences, transitions
    live = [(t, {"offline_warn": ow, "mode": m}) for t, ow, m in (
        (0.0, 1, 0), (1.0, 1, 0), (3.0, 0, 0), (3.5, 0, 1), (5.0, 0, 0), (9.0, 1, 0), (12.0, 0, 0))]
    fields = ("offline_warn", "mode")
    assert transitions(live, fields, start=1.5, end=10.0) == [
        (1.5, (1, 0)), (3.0, (0, 0)), (3.5, (0, 1)), (5.0, (0, 0)), (9.0, (1, 0))]
    # the replay: backend mode while offline, a state the live robot never had
    wrong = [(t, {"offline_warn": ow, "mode": m}) for t, ow, m in (
        (1.5, 1, 0), (3.5, 1, 1), (3.9, 0, 1), (5.0, 0, 0), (9.0, 1, 0))]
    problems = transition_differences(transitions(live, fields, 1.5, 10.0), transitions(wrong, fields))
    assert problems and "states differ" in problems[0]
    late = [(t, {"offline_warn": ow, "mode": m}) for t, ow, m in (
        (1.5, 1, 0), (3.1, 0, 0), (3.6, 0, 1), (5.9, 0, 0), (9.0, 1, 0))]
    assert transition_differences(transitions(live, fields, 1.5, 10.0), transitions(late, fields), 0.5) == [
        "(0, 0): live at 5.000 s, replay at 5.900 s"]
    assert transition_differences(transitions(live, fields, 1.5, 10.0), transitions(late, fields), 1.0) == []
