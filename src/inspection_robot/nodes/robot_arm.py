"""robot_arm: the inspection arm (INTERFACE.md section 4, "Arm"; inspection_robot.arm.controller).

Services:    arm_control (ControlService): every arm command
             ~sim_control (ControlService), only with ~driver sim: cmd ``fault`` data reason
               ("" clears it): every arm call then fails with that reason
Subscribes:  arm_cmd (GeneralCmd), control_status (ControlStatus): joystick-busy rule
Publishes:   arm_ack (GeneralAck): replies to arm_cmd, and unprompted reports (trans_id 0,
               receiver "") when a recording or playback ends or fails
Parameters:  config/robot_arm.yaml: every setting, its default and meaning (read through ros.node.NodeSettings);
             ~driver is required (none answers every command failed "unsupported: arm not fitted (driver: none)");
             data_root (namespace)
"""
import os

import rospy

from inspection_robot.arm.controller import AXIS_NAMES, ArmController
from inspection_robot.arm.driver import Limits
from inspection_robot.command import CommandTable, failed
from inspection_robot.drivers import SIM, make_driver, not_fitted_reason
from inspection_robot.interface import ARM_COMMANDS, UNSUPPORTED
from inspection_robot.ros.node import NodeSettings, init_node
from inspection_robot.ros.twin import CommandTwin, serve_table
from inspection_robot.ros.data_root import data_root

NODE_NAME = "robot_arm"


def _limits(limits):
    """Limits from ``~limits`` (every axis given: the file's, merged under the parameter server's)."""
    return Limits(tuple(tuple(limits["position_mm"][n]) for n in AXIS_NAMES[0]),
                  tuple(tuple(limits["orientation_deg"][n]) for n in AXIS_NAMES[1]))


def _serve_sim_faults(arm):
    def set_fault(data):
        arm.fault = data or None
    return serve_table("~sim_control", CommandTable({"fault": set_fault}))


def main():
    init_node(NODE_NAME)
    settings = NodeSettings("robot_arm")
    driver_spec = settings.get("~driver")
    root = data_root()
    roots = settings.path_list("~trajectory_roots", root)
    default_file = settings.path("~default_trajectory", root)
    limits = _limits(settings.get("~limits"))
    sim = settings.get("~sim")
    for folder in roots:
        os.makedirs(folder, exist_ok=True)
    holder = {}

    def report(reply):
        rospy.loginfo("%s: %s: %s" % (NODE_NAME, reply.ack, reply.data))
        holder["twin"].publish_ack(reply)

    def simulator():
        from inspection_robot.sim.arm import SimArm
        arm = SimArm(limits, sim["linear_speed_mm_s"], sim["angular_speed_deg_s"])
        _serve_sim_faults(arm)
        return arm

    arm = make_driver("arm", driver_spec, {SIM: simulator}, settings.get("~driver_params"))
    if arm is None:  # driver: none
        reason = "%s: %s" % (UNSUPPORTED, not_fitted_reason("arm"))
        table = CommandTable({name: (lambda data: failed(reason)) for name in ARM_COMMANDS})
    else:
        controller = ArmController(arm, roots, default_file,
                                   record_rate_hz=float(settings.get("~record_rate")),
                                   move_timeout=float(settings.get("~move_timeout")),
                                   tolerance_mm=float(settings.get("~tolerance_mm")),
                                   tolerance_deg=float(settings.get("~tolerance_deg")),
                                   max_record_s=float(settings.get("~max_record_s")),
                                   report=report)
        table = controller.table()
        rospy.on_shutdown(controller.shutdown)
    holder["twin"] = CommandTwin(table, "arm_control", "arm_cmd", "arm_ack", NODE_NAME, data_root=root)
    rospy.spin()
