"""The doors a user walks through: a non-editable install from a clean copy of the tree.

Default: a wheel built from a copy (no editable checkout on the path) declares every runtime
dependency (found by scanning the package's imports, not from our list) and, installed with
--target, runs `kilobot-twin run` end to end. Slow: `pip install .` into a fresh virtualenv that
resolves every dependency from the package index, then `kilobot-twin run`.
"""

import ast
import importlib.metadata as md
import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
IGNORE = shutil.ignore_patterns(".git", ".venv", "bags", "build", "install", "log", "__pycache__", "*.egg-info", "out",
                                "results", "dist")


def _clean_copy(tmp_path) -> Path:
    dst = tmp_path / "src"
    shutil.copytree(ROOT, dst, ignore=IGNORE)
    return dst


def _env(**extra) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "AMENT_PREFIX_PATH")}
    env.update(extra)
    return env


def _third_party_imports() -> set[str]:
    """Top-level modules the package imports that are neither stdlib nor the package itself."""
    names = set()
    for path in (ROOT / "kilobot_twin").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names.add(node.module.split(".")[0])
    return {n for n in names if n not in sys.stdlib_module_names and n not in ("kilobot_twin", "__future__")}


def _norm(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _closure(requirements: list[str]) -> set[str]:
    """Distributions installed by ``requirements`` (with their dependencies and the requirements of
    the extras asked for, e.g. ``dask[distributed]``), from this environment's metadata."""
    todo = [(r, ()) for r in requirements]
    seen: set[str] = set()
    while todo:
        req, _ = todo.pop()
        m = re.match(r"\s*([A-Za-z0-9_.\-]+)\s*(?:\[([^\]]*)\])?", req)
        name, extras = _norm(m.group(1)), {e.strip() for e in (m.group(2) or "").split(",") if e.strip()}
        key = name + "[" + ",".join(sorted(extras)) + "]"
        if key in seen:
            continue
        seen.add(key)
        try:
            reqs = md.requires(name) or []
        except md.PackageNotFoundError:
            continue
        for r in reqs:
            marker = re.search(r"extra\s*==\s*['\"]([^'\"]+)['\"]", r)
            if marker is None or marker.group(1) in extras:
                todo.append((r, ()))
    return {k.split("[")[0] for k in seen}


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("wheel")
    src = _clean_copy(tmp)
    res = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w",
                          str(tmp / "dist"), str(src)], capture_output=True, text=True, timeout=300, env=_env())
    assert res.returncode == 0, res.stderr
    return next((tmp / "dist").glob("kilobot_twin-*.whl"))


def test_wheel_holds_every_module_and_declares_every_runtime_dependency(wheel):
    with zipfile.ZipFile(wheel) as z:
        names = set(z.namelist())
        meta = z.read(next(n for n in names if n.endswith(".dist-info/METADATA"))).decode()
    for path in (ROOT / "kilobot_twin").rglob("*.py"):
        assert str(path.relative_to(ROOT)) in names, path  # e.g. kilobot_twin/nodes/robot.py
    assert "kilobot_twin/ros/fastdds.xml" in names
    requires = [ln.split(":", 1)[1].strip() for ln in meta.splitlines() if ln.startswith("Requires-Dist:")]
    provided = _closure(requires)
    dists = md.packages_distributions()
    missing = {mod: dists.get(mod) for mod in _third_party_imports()
               if not any(_norm(d) in provided for d in dists.get(mod, []))}
    assert not missing, f"imported but not installed by install_requires: {missing}"


def test_non_editable_install_runs_the_twin(wheel, tmp_path):
    target = tmp_path / "site"
    res = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target", str(target), str(wheel)],
                         capture_output=True, text=True, timeout=300, env=_env())
    assert res.returncode == 0, res.stderr
    env = _env(PYTHONPATH=str(target))
    where = subprocess.run([sys.executable, "-c", "import kilobot_twin.nodes.robot as m; print(m.__file__)"],
                           capture_output=True, text=True, cwd=tmp_path, env=env, timeout=60)
    assert where.stdout.strip().startswith(str(target)), where.stdout + where.stderr
    run = subprocess.run([sys.executable, "-m", "kilobot_twin", "run", "--scenario", "phototaxis", "--robots", "2",
                          "--duration", "1", "--out", "bags/w"], capture_output=True, text=True, cwd=tmp_path, env=env,
                         timeout=180)
    assert run.returncode == 0, run.stdout + run.stderr
    assert (tmp_path / "bags" / "w" / "metadata.yaml").is_file()


@pytest.mark.slow
def test_pip_install_into_a_fresh_virtualenv_pulls_every_dependency(tmp_path):
    src = _clean_copy(tmp_path)
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=120)
    res = subprocess.run([str(venv / "bin" / "pip"), "install", "-q", str(src)], capture_output=True, text=True,
                         timeout=1800, env=_env())
    assert res.returncode == 0, res.stderr[-3000:]
    run = subprocess.run([str(venv / "bin" / "kilobot-twin"), "run", "--scenario", "phototaxis", "--robots", "2",
                          "--duration", "1", "--out", "bags/v"], capture_output=True, text=True, cwd=tmp_path,
                         env=_env(), timeout=180)
    assert run.returncode == 0, run.stdout + run.stderr
    assert (tmp_path / "bags" / "v" / "metadata.yaml").is_file()
