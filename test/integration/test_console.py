#!/usr/bin/env python3
"""rostest: the operator console in a real browser (Debian's chromium, headless, driven by Playwright)
against sim.launch. Every step asserts what the robot did, not only what the page shows:
status in words, hold-to-move driving that stops on key-up, a polygon drawn on the map becoming a
virtual obstacle (then edited and deleted), a click on the picture turning the head, a recorded
preset directory, a goal sent and cancelled; a meter box and needle points drawn on the preset's
picture becoming its calibration (after the robot's refusal of a bad one is shown); a patrol started,
paused, cancelled, resumed and sent home from the page as task_status reports it, its reading listed
with its annotated picture; two uncertain readings settled from the review panel (one corrected, one
confirmed) and found in the store; and a second, authenticated bridge where the page asks for the token, refuses a
wrong one and shows a dropped link. Any JavaScript error fails the test.
Screenshots go to <package>/test_logs/console/.
"""
import configparser
import json
import math
import os
import re
import shutil
import subprocess
import time
import unittest

import rospkg
import rospy
import rostest
from geometry_msgs.msg import PoseWithCovarianceStamped, TwistStamped
from nav_msgs.msg import OccupancyGrid
from playwright.sync_api import sync_playwright
from sensor_msgs.msg import JointState

from inspection_robot.msg import GeneralAck, GeneralCmd, GeneralTopic, MoveCmd, RobotStatus
from inspection_robot.task.patrol import Inspection
from inspection_robot.task.rows import reading_rows
from inspection_robot.task.store import ResultStore
from rostest_helpers import Latest, control_proxy, localizer_tolerance, wait_for, wait_subscribed

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]
CMD_TIMEOUT = 0.5      # s, robot_control's move_cmd watchdog
SHOTS = os.path.join(rospkg.RosPack().get_path("inspection_robot"), "test_logs", "console")
SCREENS = os.path.join(rospkg.RosPack().get_path("inspection_robot"), "test_logs", "screens")   # named views
FAR_STOP = (15.5, 10.0, 0.0)
# copies of test_8's preset recorded at other stops of the yard (inspection_robot_testing/yard_patrol.py)
YARD_COPIES = {"console_yard_a": (15.5, 10.0, 0.0), "console_yard_b": (20.0, 15.0, -math.pi / 2),
               "console_yard_c": (26.0, 21.4, math.pi / 2)}
# A page of another origin that tries to take backend control and drive through the robot's bridge.
ATTACK_PAGE = """<!doctype html><script>
window.attack = {opened: false, done: false};
const ws = new WebSocket('ws://127.0.0.1:%d/');
const header = {sender: 'server', receiver: '', trans_id: 1};
ws.onopen = () => {
  window.attack.opened = true;
  ws.send(JSON.stringify({op: 'publish', topic: '/mode_cmd',
                          msg: Object.assign({cmd: 'acquire', data: 'server'}, header)}));
  ws.send(JSON.stringify({op: 'publish', topic: '/move_cmd', msg: Object.assign({velocity_x: 0.5}, header)}));
};
ws.onclose = () => { window.attack.done = true; };
</script>"""   # a reachable stop of the yard (inspection_robot_testing/yard_patrol.py), ~11 m from the start


def bridge_port(node):
    return int(wait_for(lambda: rospy.get_param("/%s/actual_port" % node, None), 60.0, node + " port"))


class ConsoleTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_console")
        os.makedirs(SHOTS, exist_ok=True)
        os.makedirs(SCREENS, exist_ok=True)
        cls.port = bridge_port("rosbridge_websocket")
        cls.status = Latest("/robot_status", RobotStatus)
        cls.true_pose = Latest("/sim/true_pose", PoseWithCovarianceStamped)
        cls.chassis = Latest("/sim/chassis_cmd", TwistStamped, queue_size=1000)
        cls.head = Latest("/terrace_state", JointState)
        cls.obstacle_acks = Latest("/virtual_obstacle_ack", GeneralAck)
        cls.obstacle_map = Latest("/virtual_obstacle_map", OccupancyGrid)
        cls.obstacle_cmd = rospy.Publisher("/virtual_obstacle_cmd", GeneralCmd, queue_size=10)
        cls.mode_cmd = rospy.Publisher("/mode_cmd", GeneralCmd, queue_size=10)
        cls.move_cmds = Latest("/move_cmd", MoveCmd, queue_size=1000)
        cls.task_status = Latest("/task_status", GeneralTopic)
        cls.calibrated_preset = None   # test_8's preset directory, patrolled by test_9
        cls.playwright = sync_playwright().start()
        cls.browser = cls.playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)

    @classmethod
    def tearDownClass(cls):
        cls.browser.close()
        cls.playwright.stop()

    def setUp(self):
        self.link_errors_expected = False
        self.errors = []
        self.page = self.browser.new_page(viewport={"width": 1400, "height": 1200})
        self.page.on("pageerror", lambda err: self.errors.append("page error: %s" % err))
        self.page.on("console", lambda msg: self.errors.append("console %s: %s" % (msg.type, msg.text))
                     if msg.type == "error" else None)

    def tearDown(self):
        self.page.screenshot(path=os.path.join(SHOTS, self.id().split(".")[-1] + ".png"), full_page=True)
        self.page.close()
        if self.link_errors_expected:   # chromium reports every refused reconnection attempt
            self.errors = [e for e in self.errors if "WebSocket connection to" not in e]
        self.assertEqual(self.errors, [], "JavaScript errors on the console page")

    def open_console(self, port=None):
        self.page.goto("http://127.0.0.1:%d/console/" % (port or self.port))

    def wait_connected(self):
        self.page.wait_for_function("document.getElementById('link').textContent === 'connected'",
                                    timeout=20000)

    def wait_page(self, expression, what, timeout=20.0):
        try:
            self.page.wait_for_function(expression, timeout=timeout * 1000)
        except Exception as err:  # playwright's TimeoutError: say what was awaited
            raise AssertionError("page: timed out waiting for %s (%s)" % (what, err))

    def obstacle_command(self, cmd):
        """Send a virtual_obstacle_cmd over ROS (not through the page) and return move_base's ack."""
        self.obstacle_acks.clear()
        wait_subscribed(self.obstacle_cmd)
        trans_id = int(time.monotonic() * 1000) % 100000000

        def ask():
            self.obstacle_cmd.publish(GeneralCmd(sender="test_console", trans_id=trans_id, cmd=cmd, data=""))
        ack = self.obstacle_acks.handshake(ask, lambda m: m.trans_id == trans_id)
        self.assertEqual(ack.ack, "success", ack.data)
        return ack

    def obstacles(self):
        """The virtual obstacles move_base holds."""
        return {item["id"]: item for item in json.loads(self.obstacle_command("query").data)}

    def ensure_task_mode(self):
        """Undo a backend take-over a failed earlier test may have left."""
        if self.status.wait(lambda m: True, 10.0, "robot_status").mode == 1:
            wait_subscribed(self.mode_cmd)
            self.mode_cmd.publish(GeneralCmd(sender="server", cmd="release", data="server"))
        self.status.wait(lambda m: m.mode == 0, 10.0, "task mode")

    def map_click(self, x, y):
        """Click the map canvas at world (x, y) m, using the page's own map-to-screen transform."""
        self.page.locator("#map").scroll_into_view_if_needed()
        box = self.page.locator("#map").bounding_box()
        sx, sy, width, height = self.page.evaluate(
            "([x, y]) => { const c = document.getElementById('map');"
            " const [sx, sy] = window.consoleMap.toScreen([x, y]); return [sx, sy, c.width, c.height]; }", [x, y])
        self.page.mouse.click(box["x"] + sx * box["width"] / width, box["y"] + sy * box["height"] / height)

    # ------------------------------------------------------------------ cross-site websocket hijacking
    def test_0_pages_of_other_origins_cannot_drive(self):
        """A page of another site (or another port of this machine) in the operator's browser tries to
        take backend control and drive: the bridge refuses its handshake and nothing moves."""
        attack = ATTACK_PAGE % self.port
        self.move_cmds.clear()
        for origin in ("http://attacker.example", "http://127.0.0.1:%d" % (self.port + 1)):
            self.page.route(origin + "/**", lambda route: route.fulfill(body=attack, content_type="text/html"))
            self.page.goto(origin + "/")
            self.wait_page("window.attack && window.attack.done", "the attack page's end")
            self.assertEqual(self.page.evaluate("window.attack.opened"), False, origin)
        self.link_errors_expected = True   # chromium logs each refused handshake
        self.open_console()   # the console itself, from the bridge's own origin, still connects
        self.wait_connected()
        self.assertEqual([m for _, m in self.move_cmds.messages if m.sender == "server"], [])
        self.assertEqual(self.status.wait(lambda m: True, 5.0, "robot_status").mode, 0)

    # ------------------------------------------------------------------ status
    def test_1_status_in_words(self):
        self.open_console()
        self.wait_connected()
        self.wait_page("document.querySelector('#status tbody') && "
                       "document.querySelector('#status tbody').textContent.includes('battery')", "status rows")
        last = self.status.wait(lambda m: m.mode == 0, 10.0, "robot_status in task mode")
        text = self.page.inner_text("#status")
        self.assertIn("task", text)
        self.assertIn("%d %%" % last.battery_quantity, text)
        # the page shows a later robot_status than `last`: the localizer's x moves with its noise
        shown = re.search(r"x (-?[0-9.]+) m", text)
        self.assertTrue(shown, text)
        self.assertAlmostEqual(float(shown.group(1)), last.position[0], delta=localizer_tolerance()[0] + 0.01)
        self.assertIn("lamp green", text)           # light_status b2 decoded
        self.assertIn("OFFLINE", self.page.inner_text("#alarms"))   # nobody sends a heartbeat yet

    # ------------------------------------------------------------------ teleop
    def test_2_hold_to_move_and_stop_on_key_up(self):
        self.open_console()
        self.wait_connected()
        self.page.click("#acquire")
        self.status.wait(lambda m: m.mode == 1 and not m.offline_warn, 15.0, "backend mode granted to the console")
        start = self.true_pose.wait(lambda m: True, 5.0, "true pose").pose.pose.position
        self.page.locator("body").focus()
        self.page.keyboard.down("ArrowUp")
        self.true_pose.wait(lambda m: math.hypot(m.pose.pose.position.x - start.x,
                                                 m.pose.pose.position.y - start.y) > 0.2, 10.0,
                            "the robot moving forward while the key is held")
        self.chassis.clear()
        self.move_cmds.clear()
        key_up = rospy.get_time()
        self.page.keyboard.up("ArrowUp")
        stop = wait_for(lambda: next((m for _, m in self.chassis.messages
                                      if m.twist.linear.x == 0.0 and m.header.stamp.to_sec() >= key_up), None),
                        5.0, "a zero velocity at the driver after key-up")
        # The stop is the page's own explicit zero move_cmd, sent on key-up, not the robot's watchdog:
        # it reached the driver before cmd_timeout had passed since the last non-zero move_cmd.
        zero = wait_for(lambda: next((m for _, m in self.move_cmds.messages if m.velocity_x == 0), None), 5.0,
                        "the page's zero move_cmd")
        self.assertEqual((zero.sender, zero.velocity_yaw), ("server", 0))
        # Latest keeps monotonic arrival times; the driver's stamps are wall-clock ROS time.
        to_wall = rospy.get_time() - time.monotonic()
        last_drive = max([t + to_wall for t, m in self.move_cmds.messages if m.velocity_x != 0] or [key_up])
        self.assertLess(stop.header.stamp.to_sec(), last_drive + CMD_TIMEOUT)
        rospy.loginfo("key-up -> zero velocity at the driver: %.1f ms (make bench measures it quietly)",
                      (stop.header.stamp.to_sec() - key_up) * 1000.0)
        # ... and the robot really comes to rest and stays there.
        wait_for(lambda: self.status.last.velocity_x == 0.0, 5.0, "robot at rest")
        rest = self.true_pose.last.pose.pose.position
        count = len(self.status.messages)
        wait_for(lambda: len(self.status.messages) >= count + 5, 5.0, "half a second more of robot_status")
        moved = self.true_pose.last.pose.pose.position
        self.assertLess(math.hypot(moved.x - rest.x, moved.y - rest.y), 0.01)
        # Holding a key and losing focus stops too.
        self.page.keyboard.down("KeyW")
        self.true_pose.wait(lambda m: math.hypot(m.pose.pose.position.x - rest.x,
                                                 m.pose.pose.position.y - rest.y) > 0.05, 10.0, "moving again")
        self.chassis.clear()
        blur = rospy.get_time()
        self.page.evaluate("window.dispatchEvent(new Event('blur'))")
        wait_for(lambda: any(m.twist.linear.x == 0.0 and m.header.stamp.to_sec() >= blur
                             for _, m in self.chassis.messages), 5.0, "zero velocity after the page lost focus")
        self.page.keyboard.up("KeyW")
        self.page.click("#release")
        self.status.wait(lambda m: m.mode == 0, 10.0, "control released")

    # ------------------------------------------------------------------ map
    def test_3_draw_edit_delete_virtual_obstacle(self):
        self.open_console()
        self.wait_connected()
        self.wait_page("window.consoleMap && window.consoleMap.ready()", "the map drawn")
        self.obstacle_command("clear")   # the page selects the first obstacle under the mouse
        self.wait_page("window.consoleMap.obstacleCount() === 0", "the page's obstacle list cleared")
        before = self.obstacles()
        self.page.click("#tool-draw")
        corners = [(20.0, 20.0), (24.0, 20.0), (24.0, 23.0), (20.0, 23.0)]
        for x, y in corners:
            self.map_click(x, y)
        self.page.click("#obstacle-finish")
        added = wait_for(lambda: {k: v for k, v in self.obstacles().items() if k not in before}, 10.0,
                         "the drawn polygon as a virtual obstacle")
        (ident, obstacle), = added.items()
        self.assertTrue(ident.startswith("console_"))
        self.assertTrue(obstacle["closed"])
        self.assertEqual(len(obstacle["points"]), 4)
        for (x, y), (px, py) in zip(corners, obstacle["points"]):
            self.assertAlmostEqual(px, x, delta=0.3)
            self.assertAlmostEqual(py, y, delta=0.3)
        grid = self.obstacle_map.wait(lambda m: any(m.data), 10.0, "virtual_obstacle_map with the wall")
        self.assertTrue(any(grid.data))
        # Edit: select it, drag one corner 2 m right, save.
        self.wait_page("window.consoleMap.obstacleCount() === 1", "the new obstacle in the page's list")
        self.page.click("#tool-edit")
        self.map_click(22.0, 21.5)
        self.wait_page("!document.getElementById('obstacle-delete').disabled", "the obstacle selected")
        box = self.page.locator("#map").bounding_box()
        width, height = self.page.evaluate("[document.getElementById('map').width,"
                                           " document.getElementById('map').height]")

        def screen(x, y):
            sx, sy = self.page.evaluate("([x, y]) => window.consoleMap.toScreen([x, y])", [x, y])
            return box["x"] + sx * box["width"] / width, box["y"] + sy * box["height"] / height
        self.page.mouse.move(*screen(24.0, 20.0))
        self.page.mouse.down()
        self.page.mouse.move(*screen(26.0, 20.0), steps=5)
        self.page.mouse.up()
        self.wait_page("!document.getElementById('obstacle-save').disabled", "the corner dragged")
        self.page.click("#obstacle-save")
        wait_for(lambda: abs(self.obstacles()[ident]["points"][1][0] - 26.0) < 0.3, 10.0, "the moved corner saved")
        self.page.click("#obstacle-delete")
        wait_for(lambda: ident not in self.obstacles(), 10.0, "the obstacle deleted")

    def test_4_goal_sent_and_cancelled(self):
        self.ensure_task_mode()
        self.open_console()
        self.wait_connected()
        self.wait_page("window.consoleMap && window.consoleMap.ready()", "the map drawn")
        start = self.true_pose.wait(lambda m: True, 5.0).pose.pose.position
        self.page.click("#tool-goal")
        self.map_click(start.x + 8.0, start.y)
        self.true_pose.wait(lambda m: math.hypot(m.pose.pose.position.x - start.x,
                                                 m.pose.pose.position.y - start.y) > 0.3, 30.0,
                            "the robot driving to the clicked goal")
        self.page.click("#goal-cancel")
        self.wait_page("document.getElementById('log').textContent.includes('move_action result 4')",
                       "the cancelled goal's result in the page")

    # ------------------------------------------------------------------ head, camera, presets
    def test_5_click_on_picture_turns_head(self):
        self.open_console()
        self.wait_connected()
        # the live views draw the JPEG topics (<image topic>/compressed): pictures of the world, and new ones
        self.wait_page("window.consoleFrames && window.consoleFrames.picture > 0", "a live picture")
        self.wait_page("window.consoleFrames.thermal > 0", "a live thermal picture")
        for view in ("picture", "thermal"):
            drawn = self.page.evaluate("window.consoleFrames.%s" % view)
            self.wait_page("window.consoleFrames.%s > %d" % (view, drawn), "the %s stream advancing" % view)
            spread = self.page.evaluate("""(id) => {
                const c = document.getElementById(id);
                const px = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
                let lo = 255, hi = 0;
                for (let i = 0; i < px.length; i += 4) { lo = Math.min(lo, px[i + 1]); hi = Math.max(hi, px[i + 1]); }
                return [c.width, hi - lo];
            }""", view)
            self.assertGreater(spread[0], 16, view)
            self.assertGreater(spread[1], 40, "%s: a blank picture (green channel spread %d)" % (view, spread[1]))
        self.assertIn("hottest", self.page.inner_text("#thermal-caption"))
        pan0 = self.head.wait(lambda m: True, 10.0, "terrace_state").position[0]
        box = self.page.locator("#picture").bounding_box()
        self.page.mouse.click(box["x"] + box["width"] * 0.85, box["y"] + box["height"] * 0.5)
        # A point right of the centre: the head pans clockwise (standard pan decreases).
        self.head.wait(lambda m: m.position[0] < pan0 - math.radians(5.0), 15.0, "the head turning right")
        self.wait_page("document.getElementById('log').textContent.includes('terrace_ack')", "preset_rotate's ack")

    def test_6_record_preset(self):
        self.open_console()
        self.wait_connected()
        self.page.fill("#preset-id", "console_test")
        self.page.click("#preset-form button[type=submit]")
        self.wait_page("document.getElementById('preset-result').textContent.startsWith('recorded: ')",
                       "the preset recorded", timeout=60.0)
        directory = self.page.inner_text("#preset-result")[len("recorded: "):].strip()
        self.assertTrue(os.path.isdir(directory), directory)
        self.assertTrue(os.path.isfile(os.path.join(directory, "preset.ini")), os.listdir(directory))

    # ------------------------------------------------------------------ calibration on the page
    def calib_point(self, x, y):
        """Page coordinates of picture pixel (x, y) of the calibration canvas."""
        box = self.page.locator("#calib-picture").bounding_box()
        width, height = self.page.evaluate("window.consoleCalib.size()")
        return box["x"] + x * box["width"] / width, box["y"] + y * box["height"] / height

    def calibration(self, preset):
        """calibration_control get over ROS (not through the page)."""
        reply = control_proxy("/calibration_control", 30.0)(
            sender="test_console", cmd="get", data=json.dumps({"preset": preset}))
        self.assertEqual(reply.ack, "success", reply.data)
        return json.loads(reply.data)

    def test_8_calibration_drawn_on_the_page_is_applied(self):
        self.open_console()
        self.wait_connected()
        # A directory that is no preset: the robot's own failure text.
        self.page.fill("#calib-preset", "presets/console_calib/no_such_recording")
        self.page.click("#calib-load")
        self.wait_page("document.getElementById('calib-result').textContent.startsWith('cannot load ')",
                       "the failed load shown")
        self.assertIn("preset directory not found", self.page.inner_text("#calib-result"))
        self.page.fill("#preset-id", "console_calib")
        self.page.click("#preset-form button[type=submit]")
        self.wait_page("document.getElementById('preset-result').textContent.startsWith('recorded: ')",
                       "the preset recorded", timeout=60.0)
        directory = self.page.inner_text("#preset-result")[len("recorded: "):].strip()
        self.wait_page("window.consoleCalib.ready()", "the preset's zoom0.jpg on the calibration canvas")
        width, height = self.page.evaluate("window.consoleCalib.size()")
        x0, y0, x1, y1 = 0.3 * width, 0.3 * height, 0.6 * width, 0.7 * height
        self.page.locator("#calib-picture").scroll_into_view_if_needed()
        self.page.click("#calib-tool-box")
        self.page.mouse.move(*self.calib_point(x0, y0))
        self.page.mouse.down()
        self.page.mouse.move(*self.calib_point(x1, y1), steps=5)
        self.page.mouse.up()
        radius = 0.4 * (x1 - x0)

        def needle(angle_deg):   # the picture point the needle points at, angle clockwise from 12 o'clock
            return self.calib_point((x0 + x1) / 2 + radius * math.sin(math.radians(angle_deg)),
                                    (y0 + y1) / 2 - radius * math.cos(math.radians(angle_deg)))
        self.page.click("#calib-tool-zero")   # needle at 7:30 (-135 deg) reads 0, at 4:30 (+135 deg) 1.6
        self.page.mouse.click(*needle(-135.0))
        self.page.click("#calib-tool-full")
        self.page.mouse.click(*needle(135.0))
        self.page.fill("#calib-name", "console_gauge")
        self.page.fill("#calib-unit", "MPa")
        self.page.fill("#calib-zero-value", "0")
        self.page.fill("#calib-full-value", "1.6")
        # A lamp without a colour: the robot refuses, the page shows its text, nothing is written.
        self.page.select_option("#calib-kind", "lamp")
        self.page.click("#calib-form button[type=submit]")
        self.wait_page("document.getElementById('calib-result').textContent.startsWith('refused: ')",
                       "the refusal shown")
        self.assertIn("calibration refused, nothing written: ", self.page.inner_text("#calib-result"))
        self.assertFalse(self.calibration(directory)["calibrated"])
        self.page.select_option("#calib-kind", "pointer")
        # The operator says the needle shows 100 on a 0-1.6 scale: the robot refuses, nothing written.
        self.page.fill("#calib-expected", "100")
        self.page.click("#calib-form button[type=submit]")
        self.wait_page("document.getElementById('calib-result').textContent.startsWith('refused: ')",
                       "the self-check's refusal shown")
        self.assertIn("you expect 100, outside its scale 0 .. 1.6", self.page.inner_text("#calib-result"))
        self.assertFalse(self.calibration(directory)["calibrated"])
        self.page.fill("#calib-expected", "")
        self.page.click("#calib-form button[type=submit]")
        self.wait_page("document.getElementById('calib-result').textContent.startsWith('applied: ')",
                       "the calibration applied")
        self.assertIn("the robot reads", self.page.inner_text("#calib-result"))   # its reading beside
        got = self.calibration(directory)
        self.assertTrue(got["calibrated"])
        (target,) = got["targets"]
        self.assertEqual((target["kind"], target["name"], target["unit"]), ("pointer", "console_gauge", "MPa"))
        for value, expected in zip(target["box"], [x0, y0, x1, y0, x1, y1, x0, y1]):
            self.assertAlmostEqual(value, expected, delta=2.0)
        self.assertAlmostEqual(target["start_angle"], -135.0, delta=2.0)
        self.assertAlmostEqual(target["end_angle"], 135.0, delta=2.0)
        self.assertEqual((target["start_value"], target["end_value"]), (0.0, 1.6))
        self.assertAlmostEqual(target["aspect"], (x1 - x0) / (y1 - y0), delta=0.02)
        ConsoleTest.calibrated_preset = directory

    # ------------------------------------------------------------------ patrol and history
    def task(self, predicate, what, timeout=30.0):
        return self.task_status.wait(lambda m: predicate(json.loads(m.data)), timeout, what)

    def test_9_patrol_started_paused_cancelled_sent_home_from_the_page(self):
        self.assertIsNotNone(self.calibrated_preset, "test_8 calibrates the preset this patrol reads")
        self.ensure_task_mode()
        self.open_console()
        self.wait_connected()
        self.wait_page("document.getElementById('patrol-state').textContent !== 'no task_status yet'",
                       "task_status on the page")
        pose = self.status.wait(lambda m: True, 5.0, "robot_status")
        task_id = "console_%d" % int(time.time() * 1000)
        preset = os.path.relpath(self.calibrated_preset, os.path.dirname(os.path.dirname(self.calibrated_preset)))
        # The operator sets the gauge's limits on the page: a normal band it reads outside of, an alarm
        # band around that (a bad band refused first, nothing saved).
        calibrated = self.calibration("presets/" + preset)
        self.set_limits("presets/" + preset, "abc", "200", "", "")
        self.wait_page("document.getElementById('limits-result').textContent.includes("
                       "'normal band low must be a number, got \"abc\" (nothing saved)')", "the bad band refused")
        self.set_limits("presets/" + preset, "100", "200", "150", "250")
        self.wait_page("document.getElementById('limits-result').textContent.includes('alarm band [150, 250] must "
                       "contain the normal band [100, 200]')", "the alarm band that does not contain the normal one")
        self.assertEqual(self.calibration("presets/" + preset)["targets"], calibrated["targets"])
        self.set_limits("presets/" + preset, "100", "200", "50", "250")
        self.wait_page("document.getElementById('limits-result').textContent.startsWith('limits saved')",
                       "the limits saved")
        (gauge,) = self.calibration("presets/" + preset)["targets"]
        self.assertEqual((gauge["normal"], gauge["alarm_band"]), ([100.0, 200.0], [50.0, 250.0]))
        self.page.locator("#limits-table").screenshot(path=os.path.join(SCREENS, "limits.png"))
        open_before = self.page.evaluate("window.consoleAlarms.count")
        # retries 1, the product's default: a drive ended by a passing localization stall (the
        # simulated pose 0.5 s late on a loaded test machine: "localization lost") is driven again,
        # and the patrol is still there to be paused (fresh-clone CI of 025383b)
        task = {"id": task_id, "retries": 1, "stops": [
            {"name": "here", "pose": {"x": pose.position[0], "y": pose.position[1], "yaw": pose.orientation},
             "presets": [preset]},
            {"name": "far", "pose": {"x": FAR_STOP[0], "y": FAR_STOP[1], "yaw": FAR_STOP[2]}, "presets": [preset]}]}
        self.page.click("#patrol-advanced summary")   # the JSON view, for what the planner cannot say
        self.page.fill("#patrol-task", json.dumps(task))
        self.page.click("#patrol-form button[type=submit]")
        self.task(lambda s: s.get("task_id") == task_id and s["state"] == "running", "the patrol running")
        self.wait_page("document.getElementById('patrol-state').textContent.startsWith('running: %s')" % task_id,
                       "the running patrol on the page")
        # Stop 1 inspected, the robot on its way to stop 2: pause from the page.
        self.task(lambda s: s.get("task_id") == task_id and s["done"] >= 1, "the first preset inspected", 120.0)
        self.wait_page("document.getElementById('patrol-state').textContent.includes('stop 2 of 2')",
                       "the progress on the page")
        self.page.click("#patrol-pause")
        self.task(lambda s: s.get("task_id") == task_id and s["state"] == "paused" and s["holds"] == ["operator"],
                  "the patrol paused by the page")
        self.wait_page("document.getElementById('patrol-state').textContent.startsWith('paused')", "paused shown")
        # The reading of stop 1 in the history, with its annotated picture fetched through file_control.
        reply = control_proxy("/task_control", 10.0)(
            sender="test_console", cmd="query_results", data=json.dumps({"task_id": task_id}))
        (row,) = json.loads(reply.data)
        # outside both bands: an alarm, or a check when the reader doubted the value (the sim's gauge may)
        self.assertIn(row["alarm"], ("alarm", "check"))
        self.assertEqual((row["low"], row["high"], row["alarm_low"], row["alarm_high"]), (100.0, 200.0, 50.0, 250.0))
        # The patrol's alarm: the banner within that reading, acknowledged on the page by a named operator.
        self.wait_page("!document.getElementById('alarm-banner').hidden && window.consoleAlarms.count > %d"
                       % (open_before or 0), "the banner of the patrol's alarm")
        self.wait_page("window.consoleAlarms.ids().includes(%d)" % row["id"], "the alarm listed")
        self.page.fill("#alarm-by", "console_operator")
        self.page.fill("#alarm-note", "gauge checked on site")
        self.page.click("#alarm-list tr[data-id='%d'] .alarm-ack" % row["id"])
        self.wait_page("!window.consoleAlarms.ids().includes(%d)" % row["id"], "the alarm acknowledged")
        acknowledged = self.task_control("query_results", {"task_id": task_id})[0]
        self.assertEqual((acknowledged["ack_by"], acknowledged["ack_note"]),
                         ("console_operator", "gauge checked on site"))
        self.wait_page("document.querySelector('#results tbody').textContent.includes('console_gauge')",
                       "the reading in the history")
        if row["picture"]:
            self.wait_page("Array.from(document.querySelectorAll('#results img'))"
                           ".some((i) => i.src.startsWith('data:image/') && i.naturalWidth > 0)",
                           "the annotated picture shown")
        # The meter's trend: every reading of it the store holds (the page asks for the last 90 days),
        # with two weeks of earlier readings of it stored as task_manager stores them: one a day,
        # drifting up out of its band [0, 1] on the last day.
        self.store_history("console_gauge", [0.55 + 0.035 * day for day in range(14)])
        history = json.loads(control_proxy("/task_control", 10.0)(
            sender="test_console", cmd="query_results", data=json.dumps({"target": "console_gauge"})).data)
        self.assertGreaterEqual(len(history), 1)
        self.page.click("#results td.trend-link >> text=console_gauge")
        points = len([r for r in history if r["value"] is not None])
        self.wait_page("document.getElementById('trend').dataset.points === '%d'" % points, "the meter's trend drawn")
        self.wait_page("document.querySelector('#trend .uplot canvas') !== null", "the chart (uPlot) on the page")
        # the legend names the meter and its bands; CSV export has a line per reading
        legend = self.page.inner_text("#trend .u-legend")
        self.assertIn("console_gauge", legend)
        self.assertIn("console_gauge normal high", legend)
        csv = self.page.evaluate("window.consoleTrends.csv()").strip().split("\n")
        self.assertEqual(len(csv), 1 + points)
        self.assertTrue(csv[0].startswith("time_utc,time,target,value,unit,status,alarm,low,high"))
        # hovering the chart shows a value in the legend
        over = self.page.locator("#trend .u-over")
        over.scroll_into_view_if_needed()
        box = over.bounding_box()
        over.hover(position={"x": box["width"] - 3, "y": box["height"] / 2})   # the newest reading
        self.wait_page("Array.from(document.querySelectorAll('#trend .u-legend .u-value')).some("
                       "(e) => e.textContent.includes('MPa'))", "a value under the cursor")
        self.page.select_option("#trend-range", "7")   # the last week only: the 14 days of history halve
        self.wait_page("Number(document.getElementById('trend').dataset.points) < %d" % points, "the week's trend")
        self.page.locator("#trend").screenshot(path=os.path.join(SCREENS, "trend.png"))
        self.page.click("#patrol-cancel")
        self.task(lambda s: (s.get("last_ended") or {}).get("task_id") == task_id
                  and s["last_ended"]["state"] == "cancelled", "the patrol cancelled by the page")
        # The report of the cancelled patrol names who acknowledged the alarm, and when.
        report = os.path.join(rospy.get_param("/data_root"), "tasks", "reports", task_id, "report.html")
        wait_for(lambda: os.path.isfile(report), 20.0, "the patrol's report")
        with open(report) as f:
            page = f.read()
        self.assertIn("acknowledged by console_operator, %s" % time.strftime(
            "%Y-%m-%d %H:%M:%S", time.localtime(acknowledged["ack_time"])), page)
        self.assertIn("100 .. 200 MPa; alarm outside 50 .. 250 MPa", page)
        # The limits cleared on the page again (every field empty): the later tests read without limits.
        self.set_limits("presets/" + preset, "", "", "", "")
        self.wait_page("document.getElementById('limits-result').textContent.startsWith('limits saved')",
                       "the limits cleared")
        self.assertNotIn("normal", self.calibration("presets/" + preset)["targets"][0])
        # A refusal shows the robot's own text: task ids are never reused.
        self.page.fill("#patrol-task", json.dumps(task))
        self.page.click("#patrol-form button[type=submit]")
        self.wait_page("document.getElementById('patrol-result').textContent.includes(\"refused: duplicate task "
                       "id '%s' (ids are never reused)\")" % task_id, "the refusal shown")
        self.page.click("#patrol-resume")   # the operator hold outlives the task: release it
        self.task(lambda s: s["holds"] == [], "the operator hold released")
        self.task_status.clear()
        self.page.click("#patrol-home")
        wait_for(lambda: any(json.loads(m.data)["state"] == "returning_home" for _, m in self.task_status.messages),
                 10.0, "task_manager returning home")
        # Home reached: task_manager leaves returning_home (it then shows the last task's end again).
        status = json.loads(self.task(lambda s: s["state"] != "returning_home", "home reached", 60.0).data)
        self.assertFalse(status["reason"].startswith("return home failed"), status["reason"])
        home = self.true_pose.last.pose.pose.position
        self.assertLess(math.hypot(home.x - 5.0, home.y - 5.0), 0.5)   # config/sim_site.yaml task_manager/home_pose

    # ------------------------------------------------------------------ review of uncertain readings
    def test_9b_uncertain_readings_reviewed_from_the_page(self):
        self.assertIsNotNone(self.calibrated_preset, "test_8 calibrates the preset whose picture is reviewed")
        store = json.loads(self.task(lambda s: s.get("store"), "task_status with the store").data)["store"]
        self.assertEqual(store, "tasks/results.sqlite")   # named relative to the data root, as file_control does
        data_root = rospy.get_param("/data_root")
        store_path = os.path.join(data_root, store)
        # Two readings read_scale doubted, recorded as task_manager records them (the sim's gauges read
        # confidently): one outside its band (a check alarm), one inside.
        task_id = "console_review_%d" % int(time.time() * 1000)
        picture = os.path.join(self.calibrated_preset, "zoom0.jpg")
        preset = {"directory": self.calibrated_preset, "foreign": False, "alarms": {"console_gauge": [0.0, 1.0]},
                  "targets": [{"name": "console_gauge", "kind": "pointer", "unit": "MPa"}]}
        rows = []
        for index, value in enumerate((1.3, 0.4)):
            inspection = Inspection([value], [35.0], [picture], (1.0, 2.0, 0.0), None, ["glare over 30 % of the dial"],
                                    [{"picture": picture, "roi": [10, 10, 90, 10, 90, 90, 10, 90]}])
            rows += reading_rows(task_id, 0, "here", index, preset, inspection, "", time.time())
        store = ResultStore(store_path)
        self.assertEqual(store.add_readings(rows), 2)
        store.close()
        queue = self.task_control("review_queue", {"task_id": task_id})
        self.assertEqual([(r["alarm"], r["value"]) for r in queue], [("check", 1.3), ("normal", 0.4)])
        corrected, confirmed = (r["id"] for r in queue)
        self.open_console()
        self.wait_connected()
        item = "document.querySelector('.review-item[data-id=\"%d\"]')"
        self.wait_page(item % corrected + " !== null && " + item % confirmed + " !== null", "both in the review queue")
        self.assertIn("CHECK", self.page.inner_text(".review-item[data-id='%d']" % corrected))
        self.assertIn("glare over 30 % of the dial", self.page.inner_text(".review-item[data-id='%d']" % corrected))
        self.wait_page("(%s.querySelector('img') || {}).naturalWidth > 0" % (item % corrected), "the picture shown")
        # No reviewer name: the page asks for it and sends nothing.
        self.page.click(".review-item[data-id='%d'] .review-confirm" % confirmed)
        self.wait_page("document.getElementById('review-result').textContent.includes('reviewer')", "name asked")
        self.page.fill("#review-by", "console_operator")
        self.page.fill(".review-item[data-id='%d'] .review-value" % corrected, "0.85")
        self.page.click(".review-item[data-id='%d'] .review-correct" % corrected)
        self.wait_page(item % corrected + " === null", "the corrected reading leaving the queue")
        self.page.click(".review-item[data-id='%d'] .review-confirm" % confirmed)
        self.wait_page(item % confirmed + " === null", "the confirmed reading leaving the queue")
        self.assertEqual(self.task_control("review_queue", {"task_id": task_id}), [])
        if not self.task_control("review_queue", {}):   # an empty queue says so instead of showing nothing
            self.wait_page("document.getElementById('review-list').textContent.includes('Nothing to review')",
                           "the empty queue's words")
        got = dict((r["id"], r) for r in self.task_control("query_results", {"task_id": task_id}))
        self.assertEqual((got[corrected]["value"], got[corrected]["review_value"], got[corrected]["review_alarm"],
                          got[corrected]["review_by"]), (1.3, 0.85, "normal", "console_operator"))
        self.assertEqual((got[confirmed]["value"], got[confirmed]["review_value"], got[confirmed]["review_by"]),
                         (0.4, 0.4, "console_operator"))
        with open(os.path.join(data_root, "corrections", "%s.%d.json" % (task_id, corrected))) as f:
            record = json.load(f)
        self.assertEqual((record["true_value"], record["value"], record["picture"], record["preset"]),
                         (0.85, 1.3, picture, self.calibrated_preset))

    def test_9d_an_alarm_shown_sounded_and_acknowledged_from_the_page(self):
        """A reading outside its band recorded (as task_manager records it) while the page is open: the
        header's banner and a tone, the alarm listed, acknowledged by a named operator with a note."""
        self.open_console()
        self.wait_connected()
        self.wait_page("window.consoleAlarms.count !== null", "the open-alarm count of task_status")
        chimes = self.page.evaluate("window.consoleAlarms.chimes")
        task_id = "console_alarm_%d" % int(time.time() * 1000)
        picture = os.path.join(self.calibrated_preset, "zoom0.jpg")
        preset = {"directory": self.calibrated_preset, "foreign": False, "alarms": {"console_gauge": [0.0, 1.0]},
                  "targets": [{"name": "console_gauge", "kind": "pointer", "unit": "MPa"}]}
        rows = reading_rows(task_id, 0, "here", 0, preset, Inspection([1.6], [90.0], [picture], (1.0, 2.0, 0.0)), "",
                            time.time())
        store = ResultStore(os.path.join(rospy.get_param("/data_root"), "tasks", "results.sqlite"))
        self.assertEqual(store.add_readings(rows), 1)   # another process's commit: task_manager counts it within 10 s
        store.close()
        (row_id,) = [r["id"] for r in self.task_control("query_results", {"task_id": task_id})]
        listed = "document.querySelector('#alarm-list tr[data-id=\"%d\"]')" % row_id
        self.wait_page(listed + " !== null", "the new alarm listed", timeout=30.0)
        self.wait_page("window.consoleAlarms.chimes > %d" % chimes, "a tone for the new alarm")
        self.assertFalse(self.page.is_hidden("#alarm-banner"))
        self.assertIn("open alarm", self.page.inner_text("#alarm-banner"))
        self.page.fill("#alarm-by", "")
        self.page.click("#alarm-list tr[data-id='%d'] .alarm-ack" % row_id)
        self.wait_page("document.getElementById('alarm-result').textContent.includes('operator')", "name asked")
        self.page.fill("#alarm-by", "console_operator")
        self.page.fill("#alarm-note", "gauge replaced")
        self.page.click("#alarm-list tr[data-id='%d'] .alarm-ack" % row_id)
        self.wait_page(listed + " === null", "the acknowledged alarm leaving the list")
        (acked,) = self.task_control("alarms", {"task_id": task_id, "acknowledged": True})
        self.assertEqual((acked["id"], acked["ack_by"], acked["ack_note"]),
                         (row_id, "console_operator", "gauge replaced"))
        self.assertEqual(self.task_control("alarms", {"task_id": task_id}), [])

    # ------------------------------------------------------------------ patrol planner, routines, schedules
    def task_control_raw(self, cmd, data):
        """task_control over ROS with ``data`` as it is: (ack, data)."""
        reply = control_proxy("/task_control", 10.0)(sender="test_console", cmd=cmd, data=data)
        return reply.ack, reply.data

    def pixel_near(self, canvas, x, y, colour, radius=2, tolerance=40):
        """Whether a pixel of ``canvas`` within ``radius`` px of world point (x, y) has ``colour`` (RGB)."""
        return self.page.evaluate(
            "([id, x, y, c, r, tol]) => { const canvas = document.getElementById(id);"
            " const [sx, sy] = window.consoleMap.toScreen([x, y]);"
            " const d = canvas.getContext('2d')"
            "  .getImageData(Math.round(sx) - r, Math.round(sy) - r, 2 * r + 1, 2 * r + 1).data;"
            " for (let i = 0; i < d.length; i += 4) {"
            "  if (Math.abs(d[i] - c[0]) + Math.abs(d[i + 1] - c[1]) + Math.abs(d[i + 2] - c[2]) < tol) return true; }"
            " return false; }", [canvas, x, y, list(colour), radius, tolerance])

    def test_9c_patrol_planned_on_the_map_saved_and_scheduled(self):
        self.assertIsNotNone(self.calibrated_preset, "test_8 calibrates the preset the planner picks")
        self.ensure_task_mode()
        self.task(lambda s: s["state"] not in ("running", "paused", "returning_home"), "no patrol running", 60.0)
        stamp = os.path.basename(self.calibrated_preset)
        directory = "presets/%s/%s" % (os.path.basename(os.path.dirname(self.calibrated_preset)), stamp)
        pose = self.calibration(directory)["info"]["pose"]
        # Three more presets of the same meter recorded at yard stops (copies with another pose).
        yard = {}
        for name, stop in YARD_COPIES.items():
            copy = os.path.join(os.path.dirname(os.path.dirname(self.calibrated_preset)), name, stamp)
            shutil.copytree(self.calibrated_preset, copy)
            ini = configparser.ConfigParser(interpolation=None)
            ini.read(os.path.join(copy, "preset.ini"))
            ini["preset"]["preset_id"] = name
            ini["pose"] = {"x": "%.4f" % stop[0], "y": "%.4f" % stop[1], "yaw": "%.5f" % stop[2]}
            with open(os.path.join(copy, "preset.ini"), "w") as f:
                ini.write(f)
            yard[name] = "presets/%s/%s" % (name, stamp)
        self.open_console()
        self.wait_connected()
        # The preset list loads by itself once the link is up: every preset id's newest recording.
        self.wait_page("window.consolePlanner.catalog() >= 4 && !window.consolePlanner.loading()", "the preset list")
        self.wait_page("window.consoleMap.ready()", "the map drawn")
        # A click on a stop on the map picks its presets (every calibrated one recorded there).
        self.page.click("#tool-pick")
        self.map_click(pose[0], pose[1])
        self.wait_page("window.consolePlanner.stops().length === 1", "the stop picked on the map")
        self.map_click(*YARD_COPIES["console_yard_b"][:2])
        self.wait_page("window.consolePlanner.stops().length === 2", "the second stop picked on the map")
        self.page.click("#tool-pick")
        # The searchable list: the preset ids found by a word of theirs, added; one stop each.
        self.page.fill("#planner-search", "console_yard")
        for name in ("console_yard_a", "console_yard_c"):
            self.page.click("#planner-catalog li[data-preset='%s'] .planner-add" % yard[name])
        self.wait_page("window.consolePlanner.stops().length === 4", "four stops")
        stops = self.page.evaluate("window.consolePlanner.stops()")
        self.assertEqual([s["presets"] for s in stops],
                         [[directory], [yard["console_yard_b"]], [yard["console_yard_a"]], [yard["console_yard_c"]]])
        self.assertAlmostEqual(stops[0]["pose"]["x"], pose[0], delta=0.01)
        # A meter's name finds its presets; adding one already planned says so and adds nothing.
        self.page.fill("#planner-search", "console_gauge")
        item = "#planner-catalog li[data-preset='%s']" % directory
        self.wait_page("document.querySelectorAll('#planner-catalog li').length >= 4",
                       "the presets found by their meter")
        self.page.click(item + " .planner-add")
        self.wait_page("document.getElementById('planner-route').textContent.includes('already planned')",
                       "the duplicate refused")
        self.assertEqual(len(self.page.evaluate("window.consolePlanner.stops()")), 4)
        # Plan: task_manager's order and path, drawn on the map with its length; the same as asked over ROS.
        self.page.click("#planner-plan")
        self.wait_page("window.consolePlanner.route() !== null", "the planned route", 60.0)
        route = self.page.evaluate("window.consolePlanner.route()")
        task = {"order": "shortest", "retries": 1,
                "stops": [{"name": s["name"], "pose": s["pose"], "presets": s["presets"]} for s in stops]}
        ack, data = self.task_control_raw("plan", json.dumps(task))
        self.assertEqual(ack, "success", data)
        self.assertAlmostEqual(route["planned_length_m"], json.loads(data)["planned_length_m"], delta=0.5)
        self.assertGreater(len(route["path"]), 2)
        self.assertIn("%.1f m planned" % route["planned_length_m"], self.page.inner_text("#planner-route"))
        middle = route["path"][len(route["path"]) // 2]
        self.page.locator("#map").scroll_into_view_if_needed()
        self.wait_page("window.consolePlanner.routeDrawn()", "the route drawn on the map")
        self.assertTrue(self.pixel_near("map", middle[0], middle[1], (0x6a, 0x1b, 0x9a)), "the route drawn purple")
        self.page.add_style_tag(content="header { position: static; }")   # not over the panels shot
        self.page.locator("#map-panel").screenshot(path=os.path.join(SCREENS, "planner_route.png"))
        self.page.locator("#planner-panel").screenshot(path=os.path.join(SCREENS, "planner.png"))
        # Saved as a routine: task_manager holds it as the page built it.
        routine = "console_routine_%d" % (int(time.time() * 1000) % 100000000)
        self.page.fill("#routine-name", routine)
        self.page.click("#routine-save")
        self.wait_page("document.querySelector('#routines tr[data-routine=\"%s\"]') !== null" % routine,
                       "the routine listed")
        ack, data = self.task_control_raw("routine_list", "")
        saved = next(r for r in json.loads(data) if r["name"] == routine)
        self.assertEqual([s["presets"] for s in saved["task"]["stops"]], [s["presets"] for s in stops])
        self.assertNotIn("id", saved["task"])
        # A schedule in the past: the robot's refusal shown, nothing stored.
        self.page.fill("#schedule-name", routine + "_past")
        self.page.select_option("#schedule-routine", routine)
        self.page.fill("#schedule-time", "08:00")
        self.page.check("input[name=schedule-repeat][value=date]")
        self.page.fill("#schedule-date", time.strftime("%Y-%m-%d", time.localtime(time.time() - 86400)))
        self.page.click("#schedule-form button[type=submit]")
        self.wait_page("document.getElementById('schedule-result').textContent.includes('is in the past')",
                       "the past schedule refused")
        # A one-off at the next whole minute (robot local time) at least 20 s away: it fires by itself.
        at = (int(time.time() + 20) // 60 + 1) * 60
        name = routine + "_once"
        self.page.fill("#schedule-name", name)
        self.page.fill("#schedule-time", time.strftime("%H:%M", time.localtime(at)))
        self.page.fill("#schedule-date", time.strftime("%Y-%m-%d", time.localtime(at)))
        self.page.click("#schedule-form button[type=submit]")
        row = "document.querySelector('#schedules tr[data-schedule=\"%s\"]')" % name
        self.wait_page(row + " !== null && " + row + ".textContent.includes('%s')"
                       % time.strftime("%Y-%m-%d %H:%M", time.localtime(at)), "the schedule with its next run")
        run = routine + time.strftime("_%Y%m%d_%H%M", time.localtime(at))
        self.task(lambda s: s.get("task_id") == run and s["state"] == "running", "the scheduled run started",
                  at - time.time() + 60.0)
        self.wait_page(row + ".textContent.includes('%s')" % run, "the last run on the page")
        self.assertEqual(self.task_control_raw("cancel", "")[0], "success")
        self.task(lambda s: (s.get("last_ended") or {}).get("task_id") == run, "the scheduled run cancelled")
        self.page.locator("#schedule-panel").screenshot(path=os.path.join(SCREENS, "schedules.png"))
        # Deleted from the page: the schedule, then its routine.
        self.page.click("#schedules tr[data-schedule='%s'] button >> text=delete" % name)
        self.wait_page(row + " === null", "the schedule deleted")
        self.page.click("#routines tr[data-routine='%s'] button >> text=delete" % routine)
        self.wait_page("document.querySelector('#routines tr[data-routine=\"%s\"]') === null" % routine,
                       "the routine deleted")
        self.assertNotIn(routine, [r["name"] for r in json.loads(self.task_control_raw("routine_list", "")[1])])

    def store_history(self, target, values):
        """One reading of ``target`` (test_8's preset) a day for the last ``len(values)`` days, in the store."""
        status = json.loads(self.task(lambda s: s.get("store"), "task_status with the store").data)
        store = ResultStore(os.path.join(rospy.get_param("/data_root"), status["store"]))
        preset = {"directory": self.calibrated_preset, "foreign": False, "alarms": {target: [0.0, 1.0]},
                  "targets": [{"name": target, "kind": "pointer", "unit": "MPa"}]}
        now = time.time()
        rows = []
        for day, value in enumerate(values):   # one patrol a day
            inspection = Inspection([value], [90.0], [""], (1.0, 2.0, 0.0), None, [""])
            rows += reading_rows("console_history_%d_%d" % (int(now * 1000), day), 0, "here", 0, preset, inspection,
                                 "", now - (len(values) - day) * 86400)
        self.assertEqual(store.add_readings(rows), len(values))
        store.close()

    def set_limits(self, preset, low, high, alarm_low, alarm_high):
        """The calibration editor's preset loaded (once), its one target's four limit fields typed, saved."""
        if self.page.evaluate("window.consoleCalib.preset()") != preset:
            self.page.fill("#calib-preset", preset)
            self.page.click("#calib-load")
            self.wait_page("document.querySelector('#limits-table tr[data-index=\"0\"]') !== null",
                           "the preset's limits in the editor")
        self.page.evaluate("document.getElementById('limits-result').textContent = ''")
        for name, value in (("low", low), ("high", high), ("alarm-low", alarm_low), ("alarm-high", alarm_high)):
            self.page.fill("#limits-table tr[data-index='0'] .limit-" + name, value)
        self.page.click("#limits-save")

    def task_control(self, cmd, query):
        """task_control over ROS (not through the page): the JSON of a successful reply."""
        reply = control_proxy("/task_control", 10.0)(sender="test_console", cmd=cmd, data=json.dumps(query))
        self.assertEqual(reply.ack, "success", reply.data)
        return json.loads(reply.data)

    # ------------------------------------------------------------------ the operator's language
    PANELS = ("status-panel", "teleop-panel", "camera-panel", "map-panel", "planner-panel", "schedule-panel",
              "preset-panel", "patrol-panel", "alarm-panel", "review-panel", "log-panel")

    def test_9e_the_page_in_chinese_and_english_each_panel_shown(self):
        """The site's language (the simulated yard's: en) first; Chinese chosen in the page stays chosen
        across a reload; every panel's screenshot in both languages (test_logs/screens/console_<lang>_*)."""
        self.open_console()
        self.wait_connected()
        self.assertEqual(self.page.evaluate("document.documentElement.lang"), "en")
        self.shoot_panels("en")
        self.page.select_option("#language", "zh-CN")   # the page reloads in Chinese
        self.page.wait_for_function("document.documentElement.lang === 'zh-CN'", timeout=20000)
        self.page.wait_for_function("document.getElementById('link').textContent === '已连接'", timeout=20000)
        self.page.reload()   # the choice is kept in this browser
        self.page.wait_for_function("document.getElementById('link').textContent === '已连接'", timeout=20000)
        self.wait_page("document.querySelector('#status tbody').textContent.includes('电池')", "the status in Chinese")
        header = self.page.inner_text("header")
        self.assertIn("巡检机器人", header)
        self.assertIn("急停", header)
        for panel, words in (("status-panel", "状态"), ("planner-panel", "规划巡检"),
                             ("preset-panel", "本预置位的阈值"), ("patrol-panel", "巡检与历史"),
                             ("alarm-panel", "未确认告警"), ("review-panel", "待复核")):
            self.assertIn(words, self.page.inner_text("#" + panel), panel)
        days = self.page.inner_text("#schedule-days")   # three-letter words escape the check below
        self.assertIn("周一", days)
        self.assertNotIn("mon", days)
        # static words left in English: none but names, units and symbols
        leftovers = self.page.evaluate("""() => {
            const out = [];
            const walker = document.createTreeWalker(document.body, NodeFilter.SHOW_TEXT);
            while (walker.nextNode()) {
                const node = walker.currentNode, text = node.nodeValue.trim();
                const el = node.parentNode;
                const robotWords = '#log, textarea, script, style, #results, #alarm-list, #schedules, #routines,'
                    + ' #planner-catalog, #planner-stops, .u-legend, #patrol-task, select#language';
                if (!text || !el || el.closest(robotWords)) continue;
                if (/[A-Za-z]{4,}/.test(text) && !/[\u4e00-\u9fff]/.test(text)) out.push(text);
            }
            return out; }""")
        self.maxDiff = None
        technical = r"^(control_cmd \w+|presets/\S+|[a-z_/]+\.\w+)$"   # command names, paths, file names
        self.assertEqual([t for t in leftovers if not re.match(technical, t)], [])
        self.shoot_panels("zh-CN")
        for width in (1280, 1920):   # the operator's screens: no horizontal scrolling, in Chinese too
            self.page.set_viewport_size({"width": width, "height": 1000})
            scroll, client = self.page.evaluate("[document.documentElement.scrollWidth, "
                                                "document.documentElement.clientWidth]")
            self.assertLessEqual(scroll, client, "the page is wider than a %d-px window" % width)
            self.page.screenshot(path=os.path.join(SCREENS, "console_zh-CN_%d.png" % width), full_page=True)
        self.page.select_option("#language", "en")   # back to English for whatever runs next in this browser
        self.page.wait_for_function("document.documentElement.lang === 'en'", timeout=20000)
        self.wait_connected()

    def shoot_panels(self, language):
        os.makedirs(SCREENS, exist_ok=True)
        for panel in self.PANELS:
            path = os.path.join(SCREENS, "console_%s_%s.png" % (language, panel))
            self.page.locator("#" + panel).screenshot(path=path)
        self.page.screenshot(path=os.path.join(SCREENS, "console_%s_page.png" % language), full_page=True)

    # ------------------------------------------------------------------ authentication and a dropped link
    def test_7_token_asked_refused_accepted_and_link_loss_shown(self):
        port = bridge_port("rosbridge_auth")
        self.link_errors_expected = True
        sent = []   # every frame the page sends: the token must never be among them
        self.page.on("websocket", lambda ws: ws.on("framesent", lambda payload: sent.append(str(payload))))
        self.open_console(port)
        self.wait_page("document.getElementById('auth').open", "the token dialog")
        self.page.fill("#auth-token", "wrong-token")
        self.page.click("#auth-form button[type=submit]")
        self.wait_page("document.getElementById('auth').open && "
                       "document.getElementById('auth-error').textContent.includes('refused')",
                       "the refusal shown and the token asked again")
        self.page.fill("#auth-token", "console-secret")
        self.page.click("#auth-form button[type=submit]")
        self.wait_connected()
        self.wait_page("document.querySelector('#status tbody').textContent.includes('battery')",
                       "status through the authenticated link")
        auths = [json.loads(frame) for frame in sent if '"op":"auth"' in frame.replace(" ", "")]
        self.assertEqual(len(auths), 2, sent[:5])   # the wrong token's and the right one's, as MACs of nonces
        self.assertEqual(len({a["rand"] for a in auths}), 2)
        self.assertFalse([frame for frame in sent if "console-secret" in frame or "wrong-token" in frame])
        subprocess.check_call(["rosnode", "kill", "/rosbridge_auth"], stdout=subprocess.DEVNULL)
        self.wait_page("document.getElementById('link').textContent.startsWith('disconnected')",
                       "the dropped link shown")


if __name__ == "__main__":
    rostest.rosrun("inspection_robot", "test_console", ConsoleTest)
