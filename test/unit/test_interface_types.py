"""msg/, srv/ and action/ match the type table of INTERFACE.md section 1 (copied in data/)."""
import os
import re

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
TABLE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "interface_types.md")
HEADER_BLOCK = [("Header", "header"), ("string", "sender"), ("string", "receiver"), ("uint32", "trans_id")]
CONTROL_FIELDS_START = "wheel_status"


def parse_definition(text):
    """Fields of a .msg/.srv/.action text as sections of (type, name) pairs."""
    sections = [[]]
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        if line == "---":
            sections.append([])
            continue
        ftype, name = line.split()[:2]
        assert "=" not in name, "constants are not part of the spec: %s" % line
        sections[-1].append((ftype, name))
    return sections


def spec_table():
    rows = {}
    for line in open(TABLE):
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 2 or cells[0] in ("type", "---"):
            continue
        rows[cells[0]] = cells[1]
    return rows


def spec_fields(cell):
    return [tuple(f.split()[:2]) for f in re.findall(r"`([^`]+)`", cell) if len(f.split()) >= 2]


def read(kind, name):
    with open(os.path.join(ROOT, kind, name)) as f:
        return parse_definition(f.read())


def test_every_message_type_matches_the_table():
    rows = spec_table()
    control = spec_fields(rows["ControlStatus"])
    for name, cell in rows.items():
        if "." in name:
            continue
        expected = spec_fields(cell)
        if name == "RobotStatus":
            # "then every ControlStatus field from wheel_status to temperature in the same order"
            start = [n for _, n in control].index(CONTROL_FIELDS_START)
            expected = expected + control[start:]
        (fields,) = read("msg", name + ".msg")
        assert fields == HEADER_BLOCK + expected, name


def test_no_message_beyond_the_table():
    rows = spec_table()
    files = sorted(f[:-4] for f in os.listdir(os.path.join(ROOT, "msg")))
    assert files == sorted(n for n in rows if "." not in n)


def test_control_service():
    request, response = read("srv", "ControlService.srv")
    assert request == HEADER_BLOCK + [("string", "cmd"), ("string", "data")]
    assert response == [("uint32", "trans_id"), ("string", "ack"), ("string", "data")]


def test_general_action():
    goal, result, feedback = read("action", "General.action")
    assert goal == HEADER_BLOCK + [("string", "type"), ("string", "data")]
    assert result == [("string", "ret_code"), ("string", "data")]
    assert feedback == [("string", "event_code"), ("string", "data")]


@pytest.mark.parametrize("name", ["ControlStatus", "RobotStatus", "MoveCmd"])
def test_unit_and_bit_comments_present(name):
    with open(os.path.join(ROOT, "msg", name + ".msg")) as f:
        text = f.read()
    assert "unit" in text or "b0" in text
