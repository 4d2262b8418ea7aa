"""lazy: a module held by lazy_import is imported at its first attribute access, not before."""
import subprocess
import sys

import pytest

from inspection_robot.lazy import lazy_import


def assert_runs(code):
    """Run ``code`` in a fresh interpreter (this process may already have imported the modules)."""
    result = subprocess.run([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            universal_newlines=True)
    assert result.returncode == 0, result.stderr


def test_module_imported_on_first_attribute_only():
    # a fresh interpreter: this test process may already have imported colorsys
    code = ("import sys\nfrom inspection_robot.lazy import lazy_import\n"
            "colorsys = lazy_import('colorsys')\nassert 'colorsys' not in sys.modules\n"
            "assert colorsys.rgb_to_hsv(1.0, 0.0, 0.0) == (0.0, 1.0, 1.0)\nassert 'colorsys' in sys.modules\n")
    assert_runs(code)


def test_attributes_and_errors_are_the_module_s():
    json = lazy_import("json")
    assert json.dumps([1]) == "[1]" and json.JSONDecodeError.__module__ == "json.decoder"
    assert "loads" in dir(json)
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        json.nope


def test_the_node_modules_that_read_pictures_load_without_cv2():
    code = ("import sys\nimport inspection_robot.inspection.reading, inspection_robot.inspection.finder, "
            "inspection_robot.thermal.commands, inspection_robot.camera.isapi, inspection_robot.camera.jpeg, "
            "inspection_robot.sim.camera\nassert 'cv2' not in sys.modules\n")
    assert_runs(code)
