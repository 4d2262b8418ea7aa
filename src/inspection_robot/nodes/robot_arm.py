"""robot_arm: the inspection arm (INTERFACE.md section 4, "Arm"; inspection_robot.arm.controller).

Services:    arm_control (ControlService): every arm command
             ~sim_control (ControlService), only with ~driver sim: cmd ``fault`` data reason
               ("" clears it): every arm call then fails with that reason
Subscribes:  arm_cmd (GeneralCmd), control_status (ControlStatus): joystick-busy rule
Publishes:   arm_ack (GeneralAck): replies to arm_cmd, and unprompted reports (trans_id 0,
               receiver "") when a recording or playback ends or fails
Parameters:  ~driver (sim | none | "package.module:Class" with ~driver_params, required; none answers
               every command failed "unsupported: arm not fitted (driver: none)"),
             data_root (namespace), ~trajectory_roots ([arm], under data_root unless absolute): where
             trajectory files may live, ~default_trajectory ("arm/default_orbit.csv"),
             ~record_rate (Hz, 20.0), ~move_timeout (s, 20.0), ~tolerance_mm (0.5),
             ~tolerance_deg (0.5), ~max_record_s (s, 600.0),
             ~limits/position_mm ({x: [-600, 600], y: [-600, 600], z: [-200, 800]}),
             ~limits/orientation_deg ({roll: [-180, 180], pitch: [-90, 90], yaw: [-180, 180]}),
             ~sim/linear_speed_mm_s (200.0), ~sim/angular_speed_deg_s (90.0)
"""
import os

import rospy

from inspection_robot.arm.controller import AXIS_NAMES, ArmController
from inspection_robot.arm.driver import Limits
from inspection_robot.command import CommandTable, failed
from inspection_robot.drivers import SIM, make_driver, not_fitted_reason
from inspection_robot.interface import ARM_COMMANDS, UNSUPPORTED
from inspection_robot.ros.node import init_node
from inspection_robot.ros.twin import CommandTwin, serve_table
from inspection_robot.ros.data_root import data_root, path_list_param, path_param

NODE_NAME = "robot_arm"
DEFAULT_LIMITS = {"position_mm": {"x": [-600, 600], "y": [-600, 600], "z": [-200, 800]},
                  "orientation_deg": {"roll": [-180, 180], "pitch": [-90, 90], "yaw": [-180, 180]}}


def _limits(param):
    merged = {key: dict(DEFAULT_LIMITS[key], **param.get(key, {})) for key in DEFAULT_LIMITS}
    return Limits(tuple(tuple(merged["position_mm"][n]) for n in AXIS_NAMES[0]),
                  tuple(tuple(merged["orientation_deg"][n]) for n in AXIS_NAMES[1]))


def _serve_sim_faults(arm):
    def set_fault(data):
        arm.fault = data or None
    return serve_table("~sim_control", CommandTable({"fault": set_fault}))


def main():
    init_node(NODE_NAME)
    driver_spec = rospy.get_param("~driver", "")
    root = data_root()
    roots = path_list_param("~trajectory_roots", ["arm"], root)
    default_file = path_param("~default_trajectory", "arm/default_orbit.csv", root)
    limits = _limits(rospy.get_param("~limits", {}))
    sim = rospy.get_param("~sim", {})
    for folder in roots:
        os.makedirs(folder, exist_ok=True)
    holder = {}

    def report(reply):
        rospy.loginfo("%s: %s: %s" % (NODE_NAME, reply.ack, reply.data))
        holder["twin"].publish_ack(reply)

    def simulator():
        from inspection_robot.sim.arm import SimArm
        arm = SimArm(limits, sim.get("linear_speed_mm_s", 200.0), sim.get("angular_speed_deg_s", 90.0))
        _serve_sim_faults(arm)
        return arm

    arm = make_driver("arm", driver_spec, {SIM: simulator}, rospy.get_param("~driver_params", {}))
    if arm is None:  # driver: none
        reason = "%s: %s" % (UNSUPPORTED, not_fitted_reason("arm"))
        table = CommandTable({name: (lambda data: failed(reason)) for name in ARM_COMMANDS})
    else:
        controller = ArmController(arm, roots, default_file,
                                   record_rate_hz=float(rospy.get_param("~record_rate", 20.0)),
                                   move_timeout=float(rospy.get_param("~move_timeout", 20.0)),
                                   tolerance_mm=float(rospy.get_param("~tolerance_mm", 0.5)),
                                   tolerance_deg=float(rospy.get_param("~tolerance_deg", 0.5)),
                                   max_record_s=float(rospy.get_param("~max_record_s", 600.0)),
                                   report=report)
        table = controller.table()
        rospy.on_shutdown(controller.shutdown)
    holder["twin"] = CommandTwin(table, "arm_control", "arm_cmd", "arm_ack", NODE_NAME, data_root=root)
    rospy.spin()
