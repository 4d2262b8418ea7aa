"""scripts/check_tests.py: test functions that cannot fail are named; helpers that assert count."""
import os
import subprocess
import sys

SCRIPT = os.path.join(os.path.dirname(__file__), "..", "..", "scripts", "check_tests.py")


def run(tmp_path, source):
    path = tmp_path / "test_sample.py"
    path.write_text(source)
    result = subprocess.run([sys.executable, SCRIPT, str(path)], stdout=subprocess.PIPE, universal_newlines=True)
    return result.returncode, result.stdout


def test_a_test_without_assertion_is_named(tmp_path):
    code, out = run(tmp_path, "def test_quiet():\n    total = sum([1, 2])\n\n\n"
                              "def test_loud():\n    assert sum([1, 2]) == 3\n")
    assert code == 1 and out.endswith("test_sample.py:1: test_quiet has no assertion, expected exception or "
                                      "asserting helper\n") and "test_loud" not in out


def test_helpers_exceptions_and_unittest_methods_count(tmp_path):
    code, out = run(tmp_path, "import pytest\n\n\ndef check(x):\n    if x:\n        raise AssertionError(x)\n\n\n"
                              "def via(x):\n    check(x)\n\n\ndef test_helper():\n    via(0)\n\n\n"
                              "def test_raises():\n    with pytest.raises(ZeroDivisionError):\n        1 / 0\n\n\n"
                              "class T:\n    def test_method(self):\n        self.assertEqual(1, 1)\n")
    assert (code, out) == (0, "")
