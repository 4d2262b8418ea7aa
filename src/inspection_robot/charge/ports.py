"""What charge_control's state machine takes in and acts through: the Battery it reads from a
robot_status message, its ChargeConfig (validated), and ChargePorts, the outside world the node
implements and the tests record.

Apart from machine.py so that the machine's boundary reads on its own: this is what the node has to
provide (docs/interface.md, "Charging (charge_control)"). No rospy: the message is only read.
"""
from collections import namedtuple

from inspection_robot.interface import BATTERY_CHARGING, LIGHT_CHARGE_RELAY
from inspection_robot.status.merge import STALE_CONTROL_STATUS, STALE_NAV_STATUS

Battery = namedtuple("Battery", "quantity charging relay mode pose")
ChargeConfig = namedtuple("ChargeConfig", "low_level full_level retries pause_timeout relay_timeout "
                                          "current_timeout current_lost_timeout status_timeout")


def battery_from_robot_status(msg):
    """The Battery a robot_status message reports, or None while its control_status input is stale
    (status_control then repeats old values, or zeros before robot_control's first message).
    The pose is None while nav_status is stale or has no position."""
    other = msg.other_status[0] if len(msg.other_status) else 0
    if other & STALE_CONTROL_STATUS:
        return None
    pose = None
    if len(msg.position) >= 2 and not other & STALE_NAV_STATUS:
        pose = (msg.position[0], msg.position[1], msg.orientation)
    return Battery(msg.battery_quantity, bool(msg.battery_status & BATTERY_CHARGING),
                   bool(msg.light_status & LIGHT_CHARGE_RELAY), msg.mode, pose)


def validate_config(config):
    """Raise ValueError naming the first inconsistent parameter of a ChargeConfig."""
    if not 0 <= config.low_level < config.full_level <= 100:
        raise ValueError("need 0 <= low_level < full_level <= 100, got %s and %s"
                         % (config.low_level, config.full_level))
    if config.retries < 0 or int(config.retries) != config.retries:
        raise ValueError("retries must be a whole number >= 0, got %s" % (config.retries,))
    for name in ("pause_timeout", "relay_timeout", "current_timeout", "current_lost_timeout", "status_timeout"):
        if not getattr(config, name) > 0:
            raise ValueError("%s must be positive, got %s" % (name, getattr(config, name)))
    return config


class ChargePorts(object):
    """What the machine asks of the outside world; the node implements it, tests record it."""

    def task(self, token, cmd):
        """Send task_control ``cmd`` (pause|resume) with data "charge"; answer with
        ``on_task_reply(token, ok, data)``, ok None when task_manager is not running."""
        raise NotImplementedError

    def goal(self, token, pose, precision, backward):
        """Send a move_action goal to ``pose`` (x, y, yaw); answer ``on_move_result(token, ok, reason)``,
        ok None when the goal could not be sent because move_action's server is not up."""
        raise NotImplementedError

    def cancel_goal(self):
        raise NotImplementedError

    def relay(self, closed):
        """control_cmd enable_charge (True) or disable_charge (False)."""
        raise NotImplementedError

    def alarm(self, reason, clips):
        """Report a failure that retries did not cure: alarm topic and voice prompt ``clips``."""
        raise NotImplementedError

    def speak(self, clips):
        raise NotImplementedError

    def warn(self, text):
        """A throttled log warning (recoverable trouble, e.g. a retry or a missing task_manager)."""
        raise NotImplementedError

    def status(self, status):
        """Publish the status dict (called only when it changed)."""
        raise NotImplementedError
