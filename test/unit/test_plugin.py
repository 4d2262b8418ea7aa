"""inspection_robot.plugin: the one "package.module:Class" loader of vendor drivers."""
import pytest

from inspection_robot.plugin import load_class
from inspection_robot.thermal.driver import NoImager


def test_loads_the_named_class():
    assert load_class("inspection_robot.thermal.driver:NoImager") is NoImager


@pytest.mark.parametrize("spec", ["", "inspection_robot.thermal.driver", ":NoImager",
                                  "inspection_robot.thermal.driver:"])
def test_malformed_spec_is_refused(spec):
    with pytest.raises(ValueError, match="package.module:Class"):
        load_class(spec)


def test_missing_class_is_refused():
    with pytest.raises(ValueError, match="has no class Nope"):
        load_class("inspection_robot.thermal.driver:Nope")
