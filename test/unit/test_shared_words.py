"""One truth per shared word (#32): the words of task_manager's interface that several modules read
(task states, reading statuses, alarm states: task/states.py) and the spec's ack words (success,
failed, busy, unsupported: interface.py) appear as string literals nowhere else in src/; every
module imports them. A literal that only coincides with one of them (another
vocabulary: set_level's "none", a driver named "none", the charge machine's own states, a JSON key
name) is listed below with the reason; anything else fails with the file and line."""
import ast
import os

from inspection_robot import interface
from inspection_robot.task import states

SRC = os.path.join(os.path.dirname(__file__), "..", "..", "src", "inspection_robot")
WORDS = {value: name for name, value in vars(states).items()
         if name.isupper() and isinstance(value, str) and name.split("_")[0] in ("STATE", "STATUS", "ALARM")}
OWNERS = {word: {"task/states.py"} for word in WORDS}
for _name in ("ACK_SUCCESS", "ACK_FAILED", "BUSY", "UNSUPPORTED"):
    WORDS.setdefault(getattr(interface, _name), _name)
    OWNERS.setdefault(getattr(interface, _name), set()).add("interface.py")

# (file under src/inspection_robot, word): why the literal is not one of task_manager's words
COINCIDENCES = {
    ("bridge/protocol.py", "none"): "rosbridge's status levels (set_level none)",
    ("bridge/ops.py", "none"): "rosbridge's compression none (the op table's default)",
    ("bridge/session_topics.py", "none"): "rosbridge's compression none",
    ("nodes/rosbridge_websocket.py", "none"): "rosbridge's status levels",
    ("bridge/ros_backend.py", "none"): "rosbridge's compression none",
    ("drivers.py", "none"): "a device fitted with no driver",
    ("nav/pose_adapter.py", "none"): "pose_adapter's mode: nothing to adapt",
    ("ptz/driver.py", "none"): "a Pelco-D head without a driver",
    ("sim/pelco_head.py", "none"): "the simulated head's fault name",
    ("recording/ros_bag_reading.py", "none"): "bag_report's text for no value",
    ("tools/bag_report.py", "none"): "bag_report's text for no value",
    ("charge/states.py", "idle"): "charge_status's own states (docs/interface.md, charge_control)",
    ("charge/states.py", "failed"): "charge_status's own states",
    ("nav/follower.py", "done"): "the path follower's phase",
    ("nodes/find_scale.py", "cancelled"): "an action goal's end, not a task's",
    ("nodes/move_base.py", "cancelled"): "an action goal's end, not a task's",
    ("inspection/reading.py", "uncertain"): "read_scale's result word (the ack text), which the store's status mirrors",
    ("task/patrol.py", "failed"): "a step's outcome (OUTCOME_FAILED)",
    ("task/patrol.py", "done"): "a task_status key name (FINAL_PROGRESS_KEYS)",
    ("task/action.py", "done"): "a task_action feedback key name",
    ("task/store.py", "alarm"): "a results column name",
    ("task/service.py", "read"): "a step timing's name",
    ("task/report_html.py", "read"): "a summary tile's label (the count of read values)",
    ("bridge/trace.py", "read"): "the echo trace's first stage (a frame read), not a reading's status",
    ("bridge/handler.py", "read"): "the echo trace's stage name (bridge/trace.py)",
    ("interface.py", "read"): "file_control's read command (READ_ONLY_COMMANDS)",
    ("ros/compat_rospy.py", "done"): "rospy's Transport attribute named done",
    ("task/report_html.py", "failed"): "a summary tile's label",
    ("task/report_html.py", "uncertain"): "a summary line's label",
    ("task/spec.py", "normal"): "a key of a task's limits object (LIMIT_KEYS)",
    ("task/spec.py", "alarm"): "a key of a task's limits object (LIMIT_KEYS)",
    ("inspection/calibration_schema.py", "normal"): "the calibration key normal (the band), not the alarm state",
    ("bridge/protocol.py", "warning"): "rosbridge's status level warning",
    ("bridge/ros_tcpros.py", "warning"): "the bridge's log level warning",
    ("bridge/server.py", "warning"): "the bridge's log level warning",
    ("bridge/session_services.py", "warning"): "rosbridge's status level warning",
    ("bridge/session_topics.py", "warning"): "rosbridge's status level warning",
}


def _key_constants(tree):
    """ids of string constants used as keys: dict literal keys, subscripts, .get/.pop/.setdefault's key."""
    keys = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Dict):
            keys.update(id(k) for k in node.keys if k is not None)
        elif isinstance(node, ast.Subscript):
            index = node.slice
            keys.add(id(index.value if type(index).__name__ == "Index" else index))   # ast.Index up to Python 3.8
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.args \
                and node.func.attr in ("get", "pop", "setdefault"):
            keys.add(id(node.args[0]))
    return keys


def literals():
    """(file, line, word) of every literal equal to a shared word outside its owner."""
    found = []
    for folder, _dirs, files in os.walk(SRC):
        for name in sorted(files):
            path = os.path.join(folder, name)
            rel = os.path.relpath(path, SRC).replace(os.sep, "/")
            if not name.endswith(".py"):
                continue
            with open(path) as f:
                tree = ast.parse(f.read(), path)
            keys = _key_constants(tree)
            for node in ast.walk(tree):
                if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in WORDS \
                        and id(node) not in keys and rel not in OWNERS[node.value]:
                    found.append((rel, node.lineno, node.value))
    return found


def test_shared_words_are_imported_not_written_again():
    assert len(WORDS) >= 15   # the table really holds the states, statuses and alarms
    stray = ["%s:%d %r: import %s from %s" % (rel, line, word, WORDS[word], " or ".join(sorted(OWNERS[word])))
             for rel, line, word in literals() if (rel, word) not in COINCIDENCES]
    assert stray == []


def test_every_listed_coincidence_still_exists():
    present = {(rel, word) for rel, _line, word in literals()}
    assert sorted(set(COINCIDENCES) - present) == []   # a stale entry would hide a future literal
