"""find_scale: finds a preset's meters again (INTERFACE.md section 4, "Meter finding").

Actions:     find_scale_action (inspection_robot/GeneralAction), server. Goal type pre_find |
             find_scale | find_foreign | find_both, data JSON {"preset_path": dir}. Feedback
             event_code "0" preset set, "1" finding. Result ret_code "0" with data {"filename",
             "infrared_filename", "foreign_filename", "roi_vertex", "infrared_roi_vertex",
             "second_filename" (the second look of a preset with a pointer, else "")} or "1"
             with {"reason"}; a cancelled goal is preempted with ret_code "1", reason "cancelled".
Subscribes:  nav_status (NavStatus): current heading for the pan correction
             terrace_state (sensor_msgs/JointState): after each set_angle, waits (<= 2 s) until the head
             reports the new angle, so the next picture is taken from the new view
Services:    terrace_control, camera_control, infrared_control (ControlService), client
Parameters:  config/find_scale.yaml: every setting, its default and meaning (read through ros.node.NodeSettings),
             and config/camera_optics.yaml (~camera_optics: zoom -> field of view); data_root (namespace, the
             robot's state directory)
"""
import json
import math
import os
import time
import traceback

import actionlib
import rospy

from inspection_robot.lazy import lazy_import
from inspection_robot.camera.optics import ZoomOptics, focal_for_hfov
from inspection_robot.command import CommandError
from inspection_robot.files import hide_root
from inspection_robot.inspection.finder import Cancelled, Finder, FindError, ThermalGeometry
from inspection_robot.inspection.locate import Locator
from inspection_robot.inspection.preset import PresetError, load_preset
from inspection_robot.inspection.find_goal import find_result_data, parse_find_goal, reason_data
from inspection_robot.interface import (FIND_FEEDBACK_PRESET_SET, FIND_GOAL_PRE_FIND, FIND_RESULT_FAILED,
                                        FIND_RESULT_SUCCESS)
from inspection_robot.msg import GeneralAction, GeneralFeedback, GeneralResult
from inspection_robot.inspection.ros_head import HeadingWatcher, RosHead
from inspection_robot.ros.data_root import data_root
from inspection_robot.ros.node import NodeSettings, init_node

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load

NODE_NAME = "find_scale"


class FindScaleNode(object):
    def __init__(self, finder, head, heading, preset_root, data_root):
        self._finder = finder
        self._head = head
        self._heading = heading
        self._preset_root = preset_root
        self._data_root = data_root   # taken out of every refusal (files.hide_root)
        finder.is_cancelled = self._cancel_requested
        finder.feedback = self._feedback
        self._server = actionlib.SimpleActionServer("find_scale_action", GeneralAction, self._execute,
                                                    auto_start=False)
        self._server.start()

    def _cancel_requested(self):
        return self._server.is_preempt_requested() or rospy.is_shutdown()

    def _feedback(self, code, data):
        self._server.publish_feedback(GeneralFeedback(event_code=code, data=json.dumps(data)))

    def _execute(self, goal):
        try:
            data = self._run(goal)
        except Cancelled:
            rospy.loginfo("find_scale: goal cancelled")
            self._server.set_preempted(GeneralResult(ret_code=FIND_RESULT_FAILED,
                                                     data=reason_data("cancelled")))
            return
        except (CommandError, PresetError, FindError) as err:
            self._fail(str(err))
            return
        except Exception as err:  # boundary: the goal always ends in a terminal state
            rospy.logerr("find_scale: %s\n%s" % (err, traceback.format_exc()))
            self._fail("internal error: %s" % err)
            return
        self._server.set_succeeded(GeneralResult(ret_code=FIND_RESULT_SUCCESS, data=data))

    def _fail(self, reason):
        rospy.logwarn("find_scale: failed: %s" % reason)
        self._server.set_aborted(GeneralResult(ret_code=FIND_RESULT_FAILED,
                                               data=reason_data(hide_root(reason, self._data_root))))

    def _run(self, goal):
        kind, path = parse_find_goal(goal.type, goal.data, [self._preset_root])
        preset = load_preset(path, need_calibration=kind != FIND_GOAL_PRE_FIND)
        self._head.hide_osd()
        if kind == FIND_GOAL_PRE_FIND:
            pan, tilt = self._finder.restore(preset, 0.0)
            self._feedback(FIND_FEEDBACK_PRESET_SET, {"pan": round(pan, 2), "tilt": round(tilt, 2),
                                                      "zoom": preset.info.zoom_levels[0]})
            return find_result_data()
        pose = self._heading.latest()
        if pose is None:
            rospy.logwarn("find_scale: no nav_status yet; restoring the pan without heading correction")
            correction = 0.0
        else:
            correction = math.degrees(preset.info.pose[2] - pose[2])
        # feedback "0" (preset set, with the correction) comes from the finder, then "1" per picture
        result = self._finder.find(preset, kind, correction, time.strftime("%Y%m%d_%H%M%S"), cv2.imread)
        return find_result_data(result.filename, result.infrared_filename, result.foreign_filename,
                                result.roi_vertex, result.infrared_roi_vertex, result.second_filename)


def main():
    init_node(NODE_NAME)
    settings = NodeSettings("find_scale")
    root = data_root()
    preset_root = settings.path("~preset_root", root)
    picture_root = settings.path("~picture_root", root)
    optics_cfg = settings.get("~camera_optics")
    optics = ZoomOptics(optics_cfg["zoom_hfov_deg"], optics_cfg["width"], optics_cfg["height"])
    hfov = float(settings.get("~thermal_hfov_deg"))
    t_width, t_height = int(settings.get("~thermal_width")), int(settings.get("~thermal_height"))
    offset = [float(v) for v in settings.get("~thermal_offset_px")]
    if len(offset) != 2:
        raise ValueError("~thermal_offset_px must be [dx, dy]")
    if not 0.0 < hfov < 180.0 or t_width <= 0 or t_height <= 0:
        raise ValueError("~thermal_hfov_deg must be in (0, 180) and ~thermal_width/~thermal_height positive")
    service_timeout = float(settings.get("~service_timeout"))
    max_moves = int(settings.get("~max_moves"))
    centre_tolerance = float(settings.get("~centre_tolerance"))
    if service_timeout <= 0 or max_moves < 0 or not 0.0 < centre_tolerance < 1.0:
        raise ValueError("~service_timeout must be > 0, ~max_moves >= 0 and 0 < ~centre_tolerance < 1")
    thermal = ThermalGeometry(focal_for_hfov(t_width, hfov), t_width, t_height, offset)
    head = RosHead(NODE_NAME, service_timeout)
    finder = Finder(head, optics, Locator(settings.get("~detector")), picture_root,
                    max_moves=max_moves, centre_tolerance=centre_tolerance, thermal=thermal)
    for folder in (preset_root, picture_root):
        os.makedirs(folder, exist_ok=True)
    FindScaleNode(finder, head, HeadingWatcher(), preset_root, root)
    rospy.spin()
