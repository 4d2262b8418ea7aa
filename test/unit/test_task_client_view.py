"""One path form towards a backend (#31.3): data-root-relative answers, both preset forms accepted,
every unit, and a consistent snapshot of the results store instead of its live WAL file."""
import json
import os
import sqlite3

import pytest

from inspection_robot.command import CommandError
from inspection_robot.files import root_relative
from inspection_robot.storage.commands import FileCommands
from inspection_robot.task.checks import resolve_preset
from inspection_robot.task.client_view import client_progress, client_row
from inspection_robot.task.store import ResultStore, export_snapshot


def test_root_relative_names_files_inside_the_data_root_only(tmp_path):
    root = str(tmp_path / "data")
    assert root_relative(os.path.join(root, "presets", "p1", "20260101_120000"), root) == "presets/p1/20260101_120000"
    assert root_relative("/elsewhere/x.jpg", root) == "/elsewhere/x.jpg"
    assert root_relative(root + "_other/x.jpg", root) == root + "_other/x.jpg"   # a sibling, not inside
    assert root_relative("", root) == "" and root_relative("presets/p1", root) == "presets/p1"
    os.makedirs(root)
    os.symlink(root, str(tmp_path / "link"))   # a data root named through a symlink: either spelling
    assert root_relative(os.path.join(root, "pictures", "a.jpg"), str(tmp_path / "link")) == "pictures/a.jpg"


def test_rows_and_status_name_files_relative_to_the_data_root_and_carry_the_thermal_unit():
    row = {"preset": "/d/presets/t1/20260101_120000", "picture": "/d/pictures/t1/a_read_00.jpg", "source_picture": "",
           "kind": "thermal", "unit": ""}   # a row stored before thermal readings had a unit
    assert client_row(row, "/d") == {"preset": "presets/t1/20260101_120000", "picture": "pictures/t1/a_read_00.jpg",
                                     "source_picture": "", "kind": "thermal", "unit": "C", "display": "",
                                     "review_display": ""}
    assert client_row(dict(row, kind="lamp"), "/d")["unit"] == ""
    status = {"state": "running", "last_result": {"stop": 1, "preset": "/d/presets/t1/20260101_120000"}}
    assert client_progress(status, "/d")["last_result"]["preset"] == "presets/t1/20260101_120000"
    assert client_progress(dict(status, last_result=None), "/d")["last_result"] is None


def test_task_presets_in_either_form_resolve_to_one_directory(tmp_path):
    data = tmp_path / "data"
    preset = data / "presets" / "p1" / "20260101_120000"
    preset.mkdir(parents=True)
    (preset / "preset.ini").write_text("[preset]\n")
    reasons = []
    for name in ("presets/p1/20260101_120000", "p1/20260101_120000", "p1", "presets/p1"):
        with pytest.raises(CommandError) as err:   # uncalibrated: the reason names the directory found
            resolve_preset(str(data / "presets"), name, str(data))
        reasons.append(str(err.value).split(": ", 1)[1])
    assert set(reasons) == {"corrupt preset.ini: No section: 'pictures'"}
    with pytest.raises(CommandError, match="unknown preset directory 'p9': preset directory not found"):
        resolve_preset(str(data / "presets"), "p9", str(data))
    with pytest.raises(CommandError, match=r"path '\.\./x' is outside the allowed roots \(presets\)"):
        resolve_preset(str(data / "presets"), "../x", str(data))


def test_export_is_a_consistent_single_file_and_file_control_refuses_the_live_store(tmp_path):
    data = tmp_path / "data"
    (data / "tasks").mkdir(parents=True)
    store = ResultStore(str(data / "tasks" / "results.sqlite"))
    store.set_meta("holds", ["operator"])   # committed: in the -wal until a checkpoint
    assert os.path.exists(str(data / "tasks" / "results.sqlite-wal"))
    files = FileCommands(str(data), ["tasks"])
    for name in ("tasks/results.sqlite", "tasks/results.sqlite-wal"):
        reply = files.table.dispatch("read", json.dumps({"path": name}))
        assert reply.ack == "failed" and "export_results" in reply.data and str(data) not in reply.data
    assert files.table.dispatch("stat", json.dumps({"path": "tasks/results.sqlite"})).ack == "success"
    folder = str(data / "tasks" / "exports")
    paths = [export_snapshot(store, folder, 1767268800.0, keep=2) for _ in range(3)]
    assert [os.path.basename(p) for p in paths][1:] == sorted(os.listdir(folder))   # the oldest removed
    assert os.path.basename(paths[1]) == os.path.basename(paths[0])[:-7] + "_2.sqlite"
    snapshot = paths[-1]
    assert not os.path.exists(snapshot + "-wal") and os.stat(snapshot).st_mode & 0o777 == 0o644
    copy = sqlite3.connect(snapshot)
    assert copy.execute("PRAGMA journal_mode").fetchone()[0] == "delete"
    assert copy.execute("SELECT value FROM meta WHERE key = 'holds'").fetchone()[0] == '["operator"]'
    copy.close()
    reply = files.table.dispatch("read", json.dumps({"path": root_relative(snapshot, str(data))}))
    assert reply.ack == "success" and json.loads(reply.data)["eof"]
    store.close()
