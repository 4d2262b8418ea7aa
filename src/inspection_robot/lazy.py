"""Modules imported on first use, so a (re)spawned node registers with the master before paying for them.

Debian's and Ubuntu's python3-opencv link about 360 shared libraries: importing cv2 is most of a
node's start-up CPU (0.7 s on an idle core, several seconds on a loaded robot), and a node killed
under load was off the graph for up to 15 s while it re-imported cv2 before ``init_node``. Modules
that need cv2 (or scipy) only inside functions hold a :class:`LazyModule` instead: the real import
happens at the first attribute access (the first picture read, the first costmap built), after the
node has registered its topics and services.

    cv2 = lazy_import("cv2")     # at module level, in place of ``import cv2``
"""
import importlib
import threading
import types


class LazyModule(types.ModuleType):
    """Stands for module ``name`` until an attribute is read; then imports it and takes its attributes."""

    def __init__(self, name):
        super(LazyModule, self).__init__(name)
        self.__dict__["_lazy_lock"] = threading.Lock()

    def __getattr__(self, attr):   # called only for attributes not yet copied in
        with self.__dict__["_lazy_lock"]:
            module = importlib.import_module(self.__name__)
            self.__dict__.update(vars(module))
        try:
            return self.__dict__[attr]
        except KeyError:
            raise AttributeError("module %r has no attribute %r" % (self.__name__, attr))

    def __dir__(self):
        return dir(importlib.import_module(self.__name__))


def lazy_import(name):
    """A :class:`LazyModule` for ``name`` (dotted names too: ``lazy_import("scipy.sparse.csgraph")``)."""
    return LazyModule(name)
