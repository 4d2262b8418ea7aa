"""yard_patrol (test harness): it finds the package's simulated world from the source tree it runs in."""
import os

from inspection_robot_testing.yard_patrol import YARD_STOPS, default_world_file

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def test_default_world_is_the_package_sim_world():
    assert os.path.realpath(default_world_file()) == os.path.realpath(os.path.join(ROOT, "config", "sim_world.yaml"))
    assert os.path.isfile(default_world_file())
    assert len(YARD_STOPS) == 6
