"""Vendor driver plug-ins: ``~driver: "package.module:Class"`` names the class a node builds its
device driver from (robot_control's chassis, infrared_imager's thermal imager).
"""
import importlib


def load_class(spec):
    """Import ``"package.module:Class"`` and return the class; ValueError with the reason otherwise."""
    module_name, sep, class_name = str(spec).partition(":")
    if not sep or not module_name or not class_name:
        raise ValueError("driver must be 'package.module:Class', got %r" % (spec,))
    module = importlib.import_module(module_name)
    try:
        return getattr(module, class_name)
    except AttributeError:
        raise ValueError("%s has no class %s" % (module_name, class_name))
