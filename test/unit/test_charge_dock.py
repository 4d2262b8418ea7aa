"""The dock description: parsing, the docked test the simulator uses, the near-dock test charge_control uses."""
import math

import pytest

from inspection_robot.charge.dock import DockError, is_docked, near_dock, parse_dock, pose_error

SPEC = {"pose": [2.2, 5.0, math.pi], "approach_pose": [3.7, 5.0, math.pi], "tolerance_m": 0.03, "tolerance_yaw": 0.05}


def test_parse_and_tolerances():
    dock = parse_dock(SPEC)
    assert dock.pose == (2.2, 5.0, math.pi) and dock.approach == (3.7, 5.0, math.pi)
    assert is_docked(dock, (2.22, 5.01, -math.pi + 0.02)), "yaw wraps around pi"
    assert not is_docked(dock, (2.24, 5.0, math.pi))
    assert not is_docked(dock, (2.2, 5.0, math.pi - 0.06))
    assert pose_error(dock, (2.2, 5.04, math.pi)) == pytest.approx((0.04, 0.0))
    assert near_dock(dock, (2.9, 5.0, 0.0)) and not near_dock(dock, (3.0, 5.0, 0.0))
    assert parse_dock({"pose": [0, 0, 0], "approach_pose": [1, 0, 0]}).tolerance_m == 0.03


@pytest.mark.parametrize("spec, message", [
    ([1, 2], "dock must be a mapping"),
    ({"approach_pose": [1, 0, 0]}, "dock.pose must be"),
    ({"pose": [0, 0, "x"], "approach_pose": [1, 0, 0]}, "dock.pose must be three numbers"),
    ({"pose": [0, 0, float("nan")], "approach_pose": [1, 0, 0]}, "dock.pose must be finite"),
    ({"pose": [0, 0, 0], "approach_pose": [0, 0, 0]}, "dock.approach_pose must be 0-10 m"),
    ({"pose": [0, 0, 0], "approach_pose": [50, 0, 0]}, "dock.approach_pose must be 0-10 m"),
    ({"pose": [0, 0, 0], "approach_pose": [1, 0, 0], "tolerance_m": 0}, "dock.tolerance_m must be a positive"),
    ({"pose": [0, 0, 0], "approach_pose": [1, 0, 0], "tolerance_yaw": True}, "dock.tolerance_yaw must be a positive"),
])
def test_bad_dock_refused(spec, message):
    with pytest.raises(DockError, match=message):
        parse_dock(spec)
