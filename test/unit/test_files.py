"""The files module: confined paths, atomic writes (whole old file or whole new file, never
leftovers), JSON state files; every failure is one FileError."""
import os

import pytest

from inspection_robot import files
from inspection_robot.command import CommandError
from inspection_robot.files import FileError, confine_path, read_json, write_atomic, write_json_atomic


def test_writes_text_and_bytes_and_creates_the_folder(tmp_path):
    text_path = str(tmp_path / "a" / "b" / "state.json")
    write_atomic(text_path, '{"x": 1}')
    write_atomic(str(tmp_path / "pic.jpg"), b"\xff\xd8\xff")
    assert open(text_path).read() == '{"x": 1}'
    assert open(str(tmp_path / "pic.jpg"), "rb").read() == b"\xff\xd8\xff"


def test_replacing_keeps_the_old_file_until_the_new_one_is_complete(tmp_path):
    path = str(tmp_path / "preset.ini")
    write_atomic(path, "old")
    with pytest.raises(TypeError):
        write_atomic(path, 12345)
    assert open(path).read() == "old"
    assert sorted(os.listdir(str(tmp_path))) == ["preset.ini"]


def test_failure_while_writing_keeps_the_old_file(tmp_path, monkeypatch):
    path = str(tmp_path / "preset.ini")
    write_atomic(path, "old")

    def crash(*_args):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(files.os, "fsync", crash)
    with pytest.raises(FileError, match="No space left"):
        write_atomic(path, "new")
    assert open(path).read() == "old"
    assert sorted(os.listdir(str(tmp_path))) == ["preset.ini"]


def test_failed_rename_leaves_no_temporary_file(tmp_path):
    target = tmp_path / "occupied"
    target.mkdir()
    (target / "child").write_text("x")
    with pytest.raises(FileError):
        write_atomic(str(target), "data")  # a non-empty directory cannot be replaced by a file
    assert sorted(os.listdir(str(tmp_path))) == ["occupied"]


def test_confine_path(tmp_path):
    root = tmp_path / "pictures"
    root.mkdir()
    assert confine_path(str(root / "a" / "b.jpg"), [str(root)]) == str(root / "a" / "b.jpg")
    assert confine_path("rel/x.jpg", [str(root)]) == str(root / "rel" / "x.jpg")
    for bad in [str(root / ".." / "escape.jpg"), "/etc/passwd", "", "../x", "a\x00b"]:
        with pytest.raises(FileError):
            confine_path(bad, [str(root)])
    os.symlink("/etc", str(root / "link"))
    with pytest.raises(FileError, match="outside the allowed roots"):
        confine_path(str(root / "link" / "passwd"), [str(root)])
    with pytest.raises(FileError, match="no allowed roots"):
        confine_path("x.jpg", [])


def test_file_error_is_a_command_failure():
    assert issubclass(FileError, CommandError)


def test_json_state_round_trip_missing_and_corrupt(tmp_path):
    path = str(tmp_path / "state" / "pose.json")
    assert read_json(path) is None
    write_json_atomic(path, {"x": 1.5})
    assert read_json(path) == {"x": 1.5}
    open(path, "w").write("{half")
    with pytest.raises(FileError, match="not valid JSON"):
        read_json(path)


def _tree(folder):
    out = {}
    for base, _dirs, names in os.walk(str(folder)):
        for name in names:
            path = os.path.join(base, name)
            out[os.path.relpath(path, str(folder))] = open(path, "rb").read()
    return out


def test_dir_update_replaces_the_folder_at_once_or_not_at_all(tmp_path):
    folder = tmp_path / "preset"
    (folder / "sub").mkdir(parents=True)
    (folder / "keep.jpg").write_bytes(b"jpeg")
    (folder / "sub" / "deep.txt").write_text("deep")
    (folder / "calib.ini").write_text("old")
    os.symlink("keep.jpg", str(folder / "link.jpg"))
    before = _tree(folder)
    with pytest.raises(RuntimeError):     # left without commit: the folder untouched, no copy left
        with files.DirUpdate(str(folder)) as update:
            write_atomic(update.file("calib.ini"), "new")
            write_atomic(update.file("zoom0.xml"), "<zoom/>")
            assert _tree(folder) == before
            raise RuntimeError("operator gave up")
    assert _tree(folder) == before and os.listdir(str(tmp_path)) == ["preset"]
    inode = os.stat(str(folder)).st_ino
    with files.DirUpdate(str(folder)) as update:
        write_atomic(update.file("calib.ini"), "new")
        write_atomic(update.file("zoom0.xml"), "<zoom/>")
        update.commit()
    assert _tree(folder) == dict(before, **{"calib.ini": b"new", "zoom0.xml": b"<zoom/>"})
    assert os.readlink(str(folder / "link.jpg")) == "keep.jpg"
    assert os.stat(str(folder)).st_ino != inode and os.listdir(str(tmp_path)) == ["preset"]


def test_dir_update_refuses_a_missing_folder(tmp_path):
    with pytest.raises(FileError) as err:
        files.DirUpdate(str(tmp_path / "nowhere"))
    assert "no such directory" in str(err.value)
