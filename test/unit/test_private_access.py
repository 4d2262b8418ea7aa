"""One wall for internals: outside the compat modules nothing in src/ touches a private attribute of another object.

A private attribute is ``x._y`` (or getattr/setattr/hasattr(x, "_y")) where ``x`` is not ``self``/``cls``.
rospy's, tornado's and rosbag's internals are touched only in ros/compat_rospy.py,
bridge/compat_tornado.py and ros/compat_rosbag.py, each with a public fallback and a test that fails
when they change. What else is allowed says why below; anything new fails this test.
"""
import ast
import os

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SRC = os.path.join(ROOT, "src", "inspection_robot")
COMPAT = {os.path.join("ros", "compat_rospy.py"), os.path.join("bridge", "compat_tornado.py"),
          os.path.join("ros", "compat_rosbag.py")}
# genpy's generated message and service classes: their API, underscored so it cannot clash with a
# field name (rospy, rosbag and rosbridge read them the same way).
GENPY_API = {"_type", "_md5sum", "_full_text", "_has_header", "_slot_types", "_request_class", "_response_class",
             "_connection_header"}
NAMEDTUPLE_API = {"_replace", "_asdict", "_fields", "_make"}   # collections.namedtuple's public methods
# (module, expression): this package's own classes, used by a sibling in the same module.
OWN = {
    (os.path.join("sim", "render.py"), "painter._SCALE"): "sim/render.py's own painter module's fixed-point scale",
}
ACCESSORS = {"getattr", "setattr", "hasattr", "delattr"}


def private_accesses(source, name="<src>"):
    """(line, expression) of every private attribute access in ``source`` on something not self/cls."""
    tree = ast.parse(source, name)
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute):
            attr, owner = node.attr, node.value
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ACCESSORS
              and len(node.args) >= 2 and isinstance(node.args[1], ast.Constant)
              and isinstance(node.args[1].value, str)):
            attr, owner = node.args[1].value, node.args[0]
        else:
            continue
        if not attr.startswith("_") or attr.startswith("__") or attr in GENPY_API | NAMEDTUPLE_API:
            continue
        if isinstance(owner, ast.Name) and owner.id in ("self", "cls"):
            continue
        found.append((node.lineno, "%s.%s" % (ast.get_source_segment(source, owner), attr)))
    return sorted(found)


def test_nothing_outside_the_compat_modules_touches_private_internals():
    offenders = []
    for folder, _dirs, files in os.walk(SRC):
        for filename in sorted(files):
            path = os.path.join(folder, filename)
            rel = os.path.relpath(path, SRC)
            if not filename.endswith(".py") or rel in COMPAT:
                continue
            with open(path) as f:
                source = f.read()
            offenders.extend("%s:%d %s" % (rel, line, expr) for line, expr in private_accesses(source, path)
                             if (rel, expr) not in OWN)
    assert offenders == []


def test_the_compat_modules_exist():
    assert all(os.path.isfile(os.path.join(SRC, rel)) for rel in COMPAT)


def test_the_scan_catches_a_leak():
    source = ("import rospy\n"
              "def f(conn, stream, bag, msg):\n"
              "    self = conn\n"
              "    conn._queue.append(1)\n"
              "    n = getattr(stream, '_read_buffer_size', 0)\n"
              "    bag._get_connections()\n"
              "    return self._ok, msg._type, msg.__class__, msg._replace(a=1)\n")
    assert private_accesses(source) == [(4, "conn._queue"), (5, "stream._read_buffer_size"),
                                        (6, "bag._get_connections")]
