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
                   "backend: read_scale = 0.42 (no band)",
                   "fixture_patrol stop 1: transformer_1/oil_temp = 118.2 C (alarm)",
                   "fixture_patrol stop 1: cabinet_1/ammeter = 231.5 A (normal)",
                   "fixture_patrol stop 1: cabinet_1/lamp_run = 2 (no band)",
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
