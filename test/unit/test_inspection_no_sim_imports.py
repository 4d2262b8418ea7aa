"""The production read path imports nothing from sim/: inspection/ and the inspection nodes."""
import os

from test_import_rules import imported_modules

SRC = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), "src",
                   "inspection_robot")


def test_inspection_read_path_does_not_import_the_simulator():
    files = [os.path.join(SRC, "inspection", n) for n in os.listdir(os.path.join(SRC, "inspection"))
             if n.endswith(".py")]
    files += [os.path.join(SRC, "nodes", n) for n in ("read_scale.py", "find_scale.py", "preset_scale.py")]
    leaks = [(os.path.relpath(f, SRC), m) for f in files for m in imported_modules(f)
             if m == "inspection_robot.sim" or m.startswith("inspection_robot.sim.")]
    assert len(files) > 10
    assert leaks == []
