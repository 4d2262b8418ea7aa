"""inspection_robot.version: the build's git describe, from the file the build generated (never
from git at run time); a bare source tree says so."""
import os
import subprocess
import sys

from inspection_robot import version as version_module

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def test_built_version_is_the_checkouts_git_describe():
    found = version_module.version()
    if found == version_module.UNKNOWN:
        import pytest
        pytest.skip("not run inside a catkin build (scripts/rosenv)")
    # a build older than the checkout's HEAD is fine: the version must name a commit of this repository
    commit = found.replace("-dirty", "").rsplit("-g", 1)[-1]
    known = subprocess.run(["git", "cat-file", "-e", commit + "^{commit}"], cwd=ROOT)
    assert known.returncode == 0, found


def test_bare_source_tree_says_unknown(tmp_path):
    code = ("import sys; sys.path.insert(0, %r); from inspection_robot.version import version; print(version())"
            % os.path.join(ROOT, "src"))
    out = subprocess.run([sys.executable, "-c", code], stdout=subprocess.PIPE, universal_newlines=True,
                         env={"PATH": os.environ.get("PATH", "")}, cwd=str(tmp_path))
    assert out.stdout.strip() == version_module.UNKNOWN
