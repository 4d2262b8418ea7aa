"""inspection_robot.drivers: one way to choose a driver for every device."""
import sys

import pytest

from inspection_robot.camera.driver import CameraError, NoCamera
from inspection_robot.drivers import DEVICES, DriverConfigError, choose, make_driver, not_fitted_reason
from inspection_robot.motion.chassis import ChassisError, ChassisState, NoChassis
from inspection_robot.ptz.driver import HeadError, NoHead
from inspection_robot.thermal.driver import NoImager, ThermalError


class FakeDriver(object):
    def __init__(self, port="x", baud=9600):
        self.port, self.baud = port, baud


@pytest.mark.parametrize("device", list(DEVICES))
def test_same_choices_for_every_device(device):
    assert choose(device, "sim").kind == "sim"
    assert choose(device, "none").kind == "none"
    assert choose(device, "vendor.module:Class") == ("plugin", "vendor.module:Class")
    for name in DEVICES[device].builtin:
        assert choose(device, name) == ("builtin", name)


@pytest.mark.parametrize("spec", ["", None, "  "])
def test_unset_driver_names_the_setting_and_file(spec):
    with pytest.raises(DriverConfigError) as err:
        choose("chassis", spec)
    assert "robot_control/driver is not set" in str(err.value)
    assert "config/robot_control.yaml" in str(err.value)


def test_unknown_driver_lists_what_would_do():
    with pytest.raises(DriverConfigError) as err:
        choose("camera", "hikvision")
    assert "'hikvision' is no camera driver (sim, none, isapi, 'package.module:Class')" in str(err.value)
    with pytest.raises(DriverConfigError):
        choose("toaster", "sim")


def test_simulator_built_only_when_chosen():
    sys.modules.pop("inspection_robot.sim.chassis", None)
    calls = []
    driver = make_driver("chassis", "none", {"sim": lambda: calls.append("sim")}, not_fitted=NoChassis)
    assert isinstance(driver, NoChassis) and calls == []
    assert "inspection_robot.sim.chassis" not in sys.modules
    assert make_driver("chassis", "sim", {"sim": lambda: "the simulator"}) == "the simulator"


def test_plugin_built_with_driver_params():
    driver = make_driver("head", "test_drivers:FakeDriver", {}, {"port": "/dev/ttyS1"})
    assert (type(driver).__name__, driver.port, driver.baud) == ("FakeDriver", "/dev/ttyS1", 9600)


def test_builtin_without_builder_refused():
    with pytest.raises(DriverConfigError) as err:
        make_driver("camera", "isapi", {"sim": lambda: None})
    assert "isapi is not available for camera" in str(err.value)


def test_none_without_not_fitted_driver_is_none():
    assert make_driver("arm", "none", {}) is None


def test_not_fitted_drivers_fail_with_the_reason():
    chassis = NoChassis()
    chassis.set_safety_listener(lambda: None)
    chassis.send_velocity(0.0, 0.0, 0)
    chassis.stop()
    assert chassis.state() == ChassisState()
    with pytest.raises(ChassisError, match="chassis not fitted"):
        chassis.send_velocity(0.1, 0.0, 0)
    chassis.set_lamps(True, False, False)   # none to light: robot_control's control cycle sets them
    with pytest.raises(ChassisError, match=r"chassis not fitted \(driver: none\)"):
        chassis.set_charge_relay(True)
    head = NoHead()
    head.stop()
    assert head.connected is False and head.last_error == not_fitted_reason("head")
    with pytest.raises(HeadError, match="head not fitted"):
        head.set_pan(100)
    with pytest.raises(CameraError, match="camera not fitted"):
        NoCamera().get_zoom()
    with pytest.raises(ThermalError, match="thermal not fitted"):
        NoImager().frame()
