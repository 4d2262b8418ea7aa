#!/usr/bin/env python3
"""Flags test functions that cannot fail: no assertion, no expected exception, no call to a helper
that asserts. Usage: check_tests.py FILE... (exit 1 and one line per culprit when any is found).

A function "asserts" when its body has an ``assert``, raises AssertionError, calls ``self.assert*``
/ ``self.fail`` / ``pytest.raises`` / ``pytest.fail``, or calls (by name, as a function or a method)
a function of the same file or of the test helper modules that asserts; resolved by name to a fixed
point, so a helper calling a helper that asserts counts.
"""
import ast
import os
import sys

HELPER_MODULES = ("rostest_helpers.py", "bridge_fakes.py", "conftest.py")
ASSERTING_CALLS = {"raises", "fail", "approx_equal"}


def _called_name(call):
    func = call.func
    if isinstance(func, ast.Name):
        return func.id
    if isinstance(func, ast.Attribute):
        return func.attr
    return None


def _asserts_directly(func):
    for node in ast.walk(func):
        if isinstance(node, ast.Assert):
            return True
        if isinstance(node, ast.Raise) and node.exc is not None:
            exc = node.exc.func if isinstance(node.exc, ast.Call) else node.exc
            if isinstance(exc, ast.Name) and exc.id == "AssertionError":
                return True
        if isinstance(node, ast.Call):
            name = _called_name(node)
            if name and (name.startswith("assert") or name in ASSERTING_CALLS):
                return True
    return False


def _calls(func):
    return {_called_name(node) for node in ast.walk(func) if isinstance(node, ast.Call)} - {None}


def _functions(tree):
    return [node for node in ast.walk(tree) if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))]


def asserting_names(trees):
    """Names of the functions (anywhere in ``trees``) that assert, directly or through others."""
    functions = [f for tree in trees for f in _functions(tree)]
    names = {f.name for f in functions if _asserts_directly(f)}
    changed = True
    while changed:
        changed = False
        for f in functions:
            if f.name not in names and _calls(f) & names:
                names.add(f.name)
                changed = True
    return names


def culprits(path, helper_trees):
    with open(path) as source:
        tree = ast.parse(source.read(), path)
    names = asserting_names([tree] + helper_trees)
    for func in _functions(tree):
        if func.name.startswith("test") and func.name not in names:
            yield "%s:%d: %s has no assertion, expected exception or asserting helper" % (
                path, func.lineno, func.name)


def main(paths):
    helpers = []
    for folder in sorted({os.path.dirname(p) for p in paths}):
        for name in HELPER_MODULES:
            helper = os.path.join(folder, name)
            if os.path.exists(helper):
                with open(helper) as source:
                    helpers.append(ast.parse(source.read(), helper))
    found = [line for path in paths for line in culprits(path, helpers)]
    for line in found:
        print(line)
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
