"""A script of ``benchmarks/`` (a second generator, the evaluation) as a module, for the tests:
the scripts are not a package, so each is loaded from its file."""

import importlib.util
from pathlib import Path


def load(name: str):
    """The module of ``benchmarks/<name>.py``."""
    spec = importlib.util.spec_from_file_location(name, Path(__file__).parents[2] / "benchmarks" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod
