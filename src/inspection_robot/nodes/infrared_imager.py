"""infrared_imager: the radiometric thermal imager (INTERFACE.md section 4, "Thermal imager").

Services:    infrared_control (ControlService): every command of the spec (thermal.commands)
             infrared_staging (ControlService): capture_picture, save_temperature under a fresh staged name
                 (.staging/<32 hex>.<ext>) for preset_scale and find_scale only: not in the backend surface
Subscribes:  infrared_cmd (GeneralCmd) -> answers on infrared_ack (GeneralAck), trans_id echoed
             control_status (ControlStatus): joystick-busy rule (mode 2)
             sim only: sim/true_pose, terrace_state, sim/world_state (sim/ros_view.py)
Publishes:   diagnostics (diagnostic_msgs/DiagnosticArray, hardware_id "thermal_imager", ~status_rate Hz)
             thermal/image_raw (sensor_msgs/Image, bgr8 false colour, ~image_rate Hz, only with subscribers)
             thermal/image_raw/compressed (sensor_msgs/CompressedImage, format "jpeg", ~stream_jpeg_quality,
             the same frames, only with subscribers)
             thermal/hottest (GeneralTopic, JSON {"x", "y", "temperature"} of the same frame)
Parameters:  ~driver (sim | isapi | none | vendor plug-in "package.module:Class", required; none = not fitted:
             every command fails "thermal not fitted (driver: none)" and diagnostics report ERROR),
             ~driver_params (dict of keyword arguments for a plug-in, {}),
             ~width, ~height (px, 384, 288), ~roots (under data_root unless absolute, [thermal];
             a root overlapping presets, pictures, tasks ... is refused at start: files.capture_roots),
             ~quota_mib (MiB the roots may hold, hidden files included, 2048 = 2 GiB; 0 = none:
             files.CaptureQuota),
             ~measure_box_px (px, 16), ~status_rate (Hz, 1.0), ~image_rate (Hz, 1.0), ~jpeg_quality (captures, 90),
             ~stream_jpeg_quality (0..100, 80),
             ~isapi/{host (required for isapi), port (80), user ("admin"), password_file (required for
             isapi: file holding the password, mode 600), channel (2), timeout (s, 2.0),
             picture_timeout (s, 5.0)} (Hikvision thermographic camera, thermal.isapi),
             ~sim/{world_file (required for sim), seed (0), noise_sigma (degC, 0.05), hfov_deg (25.0),
             unsupported (list of commands to refuse, [])}
"""
import json

import rospy

from inspection_robot.camera.driver import DeviceHealth
from inspection_robot.camera.jpeg import check_quality
from inspection_robot.command import CommandError
from inspection_robot.msg import GeneralTopic
from inspection_robot.drivers import SIM, make_driver
from inspection_robot.ros.diagnostics import DeviceDiagnostics, probe_device
from inspection_robot.ros.images import LiveViewPublisher
from inspection_robot.ros.node import init_node
from inspection_robot.interface import INFRARED_STAGING_SERVICE
from inspection_robot.ros.twin import CommandTwin
from inspection_robot.thermal.commands import ThermalCommands
from inspection_robot.thermal.driver import NoImager, ThermalError
from inspection_robot.files import DEFAULT_CAPTURE_QUOTA_MIB, CaptureQuota, capture_roots
from inspection_robot.ros.data_root import data_root, path_list_param

NODE = "infrared_imager"
HARDWARE_ID = "thermal_imager"


class InfraredNode(object):
    def __init__(self, driver, commands, health, status_rate, image_rate, stream_quality, data_root):
        self._driver = driver
        self._health = health
        self.commands = commands
        self._diagnostics = DeviceDiagnostics("thermal imager", HARDWARE_ID)
        self._twin = CommandTwin(commands.table, "infrared_control", "infrared_cmd", "infrared_ack", NODE,
                                 staging=(commands.staging_table, INFRARED_STAGING_SERVICE), data_root=data_root)
        self._timer = rospy.Timer(rospy.Duration(1.0 / status_rate), self._on_status)
        self._live = LiveViewPublisher("thermal/image_raw", stream_quality)
        self._hottest_pub = rospy.Publisher("thermal/hottest", GeneralTopic, queue_size=1)
        self._image_timer = rospy.Timer(rospy.Duration(1.0 / image_rate), self._on_image)

    def _on_image(self, _event):
        if not self._live.wanted() and self._hottest_pub.get_num_connections() == 0:
            return   # nobody watches: no frame grabbed
        try:
            picture, hottest = self.commands.live_view()
        except CommandError as err:
            rospy.logwarn_throttle(10.0, "%s: no live thermal view: %s" % (NODE, err))
            return
        stamp = rospy.Time.now()
        self._live.publish(picture, stamp, "thermal_imager")
        msg = GeneralTopic(sender=NODE, data=json.dumps(hottest, sort_keys=True))
        msg.header.stamp = stamp
        self._hottest_pub.publish(msg)

    def _on_status(self, _event):
        probe_device(NODE, self._health, self._driver.probe, ThermalError)
        x, y = self.commands.measure_spot
        self._diagnostics.publish(self._health.ok, self._health.message,
                                  [("measure_spot", "%d,%d" % (x, y)), ("failures", self._health.failures)])


def make_imager(spec, width, height):
    def isapi():
        from inspection_robot.thermal.isapi import imager_from_settings
        return imager_from_settings(rospy.get_param("~isapi", {}))

    def simulator():
        from inspection_robot.sim.ros_view import SimView
        from inspection_robot.sim.render import ThermalRenderer
        from inspection_robot.sim.thermal import SimulatedImager
        from inspection_robot.sim.world import World
        params = rospy.get_param("~sim", {})
        world = World.load(params["world_file"])
        renderer = ThermalRenderer(world, int(params.get("seed", 0)), float(params.get("noise_sigma", 0.05)))
        return SimulatedImager(renderer, SimView(world), world.sensor_height, width, height,
                               float(params.get("hfov_deg", 25.0)), list(params.get("unsupported", [])))

    return make_driver("thermal", spec, {"isapi": isapi, SIM: simulator}, rospy.get_param("~driver_params", {}),
                       NoImager)


def main():
    init_node(NODE)
    width = int(rospy.get_param("~width", 384))
    height = int(rospy.get_param("~height", 288))
    status_rate = float(rospy.get_param("~status_rate", 1.0))
    image_rate = float(rospy.get_param("~image_rate", 1.0))
    if width < 8 or height < 8 or status_rate <= 0 or image_rate <= 0:
        raise ValueError("~width/~height must be >= 8 px, ~status_rate and ~image_rate > 0")
    driver = make_imager(rospy.get_param("~driver", ""), width, height)
    health = DeviceHealth()
    root = data_root()
    roots = capture_roots(path_list_param("~roots", ["thermal"], root), root)
    commands = ThermalCommands(driver, roots, health, width, height,
                               int(rospy.get_param("~measure_box_px", 16)), int(rospy.get_param("~jpeg_quality", 90)),
                               CaptureQuota.from_mib(roots, rospy.get_param("~quota_mib", DEFAULT_CAPTURE_QUOTA_MIB)))
    InfraredNode(driver, commands, health, status_rate, image_rate,
                 check_quality(rospy.get_param("~stream_jpeg_quality", 80)), root)
    rospy.spin()
