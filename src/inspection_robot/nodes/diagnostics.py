"""Device health on ``diagnostics`` for the device nodes (camera_node, infrared_imager, cloud_terrace).

status_control turns the level of each status into a sensor_status bit by its hardware_id
(ERROR sets the bit), so every device node reports the same way: one status per tick, OK or ERROR.
"""
import traceback

import rospy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue


class DiagnosticsPublisher(object):
    """Publishes one device's status (``name``, ``hardware_id``) on the relative ``diagnostics`` topic."""

    def __init__(self, name, hardware_id):
        self.name = name
        self.hardware_id = hardware_id
        self._pub = rospy.Publisher("diagnostics", DiagnosticArray, queue_size=10)

    def publish(self, ok, message, values):
        """``values``: (key, value) pairs, written with str()."""
        status = DiagnosticStatus(name=self.name, hardware_id=self.hardware_id,
                                  level=DiagnosticStatus.OK if ok else DiagnosticStatus.ERROR, message=message,
                                  values=[KeyValue(str(k), str(v)) for k, v in values])
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = rospy.Time.now()
        self._pub.publish(msg)


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
