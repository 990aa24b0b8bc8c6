"""The code's shape (issue: seams): short functions, no import cycles, one owner per dependency."""
import ast
import os

import pytest

PACKAGE = os.path.join(os.path.dirname(__file__), os.pardir, "sonar_embree")
MAX_FUNCTION_LINES = 80


def _modules():
    for root, _, files in os.walk(PACKAGE):
        for f in files:
            if f.endswith(".py"):
                path = os.path.join(root, f)
                rel = os.path.relpath(path, os.path.dirname(PACKAGE))[:-3].replace(os.sep, ".")
                name = rel[:-len(".__init__")] if rel.endswith(".__init__") else rel
                with open(path, encoding="utf-8") as fh:
                    yield name, path, ast.parse(fh.read())


def _imports(name, tree, is_package, known=frozenset()):
    """Package modules ``name`` imports anywhere (top level or inside functions)."""
    out = set()
    base = name.split(".") if is_package else name.split(".")[:-1]
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            parts = base[:len(base) - (node.level - 1)] if node.level else []
            mod = ".".join(parts + (node.module.split(".") if node.module else [])) if node.level else node.module
            if mod and mod.startswith("sonar_embree"):
                subs = {f"{mod}.{a.name}" for a in node.names}  # from . import x: x may be a module
                out.update(subs)
                if not subs <= known:
                    out.add(mod)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name.startswith("sonar_embree"))
    return out


def test_no_function_is_longer_than_a_screen():
    """Code lines of every function (its docstring aside) fit one screen."""
    long = []
    for name, path, tree in _modules():
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                doc = node.body[0]
                if isinstance(doc, ast.Expr) and isinstance(getattr(doc, "value", None), ast.Constant) \
                        and isinstance(doc.value.value, str):
                    n -= doc.end_lineno - doc.lineno + 1  # the docstring is documentation, not code
                if n > MAX_FUNCTION_LINES:
                    long.append(f"{name}.{node.name}: {n} lines")
    assert not long, long


def test_no_module_imports_a_module_that_imports_it():
    mods = {name: (path, tree) for name, path, tree in _modules()}
    graph = {name: {m for m in _imports(name, tree, path.endswith("__init__.py"), set(mods)) if m in mods and m != name}
             for name, (path, tree) in mods.items()}
    pairs = sorted({tuple(sorted((a, b))) for a, deps in graph.items() for b in deps if a in graph.get(b, ())})
    # a package's __init__ re-exports its own modules; those never import the package itself
    pairs = [p for p in pairs if not (p[1].startswith(p[0] + ".") and p[0] in graph[p[0]] - graph[p[1]])]
    assert not pairs, pairs


@pytest.mark.parametrize("dependency, owner", [("embreex", "sonar_embree.raycast.embree"),
                                                ("numba", "sonar_embree.kernels._numba"),
                                                ("pyproj", "sonar_embree.geo"),
                                                ("pyxtf", "sonar_embree.io.xtf"),
                                                ("rasterio", "sonar_embree.io.geotiff")])
def test_one_owner_per_dependency(dependency, owner):
    users = set()
    for name, _, tree in _modules():
        for node in ast.walk(tree):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else [])
            if any(n.split(".")[0] == dependency for n in names):
                users.add(name)
    assert users == {owner}
