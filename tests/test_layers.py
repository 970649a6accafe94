"""The layer order is a test (house style): ``core -> batch -> recording -> ros -> nodes -> {viewer,
gap, experiments} -> cli/demo``. Every module of the package has a rank; an import (at module level
or inside a function) may point only to a lower rank or within its own package; no module imports
another module's private names; one module opens MCAP files."""

import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "kilobot_twin"

#: The rank of every top-level package and module (a new one must be placed here).
RANK = {
    "errors": 0, "outputs": 0, "analysis": 0, "core": 0,  # plain NumPy: the model and array helpers
    "batch": 1, "config": 1,  # campaigns and run configurations
    "recording": 2,  # bags and datasets, free of rclpy
    "ros": 3,  # ROS adapters (messages, parameters, the launcher)
    "nodes": 4,
    "plots": 5,  # drawing helpers shared by the next rank
    "viewer": 6, "gap": 6, "experiments": 6,  # siblings: none imports another
    "demo": 7, "cli": 7, "__main__": 8, "__init__": 0,
}
SIBLINGS = {"viewer", "gap", "experiments"}


def _imports(path: Path):
    """(target top-level name, imported names, line) of every import of the package in ``path``."""
    parts = path.relative_to(PKG).with_suffix("").parts
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = list(parts[:-1])[: len(parts) - node.level] if node.level > 1 else list(parts[:-1])
                mod = base + (node.module.split(".") if node.module else [])
            elif (node.module or "").split(".")[0] == "kilobot_twin":
                mod = node.module.split(".")[1:]
            else:
                continue
            names = [a.name for a in node.names]
            target = mod if mod else [names[0]]
            if not mod:  # from . import x, y
                for n in names:
                    yield [n], [], node.lineno
            else:
                yield target, names, node.lineno
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] == "kilobot_twin" and len(a.name.split(".")) > 1:
                    yield a.name.split(".")[1:], [], node.lineno


def _modules():
    return sorted(p for p in PKG.rglob("*.py") if "__pycache__" not in p.parts)


def test_every_module_has_a_rank():
    tops = {p.relative_to(PKG).parts[0].removesuffix(".py") for p in _modules()}
    assert tops <= set(RANK), tops - set(RANK)


def test_imports_point_down_the_layers():
    bad = []
    for path in _modules():
        mine = path.relative_to(PKG).parts[0].removesuffix(".py")
        for target, _names, line in _imports(path):
            top = target[0]
            if top == mine or top not in RANK:
                continue
            if RANK[top] > RANK[mine] or (top in SIBLINGS and mine in SIBLINGS):
                bad.append(f"{path.relative_to(PKG)}:{line} imports {'.'.join(target)} (rank {RANK[top]} >= {RANK[mine]})")
    assert not bad, "\n".join(bad)


def test_no_private_names_across_modules():
    bad = []
    for path in _modules():
        me = list(path.relative_to(PKG).with_suffix("").parts)
        for target, names, line in _imports(path):
            if target == me:
                continue
            bad += [f"{path.relative_to(PKG)}:{line} imports {'.'.join(target)}.{n}" for n in names
                    if n.startswith("_") and not n.startswith("__")]
    assert not bad, "\n".join(bad)


def test_one_module_opens_mcap_files():
    users = []
    for path in _modules():
        for node in ast.walk(ast.parse(path.read_text())):
            mods = [a.name for a in node.names] if isinstance(node, ast.Import) else (
                [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else [])
            if any(m.split(".")[0] == "mcap" for m in mods):
                users.append(str(path.relative_to(PKG)))
    assert sorted(set(users)) == ["recording/bag.py"]


def test_launch_files_import_names_that_exist():
    """launch/*.py run only under `ros2 launch` (launch is not on PyPI): at least what they take
    from the package must exist, so a moved module cannot break them unseen."""
    import importlib

    for path in (PKG.parent / "launch").glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("kilobot_twin"):
                mod = importlib.import_module(node.module)
                for a in node.names:
                    assert hasattr(mod, a.name), f"{path.name}: {node.module}.{a.name}"
