"""The files module: confined paths, atomic writes (whole old file or whole new file, never
leftovers), JSON state files; every failure is one FileError. With its neighbours: a folder's files
changed at once (dir_update), the capture roots and their quota (data_layout)."""
import os

import pytest

from inspection_robot import data_layout, dir_update, files
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


# --- paths a command creates: fuzzed, each refused clearly and nothing written -----------------
def _tree(tmp_path):
    """Every file below ``tmp_path`` with its bytes (the whole tree, so nothing can hide)."""
    out = {}
    for folder, _dirs, names in os.walk(str(tmp_path)):
        for name in names:
            path = os.path.join(folder, name)
            out[os.path.relpath(path, str(tmp_path))] = open(path, "rb").read() if not os.path.islink(path) else "link"
    return out


@pytest.fixture
def roots(tmp_path):
    captures = tmp_path / "captures"
    captures.mkdir()
    (captures / "kept.jpg").write_bytes(b"calibrated")
    (tmp_path / "presets").mkdir()
    (tmp_path / "presets" / "preset.ini").write_text("[preset]")
    os.symlink(str(tmp_path / "presets"), str(captures / "to_presets"))
    os.symlink(str(tmp_path / "presets" / "new.ini"), str(captures / "dangling.jpg"))
    return tmp_path, [str(captures)]


@pytest.mark.parametrize("path, reason", [
    ("", "empty path"),
    ("a\x00b.jpg", "contains a NUL byte"),
    ("shot.jpg\n", "contains a control or unprintable character"),
    ("a\tb.jpg", "contains a control or unprintable character"),
    ("x/" * 2100 + "a.jpg", "is too long (4205 bytes, at most 4095)"),
    ("n" * 256 + ".jpg", "has a name of 260 bytes (at most 255)"),
    ("\u00e9" * 128 + ".jpg", "has a name of 260 bytes"),   # 2 bytes a character in UTF-8
    ("../presets/preset.ini", "contains '..'"),
    ("sub/../kept.jpg", "contains '..'"),
    ("/etc/cron.d/x", "outside the allowed roots"),
    ("to_presets/preset.ini", "outside the allowed roots"),      # a link out of the root
    ("to_presets/new.jpg", "outside the allowed roots"),
    ("dangling.jpg", "outside the allowed roots"),               # a link to a file not yet there
    ("kept.jpg", "'kept.jpg' already exists (files are never replaced: choose a new name)"),
    (".", "is a directory"),
    (".staging/x.jpg", "has the hidden name '.staging': names starting with '.' are the robot's own"),
    (".staging/" + "0" * 32, "hidden name '.staging'"),              # a staged name has an extension or ...
    ("sub/.staging/" + "a" * 32 + ".jpg", "hidden name '.staging'"),  # ... lies in the first root's .staging
    (".preset.ini.x1y2.tmp", "hidden name '.preset.ini.x1y2.tmp'"),  # write_atomic's in-progress file
    ("a/.tmp_20260101_x/zoom0.jpg", "hidden name '.tmp_20260101_x'"),
])
def test_new_file_path_refuses_and_nothing_is_written(roots, path, reason):
    tmp_path, allowed = roots
    before = _tree(tmp_path)
    with pytest.raises(FileError) as err:
        files.new_file_path(path, allowed)
    assert reason in str(err.value)
    assert "\n" not in str(err.value) and len(str(err.value)) < 400   # one short line, whatever came in
    assert _tree(tmp_path) == before


def test_new_file_path_accepts_a_fresh_name_relative_or_absolute(roots):
    tmp_path, allowed = roots
    assert files.new_file_path("a/b.jpg", allowed) == str(tmp_path / "captures" / "a" / "b.jpg")
    assert files.new_file_path(str(tmp_path / "captures" / "c.jpg"), allowed) == str(tmp_path / "captures" / "c.jpg")


def test_only_a_fresh_staged_name_may_be_hidden_and_a_link_does_not_lead_into_a_hidden_folder(tmp_path):
    root = tmp_path / ".ros" / "data" / "captures"   # a data root below a hidden folder (standalone_data_root)
    (root / ".staging").mkdir(parents=True)
    os.symlink(str(root / ".staging"), str(root / "staging"))
    with pytest.raises(FileError, match="hidden name '.staging'"):
        files.new_file_path("staging/a.jpg", [str(root)])
    staged = files.staged_name(".png")
    with pytest.raises(FileError, match="hidden name '.staging'"):   # not through a client's command
        files.new_file_path(staged, [str(root)])
    assert files.new_file_path(staged, [str(root)], staged=True) == str(root / staged)   # the staging service's
    with pytest.raises(FileError, match="hidden name '.staging'"):   # and only a fresh staged name there
        files.new_file_path(".staging/mine.png", [str(root)], staged=True)
    assert files.new_file_path(str(root / "a.jpg"), [str(root)]) == str(root / "a.jpg")   # the root's own path
    assert files.staged_name(".png") != staged


def test_capture_quota_counts_once_then_adds_and_counts_again_before_refusing(tmp_path, monkeypatch):
    root = tmp_path / "captures"
    (root / ".staging").mkdir(parents=True)
    (root / "a.jpg").write_bytes(b"x" * 600)
    (root / ".staging" / "b.jpg").write_bytes(b"x" * 300)      # hidden files count too
    os.symlink("/etc/passwd", str(root / "link.jpg"))           # a link is not followed
    walks = []
    real_tree_bytes = data_layout.tree_bytes
    monkeypatch.setattr(data_layout, "tree_bytes", lambda folder: (walks.append(folder) if folder == str(root)
                                                                   else None) or real_tree_bytes(folder))
    now = [0.0]
    quota = data_layout.CaptureQuota([str(root)], 1000, rescan_s=60.0, clock=lambda: now[0])
    quota.check(100)                                           # positive control: 900 + 100 fits
    assert quota.used() >= 900 and len(walks) == 1
    quota.add(100)
    with pytest.raises(FileError, match=r"capture quota exceeded: the capture folders hold 900 of 1000 bytes and "
                                        r"this picture needs 101; delete old captures \(nothing written\)"):
        quota.check(101, "this picture")                      # the added 100 were never written: counted again
    assert len(walks) == 2
    (root / "a.jpg").unlink()                                  # an operator deletes old captures
    quota.check(500)                                           # counted again before refusing: 300 + 500 fits
    assert len(walks) == 3
    quota.add(500)
    quota.check(200)                                           # cached 800 + 200 fits: no walk
    assert len(walks) == 3
    now[0] = 61.0
    assert quota.used() == 300 and len(walks) == 4              # older than rescan_s: counted again
    assert data_layout.CaptureQuota([str(root)], 0).check(10 ** 12) is None   # 0: no quota
    with pytest.raises(ValueError, match="whole number of bytes"):
        data_layout.CaptureQuota([str(root)], -1)
    assert data_layout.CaptureQuota.from_mib([str(root)], 2048).limit == 2 << 30   # the default, in a ROS int
    for bad in (-1, 1.5, "8", True):
        with pytest.raises(ValueError, match="~quota_mib must be a whole number of MiB"):
            data_layout.CaptureQuota.from_mib([str(root)], bad)


def test_confine_path_names_the_request_not_the_resolved_path(tmp_path):
    root = tmp_path / "data" / "pictures"
    root.mkdir(parents=True)
    with pytest.raises(FileError) as err:
        confine_path("../../secret", [str(root)], base=str(tmp_path / "data"), root_names=["pictures"])
    assert str(err.value) == "path '../../secret' is outside the allowed roots (pictures)"
    assert confine_path("pictures/x.jpg", [str(root)], base=str(tmp_path / "data")) == str(root / "x.jpg")


def test_write_without_replace_refuses_an_existing_file_and_keeps_it(tmp_path):
    path = str(tmp_path / "preset.ini")
    write_atomic(path, "calibrated")
    with pytest.raises(FileError, match="already exists"):
        write_atomic(path, b"\xff\xd8 jpeg", replace=False)
    assert open(path).read() == "calibrated"
    assert os.listdir(str(tmp_path)) == ["preset.ini"]   # no temporary file left
    write_atomic(str(tmp_path / "new.jpg"), b"\xff\xd8", replace=False)
    assert open(str(tmp_path / "new.jpg"), "rb").read() == b"\xff\xd8"
    assert sorted(os.listdir(str(tmp_path))) == ["new.jpg", "preset.ini"]


def test_write_without_replace_on_a_filesystem_without_hard_links(tmp_path, monkeypatch):
    def no_links(*_args):
        raise OSError(1, "Operation not permitted")
    monkeypatch.setattr(files.os, "link", no_links)
    write_atomic(str(tmp_path / "a.jpg"), b"new", replace=False)
    with pytest.raises(FileError, match="already exists"):
        write_atomic(str(tmp_path / "a.jpg"), b"newer", replace=False)
    assert open(str(tmp_path / "a.jpg"), "rb").read() == b"new"
    assert os.listdir(str(tmp_path)) == ["a.jpg"]


def test_every_rename_fsyncs_the_folders_it_changed(tmp_path, monkeypatch):
    synced = []
    real_fsync = os.fsync

    def fsync(fd):
        synced.append(os.readlink("/proc/self/fd/%d" % fd))
        return real_fsync(fd)
    monkeypatch.setattr(files.os, "fsync", fsync)
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "x").write_text("x")
    files.rename_durable(str(tmp_path / "a" / "x"), str(tmp_path / "b.txt"))
    assert synced == [str(tmp_path), str(tmp_path / "a")]
    del synced[:]
    write_atomic(str(tmp_path / "c.txt"), "c", replace=False)
    assert synced[-1] == str(tmp_path)   # the file, then its folder
    with pytest.raises(FileError, match="cannot write 'missing'"):
        files.rename_durable(str(tmp_path / "nothing"), "missing")


def test_move_file_puts_another_process_file_in_place(tmp_path):
    (tmp_path / "captures").mkdir()
    src = tmp_path / "captures" / ".staging.jpg"
    src.write_bytes(b"picture")
    dst = tmp_path / "presets" / ".tmp_x" / "zoom0.jpg"
    files.move_file(str(src), str(dst))
    assert dst.read_bytes() == b"picture" and not src.exists()
    with pytest.raises(FileError, match="cannot read"):
        files.move_file(str(src), str(dst))
    assert dst.read_bytes() == b"picture"


@pytest.mark.parametrize("roots, owned", [
    (["{root}"], "arm"), (["{root}/presets"], "presets"), (["{root}/pictures/p1"], "pictures"),
    (["{root}/captures", "{root}/tasks"], "tasks"),
])
def test_capture_roots_never_overlap_an_owner_folder(tmp_path, roots, owned):
    root = str(tmp_path)
    with pytest.raises(ValueError) as err:
        data_layout.capture_roots([r.format(root=root) for r in roots], root)
    assert os.path.join(root, owned) in str(err.value)


def test_capture_roots_accepts_captures_thermal_and_folders_elsewhere(tmp_path):
    root = str(tmp_path / "data")
    good = [root + "/captures", root + "/thermal/x", str(tmp_path / "usb")]
    assert data_layout.capture_roots(good, root) == good


def test_dir_update_replaces_the_folder_at_once_or_not_at_all(tmp_path):
    folder = tmp_path / "preset"
    (folder / "sub").mkdir(parents=True)
    (folder / "keep.jpg").write_bytes(b"jpeg")
    (folder / "sub" / "deep.txt").write_text("deep")
    (folder / "calib.ini").write_text("old")
    os.symlink("keep.jpg", str(folder / "link.jpg"))
    before = _tree(folder)
    with pytest.raises(RuntimeError):     # left without commit: the folder untouched, no copy left
        with dir_update.DirUpdate(str(folder)) as update:
            write_atomic(update.file("calib.ini"), "new")
            write_atomic(update.file("zoom0.xml"), "<zoom/>")
            assert _tree(folder) == before
            raise RuntimeError("operator gave up")
    assert _tree(folder) == before and os.listdir(str(tmp_path)) == ["preset"]
    inode = os.stat(str(folder)).st_ino
    with dir_update.DirUpdate(str(folder)) as update:
        write_atomic(update.file("calib.ini"), "new")
        write_atomic(update.file("zoom0.xml"), "<zoom/>")
        update.commit()
    assert _tree(folder) == dict(before, **{"calib.ini": b"new", "zoom0.xml": b"<zoom/>"})
    assert os.readlink(str(folder / "link.jpg")) == "keep.jpg"
    assert os.stat(str(folder)).st_ino != inode and os.listdir(str(tmp_path)) == ["preset"]


def test_dir_update_refuses_a_missing_folder(tmp_path):
    with pytest.raises(FileError) as err:
        dir_update.DirUpdate(str(tmp_path / "nowhere"))
    assert "no such directory" in str(err.value)


def test_hide_root_takes_the_data_root_out_of_a_reason(tmp_path):
    root = str(tmp_path / "data")
    os.makedirs(root)
    link = str(tmp_path / "link")
    os.symlink(root, link)
    reason = ("path '/etc/passwd' is outside the allowed roots (%s/captures, %s/thermal); cannot read '%s/presets/p1': "
              "[Errno 2] No such file or directory: '%s'" % (root, link, root, link))
    shown = files.hide_root(reason, link)   # given as a link: the resolved root goes too
    assert shown == ("path '/etc/passwd' is outside the allowed roots (captures, thermal); cannot read 'presets/p1': "
                     "[Errno 2] No such file or directory: '.'")
    assert root not in shown and link not in shown
    # a sibling folder whose name starts like the root is not the root
    assert files.hide_root("%sx/a" % root, root) == "%sx/a" % root
    assert files.hide_root("no root here", "") == "no root here"
    assert files.hide_root("/a/b", "/") == "/a/b"


def test_every_confined_path_refusal_of_a_camera_names_no_absolute_root(tmp_path):
    """camera_node and infrared_imager name their roots as given (absolute); the twin hides the data root."""
    root = str(tmp_path)
    with pytest.raises(FileError) as err:
        files.new_file_path("/etc/x.jpg", [os.path.join(root, "captures")])
    assert files.hide_root(str(err.value), root) == "path '/etc/x.jpg' is outside the allowed roots (captures)"
