"""inspection_robot.site.check: the site check refuses every unset, misspelt or simulated-yard setting,
all in one list; the template config/robot.example.yaml passes once its files exist."""
import copy
import os

import pytest
import yaml

from inspection_robot.drivers import DEVICES
from inspection_robot.site.check import (SiteError, flatten, format_problems, load_site_text, sim_yard,
                                         site_problems)
from inspection_robot_testing.site_files import template_site

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
# The nodes robot.launch runs and the config files each loads (the tool takes this from roslaunch;
# test_check_site.py checks that both agree).
NODE_FILES = {node: [node] for node in (
    "status_control", "robot_voice", "robot_control", "joy_control", "rosbridge_websocket", "cloud_terrace",
    "robot_arm", "camera_node", "infrared_imager", "move_base", "obstacle_detector", "preset_scale",
    "find_scale", "read_scale", "charge_control", "file_server", "task_manager", "pose_adapter")}


def _yaml(name):
    with open(os.path.join(ROOT, "config", name)) as f:
        return yaml.safe_load(f) or {}


def package_defaults():
    defaults = {"data_root": "/var/lib/inspection_robot", "joystick_reader/device": "/dev/input/js0"}
    for node, files in NODE_FILES.items():
        for name in files:
            defaults.update(flatten(_yaml(name + ".yaml"), node + "/"))
    return defaults


def yard():
    with open(os.path.join(ROOT, "config", "sim_site.yaml")) as f:
        text = f.read().replace("$(find inspection_robot)", ROOT)
    return sim_yard(load_site_text(text, "sim_site.yaml"))


@pytest.fixture
def site(tmp_path):
    """config/robot.example.yaml with its map, token and password files made in tmp_path."""
    return template_site(str(tmp_path))


def problems(site, **kwargs):
    return site_problems(site, package_defaults(), yard(), **kwargs)


def test_template_passes_once_its_files_exist(site):
    assert problems(site) == []


def test_no_site_file_lists_every_setting_at_once():
    found = problems({})
    text = "\n".join(found)
    for entry in DEVICES.values():
        assert "%s/driver is not set" % entry.node in text
    for name in ("move_base/map_file", "move_base/pose_topic", "move_base/init_pose", "task_manager/home_pose",
                 "charge_control/dock", "rosbridge_websocket/auth_token_file"):
        assert "%s is not set" % name in text
    assert "data_root is not set: the robot's state directory" in text
    assert len(found) == len(DEVICES) + 7


def test_typo_in_a_key_is_named_with_the_nearest_setting(site):
    site["move_base"]["robot_radus"] = 0.5
    site["movebase"] = {"pose_topic": "amcl_pose"}
    site["charge_control"]["dock"]["tolerance_mm"] = 0.02
    site["robot_control"]["ros_base"]["odom_topc"] = "odom"
    found = problems(site)
    assert "move_base/robot_radus: unknown setting (did you mean move_base/robot_radius?)" in found
    assert any(p.startswith("movebase: unknown node in the site file (did you mean move_base?)") for p in found)
    assert "charge_control/dock: dock.tolerance_mm: unknown field (dock has pose, approach_pose, tolerance_m, " \
           "tolerance_yaw)" in found
    assert any(p.startswith("robot_control/ros_base/odom_topc: unknown setting (did you mean "
                            "robot_control/ros_base/odom_topic?)") for p in found)
    assert len(found) == 4, found


def test_the_simulated_yards_dock_is_where_the_simulated_chassis_charges():
    """sim.launch gives charge_control the dock of config/sim_site.yaml, the chassis simulator charges on
    world.dock of config/sim_world.yaml: one dock, so the robot docks where the simulator charges it."""
    assert yard()["charge_control/dock"] == _yaml("sim_world.yaml")["world"]["dock"]
    assert not [name for name in yard() if name.startswith("charge_control/dock/")]


def test_simulated_yard_values_are_refused(site, tmp_path):
    sim = yard()
    site["move_base"]["map_file"] = sim["move_base/map_file"]
    site["move_base"]["pose_topic"] = "sim/true_pose"
    site["move_base"]["init_pose"] = list(sim["move_base/init_pose"])
    site["task_manager"]["home_pose"] = list(sim["task_manager/home_pose"])
    site["charge_control"]["dock"] = copy.deepcopy(sim["charge_control/dock"])
    site["obstacle_detector"]["cloud_topic"] = "/robot_7/sim/obstacle_cloud"
    found = problems(site)
    assert "move_base/map_file is the simulated yard's map (%s): give the site's map" % sim["move_base/map_file"] \
        in found
    assert "move_base/pose_topic is 'sim/true_pose', a simulator's topic: give the real robot's topic" in found
    assert "move_base/init_pose is the simulated yard's (config/sim_site.yaml): give the site's pose" in found
    assert "task_manager/home_pose is the simulated yard's (config/sim_site.yaml): give the site's pose" in found
    assert any(p.startswith("charge_control/dock is the simulated yard's dock") for p in found)
    assert any(p.startswith("obstacle_detector/cloud_topic is '/robot_7/sim/obstacle_cloud'") for p in found)
    assert len(found) == 6, found


def test_a_copy_of_the_simulated_map_is_refused(site, tmp_path):
    copy_dir = tmp_path / "copy"
    copy_dir.mkdir()
    for name in ("substation.yaml", "substation.pgm"):
        (copy_dir / name).write_bytes(open(os.path.join(ROOT, "config", "maps", name), "rb").read())
    site["move_base"]["map_file"] = str(copy_dir / "substation.yaml")
    assert any(p.startswith("move_base/map_file is the simulated yard's map") for p in problems(site))


def test_simulators_and_missing_driver_settings(site):
    site["robot_control"]["driver"] = "sim"
    del site["cloud_terrace"]["port"]
    del site["infrared_imager"]["isapi"]["host"]
    found = problems(site)
    assert any(p.startswith("robot_control/driver is sim: robot.launch drives real devices only") for p in found)
    assert "cloud_terrace/port is not set (the head driver pelco needs it; the default '/dev/ttyUSB0' is an " \
           "example)" in found
    assert any(p.startswith("infrared_imager/isapi/host is not set") for p in found)
    assert len(found) == 3, found


def test_malformed_values_are_refused(site, tmp_path):
    site["move_base"]["map_file"] = str(tmp_path / "missing.yaml")
    site["task_manager"]["home_pose"] = [1.0, 2.0]
    site["move_base"]["init_pose"] = [1.0, "north", 0.0]
    site["charge_control"]["dock"]["approach_pose"] = site["charge_control"]["dock"]["pose"]
    site["data_root"] = "var/lib/robot"
    os.chmod(site["rosbridge_websocket"]["auth_token_file"], 0o644)
    found = problems(site)
    assert any(p.startswith("move_base/map_file: cannot read map %s" % (tmp_path / "missing.yaml")) for p in found)
    assert "task_manager/home_pose must be [x, y, yaw], got [1.0, 2.0]" in found
    assert "move_base/init_pose must be three finite numbers, got [1.0, 'north', 0.0]" in found
    assert any(p.startswith("charge_control/dock: dock.approach_pose must be") for p in found)
    assert "data_root must be an absolute path, got 'var/lib/robot'" in found
    assert any("auth_token_file" in p and "accessible by group/others (mode 644)" in p for p in found)
    assert len(found) == 6, found


@pytest.mark.parametrize("language", ["fr", "zh", "", None, ["zh-CN"]])
def test_a_language_that_does_not_exist_is_refused(site, language):
    site["language"] = language
    assert problems(site) == ["language must be one of zh-CN|en, got %r (top-level in the site file: the console's, "
                              "the report's and the voice's)" % (language,)]
    site["language"] = "en"
    assert problems(site) == []


def test_insecure_needs_no_token_and_a_data_root_argument_counts(site):
    del site["rosbridge_websocket"]
    del site["data_root"]
    assert problems(site, insecure=True, data_root_arg="/srv/robot") == []
    assert [p.split(" ")[0] for p in problems(site)] == ["data_root", "rosbridge_websocket/auth_token_file"]


def test_plugin_keyword_arguments_are_free_form(site):
    site["robot_arm"] = {"driver": "vendor_arm.driver:Arm", "driver_params": {"port": "/dev/ttyS3", "any_key": 1}}
    assert problems(site) == []


def test_pose_adapter_on_for_a_tf_localizer_with_move_base_reading_its_output(site):
    site["pose_adapter"] = {"mode": "tf", "map_frame": "map", "base_frame": "base_footprint"}
    site["move_base"]["pose_topic"] = "/localization/pose"
    assert problems(site) == []
    site["pose_adapter"] = {"mode": "topic", "input_topic": "robot_pose", "output_topic": "localization/pose"}
    site["move_base"]["pose_topic"] = "localization/pose"
    assert problems(site) == []


@pytest.mark.parametrize("adapter, pose_topic, expected", [
    ({"mode": "amcl"}, "amcl_pose",
     "pose_adapter/mode must be one of none|topic|tf, got 'amcl' (none: move_base reads the localizer's topic; "
     "tf: a localizer with TF map -> base_link only; topic: republish input_topic)"),
    ({"mode": None}, "amcl_pose", "pose_adapter/mode must be one of none|topic|tf, got None"),
    ({"mode": "tf"}, "amcl_pose",
     "move_base/pose_topic is 'amcl_pose' but pose_adapter/mode is tf: move_base must read the adapter's output, "
     "set move_base/pose_topic: localization/pose (pose_adapter/output_topic)"),
    ({"mode": "none"}, "localization/pose",
     "move_base/pose_topic is 'localization/pose', pose_adapter's output, but pose_adapter/mode is none: nothing "
     "publishes it"),
    ({"mode": "topic"}, "localization/pose",
     "pose_adapter/input_topic is not set (pose_adapter/mode topic republishes it; the default 'amcl_pose' is an "
     "example)"),
    ({"mode": "topic", "input_topic": "localization/pose"}, "localization/pose",
     "pose_adapter/input_topic and pose_adapter/output_topic are both 'localization/pose': the adapter would feed "
     "itself"),
    ({"mode": "tf", "rate": 0}, "localization/pose", "pose_adapter/rate must be a positive number, got 0"),
    ({"mode": "topic", "input_topic": "sim/localization/pose"}, "localization/pose",
     "pose_adapter/input_topic is 'sim/localization/pose', a simulator's topic: give the real robot's topic"),
    ({"mode": "tf", "base_frme": "base_link"}, "localization/pose",
     "pose_adapter/base_frme: unknown setting (did you mean pose_adapter/base_frame?)"),
])
def test_pose_adapter_settings_are_checked_by_name(site, adapter, pose_topic, expected):
    site["pose_adapter"] = adapter
    site["move_base"]["pose_topic"] = pose_topic
    found = problems(site)
    assert len(found) == 1 and found[0].startswith(expected), found


def test_site_file_text_errors_name_the_file_and_line():
    with pytest.raises(SiteError, match=r"site\.yaml is not valid YAML: .*'move_base' given twice.*line 3"):
        load_site_text("move_base: {pose_topic: a}\ndata_root: /x\nmove_base: {init_pose: [1, 2, 3]}\n", "site.yaml")
    with pytest.raises(SiteError, match="must be a mapping keyed by node name, got list"):
        load_site_text("- move_base\n", "site.yaml")
    assert load_site_text("# nothing yet\n", "site.yaml") == {}


def test_one_message_lists_every_problem():
    text = format_problems(["a is not set", "b is sim"], "/etc/inspection_robot/robot.yaml")
    assert text.startswith("robot.launch refused to start, 2 site setting(s) to fix in /etc/inspection_robot/"
                           "robot.yaml ")
    assert text.endswith("\n  - a is not set\n  - b is sim")


@pytest.mark.parametrize("settings, expected", [
    ({"auth_token": "x"}, "rosbridge_websocket: set rosbridge_websocket/auth_token_file or "
                          "rosbridge_websocket/auth_token, not both"),
    ({"allowed_origins": "https://backend:8443"}, "rosbridge_websocket: rosbridge_websocket/allowed_origins must be "
                                                  "a list of origins"),
    ({"client_ca": "/etc/robot/ca.pem"}, "rosbridge_websocket: rosbridge_websocket/client_ca needs"),
    ({"surface": "open"}, "rosbridge_websocket/surface is 'open': a robot serves the backend surface only"),
    ({"surface": "wide"}, "rosbridge_websocket: rosbridge_websocket/surface must be one of robot, sim, open"),
])
def test_settings_the_bridge_would_refuse_at_every_respawn_stop_the_launch(site, settings, expected):
    site["rosbridge_websocket"].update(settings)
    found = problems(site)
    assert any(p.startswith(expected) for p in found), found
    assert len(found) == 1, found
