"""RosHead's pictures: the camera writes a new file in its own capture root, the owner
(preset_scale, find_scale) moves it into the preset or pictures folder; nothing stays behind."""
import os

import pytest

from inspection_robot.inspection.finder import FindError
from inspection_robot.inspection.ros_head import _take


class FakeDevice(object):
    """A capture command confined like camera_node's: a new file under ``root``, absolute path answered."""
    name = "camera_control"

    def __init__(self, root):
        self.root = root
        self.requests = []

    def call(self, cmd, data):
        self.requests.append((cmd, data))
        path = os.path.join(self.root, data)
        assert not os.path.exists(path) and ".." not in data
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path, "wb") as f:
            f.write(b"%s picture" % cmd.encode())
        return path


def test_the_picture_is_taken_in_the_capture_root_and_moved_by_its_owner(tmp_path):
    captures = tmp_path / "captures"
    device = FakeDevice(str(captures))
    target = tmp_path / "presets" / "p1" / ".tmp_x" / "thermal.png"
    _take(device, "save_temperature", str(target))
    (cmd, staged), = device.requests
    assert cmd == "save_temperature" and staged.startswith(".staging/") and staged.endswith(".png")
    assert target.read_bytes() == b"save_temperature picture"
    assert os.listdir(str(captures / ".staging")) == []


def test_a_failed_move_leaves_nothing_in_the_capture_root(tmp_path):
    captures = tmp_path / "captures"
    device = FakeDevice(str(captures))
    blocker = tmp_path / "presets"
    blocker.write_text("not a folder")
    with pytest.raises(FindError, match="camera_control capture_picture: cannot write"):
        _take(device, "capture_picture", str(blocker / "zoom0.jpg"))
    assert os.listdir(str(captures / ".staging")) == [] and blocker.read_text() == "not a folder"
