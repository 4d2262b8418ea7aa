"""location_cmd -> pose handed to the localizer (nav.localization.location_target)."""
import math

import pytest

from inspection_robot.command import CommandError
from inspection_robot.nav.localization import location_target

INIT = [5.0, 5.0, 0.0]


def target(data, last=None, cmd="set_location"):
    return location_target(cmd, data, INIT, lambda: last)


def test_the_three_forms():
    assert target("init_pose") == (5.0, 5.0, 0.0)
    assert target("last_pose", {"x": 1.5, "y": -2, "yaw": 4.0}) == pytest.approx((1.5, -2.0, 4.0 - 2 * math.pi))
    assert target("12.5,-3,3.1") == pytest.approx((12.5, -3.0, 3.1))


@pytest.mark.parametrize("data,last,reason", [
    ("last_pose", None, "no last pose"),
    ("last_pose", {"x": 1}, "lacks x, y, yaw"),
    ("last_pose", ["x", "y"], "lacks x, y, yaw"),
    ("last_pose", {"x": "nan", "y": 0, "yaw": 0}, "finite"),
    ("1,2", None, "3 comma-separated"),
    ("a,b,c", None, "number"),
    ("1,2,inf", None, "finite"),
])
def test_bad_requests_name_the_reason(data, last, reason):
    with pytest.raises(CommandError, match=reason):
        target(data, last)


def test_unreadable_file_and_unknown_command():
    def broken():
        raise ValueError("truncated JSON")
    with pytest.raises(CommandError, match="unreadable"):
        location_target("set_location", "last_pose", INIT, broken)
    with pytest.raises(CommandError, match="unknown command"):
        target("init_pose", cmd="teleport")
