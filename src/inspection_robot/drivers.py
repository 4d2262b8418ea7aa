"""One way to choose a device driver, the same for every device.

Every device node reads ``~driver`` (and, for a plug-in, ``~driver_params``) and hands it to
:func:`make_driver`. A ``~driver`` value is one of:

- ``sim``: the simulator (imported only when chosen: the node passes a builder that imports it);
- ``none``: the device is not fitted; every command answers failed with :func:`not_fitted_reason`;
- a built-in real driver name of that device (``BUILTIN``, e.g. ``isapi`` for the camera);
- ``package.module:Class``: a vendor plug-in, constructed as ``Class(**driver_params)``.

An empty value is refused: no device silently falls back to a simulator. robot.launch's site check
(inspection_robot.site.check, tools/check_site) refuses simulators and names every missing setting in
one message before any node starts. Pure module: no rospy.
"""
from collections import OrderedDict, namedtuple

from inspection_robot.plugin import load_class

SIM = "sim"
NONE = "none"
PARAM = "driver"
PARAMS_PARAM = "driver_params"

Device = namedtuple("Device", "node config builtin")
"""node: the node that drives it (its ``~driver``); config: the file holding the default;
builtin: built-in real driver names of this device."""

DEVICES = OrderedDict([
    ("chassis", Device("robot_control", "config/robot_control.yaml", ("ros",))),
    ("head", Device("cloud_terrace", "config/cloud_terrace.yaml", ("pelco",))),
    ("arm", Device("robot_arm", "config/robot_arm.yaml", ())),
    ("camera", Device("camera_node", "config/camera_node.yaml", ("isapi",))),
    ("thermal", Device("infrared_imager", "config/infrared_imager.yaml", ("isapi",))),
    ("sensor3d", Device("obstacle_detector", "config/obstacle_detector.yaml", ("pointcloud",))),
])

Choice = namedtuple("Choice", "kind name")
"""kind: SIM, NONE, "builtin" or "plugin"; name: the built-in name or the plug-in spec."""


class DriverConfigError(ValueError):
    """A ``~driver`` value that names no driver; the message says which values would."""


def not_fitted_reason(device):
    return "%s not fitted (driver: none)" % device


def not_fitted_class(interface, error, device, **overrides):
    """A subclass of the driver ``interface`` for a device that is not fitted: every public method
    raises ``error(not_fitted_reason(device))``, every property is False, ``close`` does nothing;
    ``overrides`` (name: function or value) replace members where the node needs a harmless answer."""
    reason = not_fitted_reason(device)

    def refuse(_self, *_args, **_kwargs):
        raise error(reason)

    members = {"reason": reason, "__doc__": "%s not fitted: every request fails with %r." % (device, reason)}
    for name, value in vars(interface).items():
        if name.startswith("_") or name == "close":
            continue
        if isinstance(value, property):
            members[name] = property(lambda _self: False)
        elif callable(value):
            members[name] = refuse
    members.update(overrides)
    return type("NotFitted" + interface.__name__, (interface,), members)


def choose(device, spec):
    """The Choice ``spec`` (a ``~driver`` value) makes for ``device``; DriverConfigError otherwise."""
    if device not in DEVICES:
        raise DriverConfigError("unknown device %r (one of %s)" % (device, ", ".join(DEVICES)))
    entry = DEVICES[device]
    spec = "" if spec is None else str(spec).strip()
    allowed = "sim, none, %s'package.module:Class'" % "".join("%s, " % b for b in entry.builtin)
    if not spec:
        raise DriverConfigError("%s/%s is not set (%s driver: %s); set it in %s or robot_config"
                                % (entry.node, PARAM, device, allowed, entry.config))
    if spec == SIM:
        return Choice(SIM, spec)
    if spec == NONE:
        return Choice(NONE, spec)
    if spec in entry.builtin:
        return Choice("builtin", spec)
    module, sep, cls = spec.partition(":")
    if sep and module and cls:
        return Choice("plugin", spec)
    raise DriverConfigError("%s/%s: %r is no %s driver (%s)" % (entry.node, PARAM, spec, device, allowed))


def make_driver(device, spec, builders, driver_params=None, not_fitted=None):
    """The driver ``spec`` chooses for ``device``.

    builders: {name: zero-argument callable} for ``sim`` and each built-in name this node can
    build (the callable imports what it needs, so a simulator is imported only when chosen).
    not_fitted: zero-argument callable building the device's not-fitted driver (for ``none``);
    without it ``none`` returns None and the node answers every command failed itself.
    A plug-in is ``Class(**driver_params)``.
    """
    choice = choose(device, spec)
    if choice.kind == NONE:
        return not_fitted() if not_fitted is not None else None
    if choice.kind == "plugin":
        return load_class(choice.name)(**dict(driver_params or {}))
    if choice.name not in builders:
        raise DriverConfigError("%s/%s: %s is not available for %s here"
                                % (DEVICES[device].node, PARAM, choice.name, device))
    return builders[choice.name]()
