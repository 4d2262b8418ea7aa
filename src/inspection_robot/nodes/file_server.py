"""file_server: the robot's stored files and preset calibration over the link (project extension).

Services:    file_control (ControlService): list | stat | read (storage.commands): captures, find
                 and result pictures, thermal frames, presets with their calibration, task results,
                 read in base64 chunks of at most ~max_chunk_bytes
             calibration_control (ControlService): get | mark_box | set_meter_type | set_zero |
                 set_full_scale | set_values | remove_target | clear_draft | apply | upload
                 (inspection.calibration_commands); at most 64 targets a preset and 1 MiB a request
                 (calibration_schema.MAX_TARGETS, MAX_REQUEST_BYTES: constants, not parameters)
Subscribes:  file_cmd, calibration_cmd (GeneralCmd): topic twins of the services
Publishes:   file_ack, calibration_ack (GeneralAck)
Parameters:  config/file_server.yaml: every setting, its default and meaning (read through ros.node.NodeSettings),
             and config/camera_optics.yaml (~camera_optics: zoom boxes of a calibration); data_root (namespace, the
             robot's state directory; under core.launch, like ~roots and ~preset_roots, fixed at launch and never
             re-read from the parameter server: ros/data_root.py)
Neither service is refused while the joystick holds the robot: nothing here moves it.
"""
import rospy

from inspection_robot.camera.optics import ZoomOptics
from inspection_robot.inspection.calibration_commands import CalibrationCommands
from inspection_robot.ros.data_root import data_root
from inspection_robot.ros.node import NodeSettings, init_node
from inspection_robot.ros.twin import CommandTwin
from inspection_robot.storage.commands import FileCommands

NODE_NAME = "file_server"


def main():
    init_node(NODE_NAME)
    settings = NodeSettings("file_server")
    root = data_root()
    # the folders it serves are fixed at launch like every data path (ros/data_root.py)
    roots = list(settings.fixed_list("~roots"))
    preset_roots = list(settings.fixed_list("~preset_roots"))
    optics_cfg = settings.get("~camera_optics")
    optics = ZoomOptics(optics_cfg["zoom_hfov_deg"], optics_cfg["width"], optics_cfg["height"])
    files = FileCommands(root, roots, int(settings.get("~max_chunk_bytes")),
                         int(settings.get("~max_list_entries")))
    calibration = CalibrationCommands(root, preset_roots, roots, optics)
    CommandTwin(files.table, "file_control", "file_cmd", "file_ack", NODE_NAME, busy_when_joystick=False,
                data_root=root)
    CommandTwin(calibration.table, "calibration_control", "calibration_cmd", "calibration_ack", NODE_NAME,
                busy_when_joystick=False, data_root=root)
    rospy.loginfo("%s: data root %s, readable %s" % (NODE_NAME, root, ", ".join(files.roots)))
    rospy.spin()
