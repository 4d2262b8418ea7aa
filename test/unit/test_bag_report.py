"""tools/bag_report on the committed fixture bag (test/fixtures/replay_run.bag, made by
scripts/make_bag_fixture.py) and on bad input: missing, truncated, foreign, wrong type. Needs the
rosbag Python API and the built messages (run through scripts/rosenv), no roscore."""
import os
import shutil
import subprocess
import sys

import pytest

rosbag = pytest.importorskip("rosbag")

import rospy  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from inspection_robot.msg import RobotStatus  # noqa: E402
from inspection_robot.tools import bag_report  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
FIXTURE = os.path.join(ROOT, "test", "fixtures", "replay_run.bag")
sys.path.insert(0, os.path.join(ROOT, "scripts"))
import make_bag_fixture  # noqa: E402


def report(capsys, *argv):
    code = bag_report.run(list(argv))
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    return code, out, err


def test_fixture_is_small_and_is_what_its_script_makes(tmp_path):
    assert os.path.getsize(FIXTURE) <= 1024 * 1024
    fresh = make_bag_fixture.write_fixture(str(tmp_path / "fresh.bag"))
    with rosbag.Bag(FIXTURE) as a, rosbag.Bag(fresh) as b:
        ours = [(topic, t.to_nsec(), raw[1]) for topic, raw, t in a.read_messages(raw=True)]
        theirs = [(topic, t.to_nsec(), raw[1]) for topic, raw, t in b.read_messages(raw=True)]
        assert ours == theirs


def test_report_of_the_fixture(tmp_path, capsys):
    png = str(tmp_path / "run.png")
    code, out, err = report(capsys, FIXTURE, "--out", png)
    assert code == 0, err
    for needle in ("duration: 0:00:40", "distance: 13.6 m", "max speed 0.80 m/s", "battery 80 % -> 79 %",
                   "modes: task 30 s, server 10 s", "goals: 1", "stops: 3", "readings: 5 (1 alarm, 1 failed)",
                   "backend: read_scale = 0.42 (no limits)",
                   "fixture_patrol stop 1: transformer_1/oil_temp = 118.2 C (alarm)",
                   "fixture_patrol stop 1: cabinet_1/ammeter = 231.5 A (normal)",
                   "fixture_patrol stop 1: cabinet_1/lamp_run = 2 (no limits)",
                   "fixture_patrol stop 1: bay_1/switch_2 = failed (find_scale ended with 1: meter not found)",
                   "tasks: 1\n  fixture_patrol done",
                   "alarms: 3", "reading alarm: transformer_1/oil_temp 118.2 C", "soft e-stop",
                   "backend link lost (offline_warn)", "faults: 2", "control_ack failed: unknown command 'foo'",
                   "reading failed: bay_1/switch_2: find_scale ended with 1: meter not found",
                   "3-D obstacles: 1", "picture: " + png):
        assert needle in out, needle
    with open(png, "rb") as f:
        assert f.read(8) == b"\x89PNG\r\n\x1a\n"
    assert os.path.getsize(png) > 20000


def test_summary_times_are_the_fixture_script(capsys):
    summary, grid, virtual, warnings = bag_report.read_run([FIXTURE])
    assert warnings == [] and grid.info.width == 200 and virtual is not None
    alarms = {a.text: a.t for a in summary.alarms}
    offline = alarms["backend link lost (offline_warn)"]
    since_start = summary.start - make_bag_fixture.FIXTURE_START   # the first robot_status's bag time
    assert abs(since_start + offline - make_bag_fixture.FIXTURE_OFFLINE_AT) < 0.15
    assert abs(since_start + alarms["soft e-stop"] - make_bag_fixture.FIXTURE_ESTOP[0]) < 0.15
    assert [(g.x, g.y) for g in summary.goals] == [make_bag_fixture.FIXTURE_GOAL]
    # each patrol reading once (task_status repeats last_result every second), at its bag time and stop
    task = [(round(since_start + r.t, 1), r.target, r.value, r.alarm) for r in summary.readings if r.task]
    assert task == [(at, r["target"], r["value"], r["alarm"]) for at, result in make_bag_fixture.FIXTURE_RESULTS
                    for r in result["readings"]]
    assert all((r.x, r.y) == make_bag_fixture.FIXTURE_GOAL for r in summary.readings)


def test_missing_bag(capsys, tmp_path):
    code, _out, err = report(capsys, str(tmp_path / "nope.bag"))
    assert code == 1 and err.strip() == "bag_report: error: %s: no such bag file" % (tmp_path / "nope.bag")


def test_truncated_bag(capsys, tmp_path):
    cut = str(tmp_path / "cut.bag")
    with open(FIXTURE, "rb") as src, open(cut, "wb") as dst:
        dst.write(src.read(os.path.getsize(FIXTURE) // 2))
    code, _out, err = report(capsys, cut, "--no-plot")
    assert code == 1 and err.startswith("bag_report: error: %s: " % cut) and err.count("\n") == 1
    assert "reindex" in err or "truncated" in err


def test_not_a_bag(capsys, tmp_path):
    text = tmp_path / "notes.bag"
    text.write_text("hello\n")
    code, _out, err = report(capsys, str(text))
    assert code == 1 and "not a readable bag" in err


def test_foreign_bag_names_what_is_missing(capsys, tmp_path):
    path = str(tmp_path / "chatter.bag")
    with rosbag.Bag(path, "w") as bag:
        bag.write("/chatter", String(data="hi"))
    code, _out, err = report(capsys, path)
    assert code == 1
    assert "no robot_status topic (inspection_robot/RobotStatus) in the bag; topics: /chatter" in err


def test_wrong_type_on_a_known_topic(capsys, tmp_path):
    path = str(tmp_path / "wrong.bag")
    with rosbag.Bag(path, "w") as bag:
        bag.write("/robot_status", RobotStatus(position=[0, 0]))
        bag.write("/obstacle_status", String(data="yes"))
    code, _out, err = report(capsys, path)
    assert code == 1
    assert "topic /obstacle_status has type std_msgs/String, expected inspection_robot/ObstacleStatus" in err


def test_a_type_unknown_to_this_build(capsys, tmp_path):
    from inspection_robot.msg import GeneralTopic
    path = str(tmp_path / "vendor.bag")
    with rosbag.Bag(path, "w") as bag:
        bag.write("/robot_status", RobotStatus(position=[0, 0]), rospy.Time(1))
        weird = {"topic": "/vendor_topic", "type": "vendor_msgs/Weird", "md5sum": String._md5sum,
                 "message_definition": "string data\nvendor_msgs/Missing inner\n"}
        bag.write("/vendor_topic", String(data="x"), rospy.Time(2), connection_header=weird)
    code, out, err = report(capsys, path, "--no-plot")   # a topic bag_report does not read: ignored
    assert code == 0 and "robot_status messages: 1" in out, err
    with rosbag.Bag(path, "a") as bag:
        garbled = {"topic": "/task_status", "type": GeneralTopic._type, "md5sum": GeneralTopic._md5sum,
                   "message_definition": "string data\nvendor_msgs/Missing inner\n"}
        bag.write("/task_status", GeneralTopic(data="{}"), rospy.Time(3), connection_header=garbled)
    code, _out, err = report(capsys, path, "--no-plot")
    assert code == 1 and err.count("\n") == 1
    assert err.startswith("bag_report: error: %s: topic /task_status: type inspection_robot/GeneralTopic cannot be "
                          "read from the bag's definition of it: Cannot locate message [Missing]" % path)


def test_check_says_whether_replay_launch_can_play_a_bag(capsys, tmp_path):
    code, out, err = report(capsys, "--check", "--ns", "/", FIXTURE, "__name:=replay_check", "__log:=/tmp/x.log")
    assert code == 0 and out == "bag_report: %s: replayable: 40.0 s of namespace / (control_status, nav_status, " \
        "robot_odom, server_status)\n" % FIXTURE, err
    code, _out, err = report(capsys, "--check", str(tmp_path / "nope.bag"))
    assert code == 1 and "no such bag file" in err
    path = str(tmp_path / "status_only.bag")
    with rosbag.Bag(path, "w") as bag:
        bag.write("/robot_status", RobotStatus(position=[0, 0]))
        bag.write("/nav_status", String(data="x"))
    code, _out, err = report(capsys, "--check", path)
    assert code == 1 and err == "bag_report: error: %s: no /control_status, /robot_odom, /server_status in the bag: " \
        "status_control cannot rebuild robot_status from it\n" % path
    with rosbag.Bag(path, "a") as bag:
        for topic in ("/control_status", "/robot_odom", "/server_status"):
            bag.write(topic, String(data="x"))
    code, _out, err = report(capsys, "--check", path)
    assert code == 1 and "topic /nav_status has type std_msgs/String, expected inspection_robot/NavStatus" in err


def test_several_robots_need_ns(capsys, tmp_path):
    path = str(tmp_path / "two.bag")
    with rosbag.Bag(path, "w") as bag:
        for ns in ("/a/", "/b/"):
            bag.write(ns + "robot_status", RobotStatus(position=[1, 2]))
    code, _out, err = report(capsys, path)
    assert code == 1 and "choose one with --ns" in err
    code, out, _err = report(capsys, path, "--ns", "b", "--no-plot")
    assert code == 0 and "robot_status messages: 1" in out


def test_the_executable_runs_by_name_without_traceback(tmp_path):
    exe = shutil.which("bag_report")
    if exe is None:
        pytest.skip("not run through scripts/rosenv")
    proc = subprocess.run([exe, str(tmp_path / "none.bag")], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                          universal_newlines=True, timeout=60)
    assert proc.returncode == 1 and "no such bag file" in proc.stderr and "Traceback" not in proc.stderr


# --- the picture's pure parts: positions never printed as nan, everything in the legend in view ---
NAN = float("nan")


def test_an_event_without_a_position_says_so():
    from inspection_robot.recording.summary import Event, RunAnalyzer, format_summary, where_text
    assert where_text(1.04, -2.0) == "at (1.0, -2.0)"
    assert where_text(NAN, NAN) == "position unknown"
    analyzer = RunAnalyzer()
    status = {"offline_warn": 1, "mode": 0, "velocity_x": 0.0, "velocity_yaw": 0.0, "position": [NAN, NAN],
              "battery_quantity": 80, "motor_status": [0] * 8, "other_status": [0]}
    status.update({f: 0 for f in ("light_status", "stop_status", "circuit_status", "nav_status", "sensor_status",
                                  "battery_status")})
    analyzer.add_status(100.0, status)
    analyzer.add_status(103.0, dict(status, position=[1.0, 2.0]))
    text = format_summary(analyzer.finish())
    assert "backend link lost (offline_warn)" in text and "position unknown" in text
    assert "nan" not in text.lower()
    events = [Event(0, NAN, NAN, "a"), Event(1, 1.0, 2.0, "b")]
    assert bag_report.legend_label("alarms", events) == "alarms (2; 1 at an unknown position)"
    assert bag_report.legend_label("alarms", events[1:]) == "alarms (1)"


def test_the_view_holds_every_point_and_a_far_virtual_obstacle():
    (x_lo, x_hi), (y_lo, y_hi) = bag_report.view_bounds([(0.0, 0.0), (2.0, 1.0), (NAN, NAN)],
                                                        [(30.0, 31.0, 30.0, 30.1), None])
    assert x_lo < 0.0 and x_hi > 31.0 and y_lo < 0.0 and y_hi > 30.1
    assert bag_report.view_bounds([(NAN, NAN)]) is None
    (x_lo, x_hi), _y = bag_report.view_bounds([(5.0, 5.0)])
    assert (x_lo, x_hi) == (-1.0, 11.0)   # a short run: 6 m of the yard around it


def test_the_occupied_cells_of_a_grid_bound_the_virtual_obstacle():
    from nav_msgs.msg import OccupancyGrid
    grid = OccupancyGrid()
    grid.info.width, grid.info.height, grid.info.resolution = 10, 5, 0.5
    grid.info.origin.position.x, grid.info.origin.position.y = -1.0, 2.0
    cells = [0] * 50
    cells[2 * 10 + 7] = 100   # row 2, column 7
    grid.data = cells
    assert bag_report.occupied_bounds(grid) == (2.5, 3.0, 3.0, 3.5)
    grid.data = [0] * 50
    assert bag_report.occupied_bounds(grid) is None


@pytest.mark.parametrize("x,y,ha,va", [(9.0, 9.0, "right", "top"), (1.0, 1.0, "left", "bottom"),
                                       (9.0, 1.0, "right", "bottom"), (1.0, 9.0, "left", "top")])
def test_labels_point_toward_the_middle_of_the_view(x, y, ha, va):
    bounds = ((0.0, 10.0), (0.0, 10.0))
    dx, dy, got_ha, got_va = bag_report.label_offset(x, y, bounds)
    assert (got_ha, got_va) == (ha, va)
    assert (dx < 0) == (x > 5.0) and (dy > 0) == (y < 5.0)
    _dx, dy2, _ha, _va = bag_report.label_offset(x, y, bounds, stacked=2)
    assert abs(dy2) == abs(dy) + 22   # stacked labels move further from the point, same direction


def test_the_picture_of_a_run_with_an_unplaced_alarm_and_a_far_obstacle(tmp_path):
    from nav_msgs.msg import OccupancyGrid
    from inspection_robot.recording.summary import Event, RunSummary, Stop
    summary = RunSummary()
    summary.t, summary.x, summary.y = [0.0, 1.0, 2.0], [0.0, 1.0, 2.0], [0.0, 0.0, 0.0]
    summary.speed, summary.battery, summary.mode = [0.0, 0.5, 0.0], [80, 80, 80], [0, 0, 0]
    summary.stops = [Stop(0.0, 0.0, 0.0, 3.0)]
    summary.alarms = [Event(0.0, NAN, NAN, "backend link lost (offline_warn)"), Event(1.0, 1.0, 0.0, "bumper")]
    virtual = OccupancyGrid()
    virtual.info.width, virtual.info.height, virtual.info.resolution = 100, 100, 0.5
    cells = [0] * 10000
    cells[90 * 100 + 90] = 100
    virtual.data = cells
    out = str(tmp_path / "run.png")
    bag_report.plot_run(summary, None, virtual, out, "made-up run")
    with open(out, "rb") as f:
        assert f.read(8) == b"\x89PNG\r\n\x1a\n"


def test_replay_player_arguments_and_whom_it_may_end():
    from inspection_robot.nodes import replay_player
    assert replay_player.split_args(["--at-end", "exit", "--clock", "a.bag", "__name:=replay_player"]) == (
        "exit", ["--clock", "a.bag", "__name:=replay_player"])
    for bad in ([], ["--clock"], ["--at-end", "later"]):
        with pytest.raises(ValueError, match="--at-end exit\\|hold"):
            replay_player.split_args(bad)
    assert not replay_player.launched_by_roslaunch(os.getpid())   # pytest, not roslaunch: never signalled
    assert not replay_player.launched_by_roslaunch(2 ** 22 + 1)   # no such process
