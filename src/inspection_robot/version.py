"""The software version (``git describe``), captured when the package is built or installed.

CMakeLists.txt runs cmake/version.cmake at every build: it writes ``build_version.py`` (VERSION)
into the package's Python folder of the devel space, and ``catkin_make install`` installs it. The
IPC may run an install space with no git checkout, so the version is never asked of git at run
time. robot_status diagnostics (status_control) and every patrol report carry it.
"""
UNKNOWN = "unknown (not built with catkin)"


def version():
    """``git describe --tags --always --dirty`` of the build, or UNKNOWN from a bare source tree."""
    try:
        from inspection_robot.build_version import VERSION  # generated at build time
    except ImportError:
        return UNKNOWN
    return VERSION
