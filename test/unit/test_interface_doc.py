"""docs/interface.md stands alone and matches the code: the generated type reference is current,
every command table in the code has a table in the docs with the same names (and the reverse),
every topic, service and action the nodes create is named, and nothing points outside the
repository. Sections and tables this test does not know are left alone."""
import importlib.util
import os
import re

import pytest

from inspection_robot import interface
from inspection_robot.inspection.calibration_commands import CalibrationCommands
from inspection_robot.nav.virtual_obstacles import VirtualObstacles
from inspection_robot.storage.commands import FileCommands

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DOC = os.path.join(ROOT, "docs", "interface.md")
TABLE_HEADER = re.compile(r"^\| ([\w/]+) (cmd|type) \|")
ROS_NAME = re.compile(r"(?:rospy\.(?:Publisher|Subscriber|Service)|SimpleActionServer|CommandTwin\([^,()]+,)"
                      r"\(?\s*\"([\w/]+)\"")


def doc_text():
    with open(DOC) as f:
        return f.read()


def doc_tables():
    """{interface name: [command names]} of every `| <name> cmd |` / `| <name> type |` table."""
    tables, current = {}, None
    for line in doc_text().splitlines():
        header = TABLE_HEADER.match(line)
        if header:
            current = tables.setdefault(header.group(1), [])
        elif current is not None and line.startswith("|"):
            cell = line.split("|")[1].strip().strip("`")
            if not set(cell) <= set("-: "):
                current.append(cell)
        else:
            current = None
    return tables


def code_tables(tmp_path):
    """The command names of every interface, from the code's own tables where they are cheap to build."""
    root = str(tmp_path)
    return {
        "terrace_control": interface.TERRACE_COMMANDS,
        "arm_control": interface.ARM_COMMANDS,
        "camera_control": interface.CAMERA_COMMANDS,
        "infrared_control": interface.INFRARED_COMMANDS,
        "control_cmd": interface.CONTROL_COMMANDS,
        "imu_control": interface.IMU_COMMANDS,
        "mode_cmd": (interface.MODE_CMD_ACQUIRE, interface.MODE_CMD_RELEASE),
        "location_cmd": (interface.LOCATION_CMD_SET,),
        "virtual_obstacle_cmd": VirtualObstacles(None).table.names,
        "move_action": (interface.MOVE_GOAL_TYPE,),
        "find_scale_action": interface.FIND_GOAL_TYPES,
        "file_control": FileCommands(root, ["x"]).table.names,
        "calibration_control": CalibrationCommands(root, ["p"], ["p"], None).table.names,
    }


def test_generated_type_reference_is_current():
    spec = importlib.util.spec_from_file_location("interface_doc", os.path.join(ROOT, "scripts", "interface_doc.py"))
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    text = doc_text()
    assert tool.replace_block(text, tool.section()) == text, "stale: run scripts/interface_doc.py"


def test_every_message_service_and_action_type_is_documented():
    text = doc_text()
    for folder, ext in (("msg", ".msg"), ("srv", ".srv"), ("action", ".action")):
        for name in os.listdir(os.path.join(ROOT, folder)):
            if name.endswith(ext):
                assert "### %s (inspection_robot/%s" % (name[:-len(ext)], name[:-len(ext)]) in text


def test_command_tables_match_the_code(tmp_path):
    documented = doc_tables()
    for name, commands in code_tables(tmp_path).items():
        assert name in documented, "docs/interface.md has no '| %s cmd |' table" % name
        assert sorted(documented[name]) == sorted(commands), name


def test_the_table_parser_sees_a_difference(tmp_path):
    tables = code_tables(tmp_path)
    assert "calibration_control" in doc_tables() and len(tables["calibration_control"]) == 10
    assert sorted(doc_tables()["camera_control"]) != sorted(tables["camera_control"][:-1])


def test_every_topic_service_and_action_of_the_nodes_is_named():
    text = doc_text()
    names = set()
    for folder in ("nodes", "ros"):
        path = os.path.join(ROOT, "src", "inspection_robot", folder)
        for module in os.listdir(path):
            if module.endswith(".py"):
                with open(os.path.join(path, module)) as f:
                    names.update(ROS_NAME.findall(f.read()))
    assert {"mode_ack", "file_control", "move_action", "robot_status"} <= names
    missing = sorted(n for n in names if n not in text)
    assert not missing, "not in docs/interface.md: %s" % ", ".join(missing)


@pytest.mark.parametrize("pattern", [r"INTERFACE\.md", r"/work/", r"spec file", r"\bV3\.0\.1 \(English",
                                     r"\bused to ", r"were dropped", r"before \(main"])
def test_stands_alone_without_history(pattern):
    assert not re.search(pattern, doc_text()), pattern
