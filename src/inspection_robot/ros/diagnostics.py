"""Device health on ``diagnostics`` for the device nodes (camera_node, infrared_imager, cloud_terrace),
through diagnostic_updater.

status_control turns the level of each status into a sensor_status bit by its hardware_id
(ERROR sets the bit), so every device node reports the same way: one status per tick, OK or ERROR.
diagnostic_updater publishes on the absolute ``/diagnostics``; core.launch remaps it to the
robot's namespace so that status_control hears its own robot's devices only.
"""
import traceback

import diagnostic_updater
import rospy
from diagnostic_msgs.msg import DiagnosticStatus


class DeviceStatusTask(diagnostic_updater.DiagnosticTask):
    """The device's last known health: OK or ERROR, a message, and (key, value) details."""

    def __init__(self, name):
        diagnostic_updater.DiagnosticTask.__init__(self, name)
        self._state = (False, "no status yet", ())

    def set(self, ok, message, values):
        self._state = (ok, message, tuple(values))

    def run(self, stat):
        ok, message, values = self._state
        stat.summary(DiagnosticStatus.OK if ok else DiagnosticStatus.ERROR, message)
        for key, value in values:
            stat.add(str(key), str(value))
        return stat


class DeviceDiagnostics(object):
    """One device's diagnostic_updater.Updater (hardware_id set) with its DeviceStatusTask.

    ``publish`` records the node's latest verdict and sends it at once, so the status keeps the
    rate of the node's own status timer; ``add`` attaches further tasks (e.g. a FrequencyStatus).
    """

    def __init__(self, task_name, hardware_id):
        self._updater = diagnostic_updater.Updater()
        self._updater.setHardwareID(hardware_id)
        self._status = DeviceStatusTask(task_name)
        self._updater.add(self._status)

    def add(self, task):
        self._updater.add(task)

    def publish(self, ok, message, values):
        """``values``: (key, value) pairs, written with str()."""
        self._status.set(ok, message, values)
        self._updater.force_update()


def probe_device(node_name, health, probe, device_errors):
    """Call ``probe()`` on a status tick and record the outcome in ``health`` (camera.driver.DeviceHealth).

    Returns ``(True, probe's result)`` or ``(False, None)``. A device error (``device_errors``) is
    logged throttled; anything else is a bug met at the timer boundary: logged with its traceback,
    counted as a failure, and the tick survives.
    """
    try:
        result = probe()
    except device_errors as err:
        health.failure(err)
        rospy.logwarn_throttle(10.0, "%s: %s" % (node_name, err))
        return False, None
    except Exception as err:  # boundary: a timer tick must not die
        health.failure("internal error: %s" % err)
        rospy.logerr_throttle(10.0, "%s: status tick failed: %s\n%s" % (node_name, err, traceback.format_exc()))
        return False, None
    health.success()
    return True, result
