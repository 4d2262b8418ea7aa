"""fixed_settings: security settings and data paths from the defaults file, the site file, the command
line and the launch's environment only."""
import pytest
import yaml

from inspection_robot.fixed_settings import (DATA_ROOT_ENV, SITE_FILE_ENV, FixedSettingsError, StartupFiles,
                                             fixed_settings, overridden, split_argv)


def write(tmp_path, name, data):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return str(path)


def test_defaults_then_site_file_then_command_line(tmp_path):
    defaults = write(tmp_path, "d.yaml", {"address": "127.0.0.1", "auth_token": "", "insecure": False, "port": 9090})
    site = write(tmp_path, "site.yaml", {"rosbridge_websocket": {"auth_token_file": "/etc/robot/token",
                                                                 "address": "10.0.0.5", "port": 1}})
    fixed = fixed_settings("rosbridge_websocket", ["--site-file", site, "_address:=0.0.0.0", "__name:=x",
                                                   "_surface:=robot", "mode_cmd:=other"], defaults)
    assert fixed == {"address": "0.0.0.0", "auth_token": "", "insecure": False, "auth_token_file": "/etc/robot/token",
                     "surface": "robot", "site_file": site, "data_root": ""}   # port is not a security setting


def test_the_launch_names_the_site_file_and_data_root_in_the_environment(tmp_path):
    site = write(tmp_path, "site.yaml", {"camera_node": {"roots": ["/srv/captures"]}})
    env = {SITE_FILE_ENV: site, DATA_ROOT_ENV: "/var/lib/inspection_robot"}
    files = StartupFiles("camera_node", [], write(tmp_path, "camera_node.yaml", {"roots": ["captures"]}), env)
    assert files.launched and files.get("roots") == ["/srv/captures"]
    assert files.data_root() == "/var/lib/inspection_robot"
    alone = StartupFiles("camera_node", [], None, {})
    assert not alone.launched and alone.data_root() == "" and alone.get("roots", ["x"]) == ["x"]


def test_the_site_files_data_root_wins_as_core_launch_loads_it_last(tmp_path):
    site = write(tmp_path, "site.yaml", {"data_root": "/var/lib/robot", "file_server": {"roots": ["tasks"]}})
    files = StartupFiles("file_server", ["--site-file=" + site, "_data_root:=/tmp/x"], None, {DATA_ROOT_ENV: "/e"})
    assert files.data_root() == "/var/lib/robot" and files.get("roots") == ["tasks"]
    assert StartupFiles("file_server", ["_data_root:=/tmp/x"], None, {DATA_ROOT_ENV: "/e"}).data_root() == "/tmp/x"


def test_a_parameter_server_write_is_named_not_taken(tmp_path):
    fixed = fixed_settings("rosbridge_websocket", ["_insecure:=false", "_auth_token:=s"], None)
    assert overridden(fixed, {"insecure": True, "auth_token": "s", "port": 1}) == ["insecure"]


def test_unreadable_files_and_bad_values_fail_loudly(tmp_path):
    with pytest.raises(FixedSettingsError, match="cannot read site file"):
        fixed_settings("rosbridge_websocket", ["--site-file", str(tmp_path / "missing.yaml")], None)
    bad = tmp_path / "bad.yaml"
    bad.write_text("- a list\n")
    with pytest.raises(FixedSettingsError, match="is not a YAML mapping"):
        fixed_settings("rosbridge_websocket", [], None, {SITE_FILE_ENV: str(bad)})
    with pytest.raises(FixedSettingsError, match="not YAML"):
        fixed_settings("rosbridge_websocket", ["_allowed_origins:=[unclosed"], None)


def test_an_empty_site_file_argument_means_none():
    assert split_argv(["--site-file", "", "_x:=1", "__ns:=/r"]) == ("", {"x": "1"})
