"""file_control: listing, metadata and chunked reads confined to the data roots."""
import base64
import hashlib
import json
import os

import pytest

from inspection_robot.storage.commands import FileCommands


@pytest.fixture
def robot(tmp_path):
    root = tmp_path / "data"
    (root / "pictures" / "p1").mkdir(parents=True)
    (root / "captures").mkdir()
    (root / "nav").mkdir()
    (root / "nav" / "last_pose.json").write_text("{}")
    payload = bytes(range(256)) * 41  # 10496 bytes
    (root / "pictures" / "p1" / "a_read_00.jpg").write_bytes(payload)
    (root / "pictures" / "p1" / ".a.jpg.x.tmp").write_bytes(b"half")
    (tmp_path / "secret.txt").write_text("no")
    files = FileCommands(str(root), ["presets", "pictures", "captures"], max_chunk_bytes=4096, max_entries=2)
    return files, root, payload


def call(files, cmd, **fields):
    reply = files.table.dispatch(cmd, json.dumps(fields))
    return reply.ack, (json.loads(reply.data) if reply.ack == "success" else reply.data)


def test_list_roots_then_a_folder(robot):
    files, _root, payload = robot
    ack, out = call(files, "list", path="")
    assert ack == "success" and [e["name"] for e in out["entries"]] == ["pictures", "captures"]
    ack, out = call(files, "list", path="pictures/p1")
    assert out["entries"] == [{"name": "a_read_00.jpg", "type": "file", "size": len(payload),
                               "mtime": out["entries"][0]["mtime"]}]  # the hidden temporary file is not listed
    assert out["total"] == 1 and not out["truncated"]


def test_list_pages_through_a_big_folder(robot):
    files, root, _payload = robot
    for i in range(5):
        (root / "captures" / ("c%d.jpg" % i)).write_bytes(b"x")
    names, offset = [], 0
    while True:
        _ack, out = call(files, "list", path="captures", offset=offset)
        names += [e["name"] for e in out["entries"]]
        offset += len(out["entries"])
        if not out["truncated"]:
            break
    assert names == ["c%d.jpg" % i for i in range(5)] and out["total"] == 5


def test_read_in_bounded_chunks_reassembles_the_file(robot):
    files, _root, payload = robot
    ack, stat = call(files, "stat", path="pictures/p1/a_read_00.jpg")
    assert ack == "success" and stat["size"] == len(payload) and stat["type"] == "file"
    assert stat["sha256"] == hashlib.sha256(payload).hexdigest()
    data, offset = b"", 0
    while True:
        ack, chunk = call(files, "read", path="pictures/p1/a_read_00.jpg", offset=offset)
        assert ack == "success" and chunk["length"] <= 4096
        data += base64.b64decode(chunk["data"])
        offset += chunk["length"]
        if chunk["eof"]:
            break
    assert data == payload
    ack, chunk = call(files, "read", path="pictures/p1/a_read_00.jpg", offset=len(payload))
    assert chunk["eof"] and chunk["length"] == 0


@pytest.mark.parametrize("cmd,fields,reason", [
    ("read", {"path": "pictures/p1/missing.jpg"}, "no such file: 'pictures/p1/missing.jpg'"),
    ("stat", {"path": "pictures/nothing"}, "no such file or directory: 'pictures/nothing'"),
    ("list", {"path": "pictures/nothing"}, "no such directory: 'pictures/nothing'"),
    ("read", {"path": "../secret.txt"}, "outside the allowed roots"),
    ("read", {"path": "nav/last_pose.json"}, "outside the allowed roots"),
    ("list", {"path": "/etc"}, "outside the allowed roots"),
    ("read", {"path": "pictures/p1"}, "is a directory (use list)"),
    ("list", {"path": "pictures/p1/a_read_00.jpg"}, "not a directory"),
    ("read", {"path": "pictures/p1/a_read_00.jpg", "length": 4097}, "length out of range [1, 4096]"),
    ("read", {"path": "pictures/p1/a_read_00.jpg", "length": 0}, "length out of range"),
    ("read", {"path": "pictures/p1/a_read_00.jpg", "offset": -1}, "offset out of range"),
    ("read", {"path": "pictures/p1/a_read_00.jpg", "offset": "5"}, "offset must be an integer"),
    ("read", {"path": "pictures/p1/a_read_00.jpg", "offset": 99999}, "beyond the end"),
    ("read", {}, "missing field 'path'"),
    ("read", {"path": 5}, "path must be a string"),
    ("stat", {"path": "pictures", "mode": "w"}, "unknown field(s) mode"),
])
def test_bad_requests_fail_clearly(robot, cmd, fields, reason):
    ack, out = call(robot[0], cmd, **fields)
    assert ack == "failed" and reason in out


def test_junk_data_and_unknown_commands(robot):
    files = robot[0]
    assert "not valid JSON" in files.table.dispatch("read", "{oops").data
    assert "JSON object" in files.table.dispatch("read", "[1]").data
    assert files.table.dispatch("write", "{}") == ("failed", "unknown command 'write'")


def test_symlink_out_of_the_roots_is_refused(robot):
    files, root, _payload = robot
    os.symlink("/etc", str(root / "captures" / "etc"))
    ack, out = call(files, "read", path="captures/etc/hostname")
    assert ack == "failed" and "outside the allowed roots" in out


def test_list_does_not_follow_links_out_of_the_roots(robot):
    files, root, payload = robot
    outside = root.parent / "secret.txt"
    os.symlink(str(outside), str(root / "captures" / "leak.txt"))            # a file outside
    os.symlink("/etc", str(root / "captures" / "etc"))                       # a folder outside
    os.symlink(str(root / "nowhere"), str(root / "captures" / "dangling"))  # nothing at all
    os.symlink(str(root / "pictures" / "p1" / "a_read_00.jpg"), str(root / "captures" / "same.jpg"))  # inside
    names, offset = {}, 0
    while True:
        _ack, out = call(files, "list", path="captures", offset=offset)
        names.update((e["name"], e) for e in out["entries"])
        offset += len(out["entries"])
        if not out["truncated"]:
            break
    for name in ("leak.txt", "etc", "dangling"):
        link = os.lstat(str(root / "captures" / name))
        assert names[name] == {"name": name, "type": "link", "size": link.st_size,
                               "mtime": round(link.st_mtime, 3)}, name   # the link's own, not its target's
    assert names["same.jpg"]["type"] == "file" and names["same.jpg"]["size"] == len(payload)
    ack, out = call(files, "stat", path="captures/leak.txt")
    assert (ack, out) == ("failed",
                          "path 'captures/leak.txt' is outside the allowed roots (presets, pictures, captures)")


@pytest.mark.parametrize("cmd", ["list", "stat", "read"])
@pytest.mark.parametrize("path, reason", [
    ("../secret.txt", "path '../secret.txt' is outside the allowed roots (presets, pictures, captures)"),
    ("nav/last_pose.json", "path 'nav/last_pose.json' is outside the allowed roots (presets, pictures, captures)"),
    ("pictures/../../secret.txt", "path 'pictures/../../secret.txt' is outside the allowed roots"),
    ("captures/a\x00b", "path 'captures/a\\x00b' contains a NUL byte"),
    ("captures/c.jpg\n", "path 'captures/c.jpg\\n' contains a control or unprintable character"),
    ("captures/" + "d/" * 2100, "is too long"),
    ("captures/" + "n" * 256, "has a name of 256 bytes (at most 255)"),
    ("", "empty path"),
    ("captures/gone", "'captures/gone'"),
])
def test_errors_name_the_request_never_the_resolved_path(robot, cmd, path, reason):
    files, root, _payload = robot
    if cmd == "list" and path == "":
        return   # "" lists the roots
    os.symlink(str(root / "captures" / "gone_target"), str(root / "captures" / "gone"))
    ack, out = call(files, cmd, path=path)
    assert ack == "failed" and reason in out, out
    assert str(root) not in out and str(root.parent) not in out and len(out) < 400
