"""scripts/runtime_graph.py: the master's view of the launch's nodes drawn as one graph."""
import importlib.util
import os

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SPEC = importlib.util.spec_from_file_location("runtime_graph", os.path.join(ROOT, "scripts", "runtime_graph.py"))
graph = importlib.util.module_from_spec(SPEC)
SPEC.loader.exec_module(graph)

ACTION = ["/move_action/%s" % part for part in ("goal", "cancel", "status", "feedback", "result")]
STATE = [
    [["/robot_status", ["/status_control"]], ["/rosout", ["/status_control"]], ["/x_cmd", ["/rosbridge_websocket"]]]
    + [[t, ["/move_base"]] for t in ACTION[2:]] + [[t, ["/task_manager"]] for t in ACTION[:2]],
    [["/robot_status", ["/task_manager", "/test_node"]], ["/x_cmd", ["/robot_control"]],
     ["/server_only", ["/rosbridge_websocket"]]]
    + [[t, ["/task_manager"]] for t in ACTION[2:]] + [[t, ["/move_base"]] for t in ACTION[:2]],
    [["/charge_control", ["/charge_control"]], ["/task_manager/get_loggers", ["/task_manager"]]],
]
NODES = ["/charge_control", "/move_base", "/robot_control", "/rosbridge_websocket", "/status_control",
         "/task_manager"]


def test_edges_collapse_actions_and_leave_out_clients_logging_and_other_nodes():
    assert graph.graph_edges(STATE, NODES) == sorted([
        (("action", "/move_action"), ("node", "/task_manager")),
        (("node", "/charge_control"), ("service", "/charge_control")),
        (("node", "/move_base"), ("action", "/move_action")),
        (("node", "/status_control"), ("topic", "/robot_status")),
        (("topic", "/robot_status"), ("node", "/task_manager")),
        (("topic", "/x_cmd"), ("node", "/robot_control")),
    ])


def test_dot_keeps_a_service_apart_from_its_namesake_node():
    text = graph.dot_source(graph.graph_edges(STATE, NODES), NODES)
    assert '"node:/charge_control" -> "service:/charge_control";' in text
    assert '"service:/charge_control" [label="/charge_control", shape=diamond];' in text
    assert '"action:/move_action" [label="/move_action", shape=doubleoctagon];' in text
    assert "/test_node" not in text and "/rosout" not in text and "/server_only" not in text
