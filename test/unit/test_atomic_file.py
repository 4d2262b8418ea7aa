"""The one atomic file writer: whole old file or whole new file, never leftovers."""
import os

import pytest

from inspection_robot.atomic_file import write_atomic


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
        write_atomic(path, 12345)        # fails while writing the temporary file
    assert open(path).read() == "old"
    assert sorted(os.listdir(str(tmp_path))) == ["preset.ini"]


def test_failed_rename_leaves_no_temporary_file(tmp_path):
    target = tmp_path / "occupied"
    target.mkdir()
    (target / "child").write_text("x")
    with pytest.raises(OSError):
        write_atomic(str(target), "data")  # a non-empty directory cannot be replaced by a file
    assert sorted(os.listdir(str(tmp_path))) == ["occupied"]
