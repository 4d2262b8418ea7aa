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
Parameters:  config/infrared_imager.yaml: every setting, its default and meaning (read through
             ros.node.NodeSettings); ~driver is required (none = not fitted: every command fails "thermal not fitted
             (driver: none)" and diagnostics report ERROR), ~isapi/host and ~isapi/password_file with driver isapi,
             ~sim/world_file with driver sim (the launch sets it); a ~roots entry overlapping presets, pictures,
             tasks ... is refused at start (data_layout.capture_roots); data_root (namespace)
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
from inspection_robot.ros.node import NodeSettings, init_node
from inspection_robot.interface import INFRARED_STAGING_SERVICE
from inspection_robot.ros.twin import CommandTwin
from inspection_robot.thermal.commands import ThermalCommands
from inspection_robot.thermal.driver import NoImager, ThermalError
from inspection_robot.data_layout import CaptureQuota, capture_roots
from inspection_robot.ros.data_root import data_root

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


def make_imager(settings, width, height):
    """The thermal imager driver ``~driver`` names, built from ``settings`` (ros.node.NodeSettings)."""
    spec = settings.get("~driver")

    def isapi():
        from inspection_robot.thermal.isapi import imager_from_settings
        return imager_from_settings(settings.get("~isapi"))

    def simulator():
        from inspection_robot.sim.ros_view import SimView
        from inspection_robot.sim.render import ThermalRenderer
        from inspection_robot.sim.thermal import SimulatedImager
        from inspection_robot.sim.world import World
        params = settings.get("~sim")
        world = World.load(params["world_file"])
        renderer = ThermalRenderer(world, int(params["seed"]), float(params["noise_sigma"]))
        return SimulatedImager(renderer, SimView(world), world.sensor_height, width, height,
                               float(params["hfov_deg"]), list(params["unsupported"]))

    return make_driver("thermal", spec, {"isapi": isapi, SIM: simulator}, settings.get("~driver_params"),
                       NoImager)


def main():
    init_node(NODE)
    settings = NodeSettings("infrared_imager")
    width = int(settings.get("~width"))
    height = int(settings.get("~height"))
    status_rate = float(settings.get("~status_rate"))
    image_rate = float(settings.get("~image_rate"))
    if width < 8 or height < 8 or status_rate <= 0 or image_rate <= 0:
        raise ValueError("~width/~height must be >= 8 px, ~status_rate and ~image_rate > 0")
    driver = make_imager(settings, width, height)
    health = DeviceHealth()
    root = data_root()
    roots = capture_roots(settings.path_list("~roots", root), root)
    commands = ThermalCommands(driver, roots, health, width, height,
                               int(settings.get("~measure_box_px")), int(settings.get("~jpeg_quality")),
                               CaptureQuota.from_mib(roots, settings.get("~quota_mib")))
    InfraredNode(driver, commands, health, status_rate, image_rate,
                 check_quality(settings.get("~stream_jpeg_quality")), root)
    rospy.spin()
