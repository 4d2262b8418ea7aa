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
