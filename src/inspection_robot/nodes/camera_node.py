"""camera_node: the visible zoom camera (INTERFACE.md section 4, "Camera").

Services:    camera_control (ControlService): every command of the spec (camera.commands)
             camera_staging (ControlService): capture_picture under a fresh staged name
                 (.staging/<32 hex>.<ext>) for preset_scale and find_scale only: not in the backend surface
Subscribes:  camera_cmd (GeneralCmd) -> answers on camera_ack (GeneralAck), trans_id echoed
             control_status (ControlStatus): joystick-busy rule (mode 2)
             sim only: sim/true_pose, terrace_state, sim/world_state (sim/ros_view.py)
Publishes:   camera_zoom (std_msgs/Float64, latched, on change)
             camera/image_raw (sensor_msgs/Image, bgr8, ~image_width px wide, ~image_rate Hz)
             camera/image_raw/compressed (sensor_msgs/CompressedImage, format "jpeg", ~stream_jpeg_quality,
             the same frames; each form encoded only while it has subscribers)
             camera/camera_info (sensor_msgs/CameraInfo, with each image)
             diagnostics (diagnostic_msgs/DiagnosticArray, hardware_id "camera", ~status_rate Hz)
Parameters:  config/camera_node.yaml: every setting, its default and meaning (read through ros.node.NodeSettings),
             and config/camera_optics.yaml (~camera_optics); ~driver is required (the site file sets it),
             ~sim/world_file too with driver sim (the launch sets it); a ~roots entry overlapping presets, pictures,
             tasks ... is refused at start (data_layout.capture_roots); data_root (namespace)
"""
import threading
import traceback

import rospy
from sensor_msgs.msg import CameraInfo
from std_msgs.msg import Float64

from inspection_robot.camera.commands import CameraCommands, format_zoom
from inspection_robot.camera.jpeg import check_quality
from inspection_robot.camera.driver import CameraError, DeviceHealth, NoCamera
from inspection_robot.camera.optics import ZoomOptics
from inspection_robot.drivers import SIM, make_driver
from inspection_robot.data_layout import CaptureQuota, capture_roots
from inspection_robot.ros.diagnostics import DeviceDiagnostics, probe_device
from inspection_robot.ros.images import LiveViewPublisher
from inspection_robot.ros.node import NodeSettings, init_node
from inspection_robot.interface import CAMERA_STAGING_SERVICE
from inspection_robot.ros.twin import CommandTwin
from inspection_robot.ros.data_root import data_root

NODE = "camera_node"
HARDWARE_ID = "camera"


def camera_info_msg(width, height, focal, stamp, frame_id):
    cx, cy = width / 2.0, height / 2.0
    msg = CameraInfo(width=width, height=height, distortion_model="plumb_bob", D=[0.0] * 5,
                     K=[focal, 0, cx, 0, focal, cy, 0, 0, 1], R=[1, 0, 0, 0, 1, 0, 0, 0, 1],
                     P=[focal, 0, cx, 0, 0, focal, cy, 0, 0, 0, 1, 0])
    msg.header.stamp, msg.header.frame_id = stamp, frame_id
    return msg


class CameraNode(object):
    def __init__(self, driver, optics, roots, image_rate, image_width, status_rate, frame_id, stream_quality,
                 quota, data_root):
        self._driver = driver
        self._optics = optics
        self._image_width = int(image_width)
        self._frame_id = frame_id
        self._health = DeviceHealth()
        self.commands = CameraCommands(driver, optics, roots, self._health, quota=quota)
        self._last_zoom = None
        self._zoom_lock = threading.Lock()
        self._zoom_pub = rospy.Publisher("camera_zoom", Float64, queue_size=1, latch=True)
        self._live = LiveViewPublisher("camera/image_raw", stream_quality)
        self._info_pub = rospy.Publisher("camera/camera_info", CameraInfo, queue_size=1)
        self._diagnostics = DeviceDiagnostics("camera", HARDWARE_ID)
        self._twin = CommandTwin(self.commands.table, "camera_control", "camera_cmd", "camera_ack", NODE,
                                 staging=(self.commands.staging_table, CAMERA_STAGING_SERVICE), data_root=data_root)
        self._status_timer = rospy.Timer(rospy.Duration(1.0 / status_rate), self._on_status)
        self._image_timer = None
        if image_rate > 0:
            self._image_timer = rospy.Timer(rospy.Duration(1.0 / image_rate), self._on_image)

    def _on_status(self, _event):
        answered, zoom = probe_device(NODE, self._health, self._driver.get_zoom, CameraError)
        if answered:
            self._publish_zoom(zoom)
        self._diagnostics.publish(self._health.ok, self._health.message,
                                  [("zoom", format_zoom(self._last_zoom or 0.0)), ("failures", self._health.failures)])

    def _publish_zoom(self, zoom):
        zoom = round(float(zoom), 2)
        with self._zoom_lock:
            if zoom == self._last_zoom:
                return
            self._last_zoom = zoom
        self._zoom_pub.publish(Float64(zoom))

    def _on_image(self, _event):
        if not self._live.wanted() and self._info_pub.get_num_connections() == 0:
            return   # nobody watches: do not burn CPU rendering or fetching pictures
        try:
            img = self._driver.grab_frame(self._image_width)
            zoom = self._driver.get_zoom()
        except CameraError as err:
            self._health.failure(err)
            rospy.logwarn_throttle(10.0, "%s: no picture: %s" % (NODE, err))
            return
        except Exception as err:  # boundary: a timer tick must not die
            rospy.logerr_throttle(10.0, "%s: image tick failed: %s\n%s" % (NODE, err, traceback.format_exc()))
            return
        stamp = rospy.Time.now()
        height, width = img.shape[:2]
        self._live.publish(img, stamp, self._frame_id)
        self._info_pub.publish(camera_info_msg(width, height, self._optics.focal_px(zoom, width), stamp,
                                               self._frame_id))

    def shutdown(self):
        self.commands.shutdown()


def make_camera(settings, optics):
    """The camera driver ``~driver`` names, built from ``settings`` (ros.node.NodeSettings)."""
    spec = settings.get("~driver")

    def isapi():
        from inspection_robot.camera.isapi import IsapiCamera
        params = settings.get("~isapi")
        return IsapiCamera(str(params["url"]), str(params["user"]), str(params["password"]), int(params["channel"]),
                           float(params["timeout"]), str(params["snapshot_url"]))

    def simulator():
        from inspection_robot.sim.ros_view import SimView
        from inspection_robot.sim.camera import SimulatedCamera
        from inspection_robot.sim.render import Renderer
        from inspection_robot.sim.world import World
        params = settings.get("~sim")
        world = World.load(params["world_file"])
        renderer = Renderer(world, int(params["seed"]), float(params["noise_sigma"]), float(params["blur_sigma"]),
                            float(params["lighting_variation"]))
        return SimulatedCamera(renderer, optics, SimView(world), world.sensor_height,
                               float(params["zoom_rate"]), float(params["focus_rate"]),
                               int(settings.get("~jpeg_quality")))

    return make_driver("camera", spec, {"isapi": isapi, SIM: simulator}, settings.get("~driver_params"),
                       NoCamera)


def main():
    init_node(NODE)
    settings = NodeSettings("camera_node")
    optics_params = settings.get("~camera_optics")
    optics = ZoomOptics(optics_params["zoom_hfov_deg"], optics_params["width"], optics_params["height"])
    root = data_root()
    roots = capture_roots(settings.path_list("~roots", root), root)
    quota = CaptureQuota.from_mib(roots, settings.get("~quota_mib"))
    image_rate = float(settings.get("~image_rate"))
    image_width = int(settings.get("~image_width"))
    status_rate = float(settings.get("~status_rate"))
    if status_rate <= 0 or image_rate < 0 or not 16 <= image_width <= optics.width:
        raise ValueError("~status_rate must be > 0, ~image_rate >= 0, 16 <= ~image_width <= camera width")
    driver = make_camera(settings, optics)
    node = CameraNode(driver, optics, roots, image_rate, image_width, status_rate,
                      settings.get("~frame_id"),
                      check_quality(settings.get("~stream_jpeg_quality")), quota, root)
    rospy.on_shutdown(node.shutdown)
    rospy.spin()
