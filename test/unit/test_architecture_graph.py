"""docs/architecture.dot (the picture in docs/development.md, "Architecture") is the package's current import graph."""
import importlib.util
import os

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def load_tool():
    spec = importlib.util.spec_from_file_location("import_graph", os.path.join(ROOT, "scripts", "import_graph.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_architecture_picture_is_current():
    tool = load_tool()
    with open(tool.DOT_FILE) as f:
        assert f.read() == tool.dot_source(), "docs/architecture.dot is stale: run scripts/import_graph.py"


def test_pure_folders_import_neither_the_ros_wing_nor_sim():
    tool = load_tool()
    bad = [(a, b) for a, b in tool.edges()
           if not tool.is_wing(a) and (tool.is_wing(b) or (b == "sim" and a != "sim"))]
    assert bad == []


def test_the_top_level_imports_only_the_top_level():
    """interface, command, files ... are what every capability shares: they import no capability."""
    tool = load_tool()
    assert [(a, b) for a, b in tool.edges() if a == tool.CORE] == []


def test_no_folder_imports_back_up():
    """The folder graph has no cycle: every chain of imports ends in the core or ROS."""
    tool = load_tool()
    graph = {}
    for a, b in tool.edges():
        graph.setdefault(a, set()).add(b)
    done, cycles = set(), []

    def visit(box, path):
        for nxt in sorted(graph.get(box, ())):
            if nxt in path:
                cycles.append(path[path.index(nxt):] + [nxt])
            elif nxt not in done:
                visit(nxt, path + [nxt])
        done.add(box)
    for box in sorted(graph):
        visit(box, [box])
    assert cycles == []
