"""``ros2msg`` schema text for MCAP, built from the installed interface definitions.

A schema is the type's own ``.msg`` text followed by every type it depends on, each after a
line of 80 ``=`` and ``MSG: pkg/Type`` (the layout rosbag2 and Foxglove use). The ``.msg``
files are found through the ament index (``share/<pkg>/msg/<Type>.msg`` under every
``AMENT_PREFIX_PATH`` entry, then under ``sys.prefix``); types the project
defines itself are read from ``msg_schemas/`` (installed to ``share/kilobot_twin/msg_schemas``).
No rclpy import: bags can be written and repaired without ROS.
"""

from __future__ import annotations

import functools
import os
import re
import sys
from pathlib import Path

PRIMITIVES = {
    "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16", "int32", "uint32",
    "int64", "uint64", "string", "wstring",
}
SEPARATOR = "=" * 80
_REPO_SCHEMAS = Path(__file__).resolve().parents[2] / "msg_schemas"


def _split(type_name: str) -> tuple[str, str]:
    """'geometry_msgs/msg/PoseStamped' or 'geometry_msgs/PoseStamped' -> ('geometry_msgs', 'PoseStamped')."""
    parts = type_name.split("/")
    if len(parts) == 3 and parts[1] == "msg":
        return parts[0], parts[2]
    if len(parts) == 2:
        return parts[0], parts[1]
    raise ValueError(f"not a message type name: {type_name!r}")


def _prefixes() -> list[Path]:
    """Install prefixes to search: the ament index (AMENT_PREFIX_PATH), then this Python's prefix
    (PyPI ROS wheels install ``share/<pkg>`` into the virtual environment without setting it)."""
    out = [Path(p) for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    out.append(Path(sys.prefix))
    return out


@functools.lru_cache(maxsize=None)
def msg_text(type_name: str) -> str:
    """The ``.msg`` definition of a type (raises FileNotFoundError if it is not installed)."""
    pkg, name = _split(type_name)
    candidates = []
    if pkg == "kilobot_twin":
        candidates.append(_REPO_SCHEMAS / f"{name}.msg")
    for prefix in _prefixes():
        share = prefix / "share" / pkg
        candidates += [share / "msg" / f"{name}.msg", share / "msg_schemas" / f"{name}.msg"]
    for c in candidates:
        if c.is_file():
            return c.read_text()
    raise FileNotFoundError(f"no .msg definition found for {type_name}")


def field_types(text: str, pkg: str) -> list[str]:
    """Fully qualified complex types (``pkg/Type``) used by the fields of a ``.msg`` text."""
    out = []
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        tokens = line.split()
        if len(tokens) < 2 or "=" in tokens[1] or (len(tokens) > 2 and tokens[2].startswith("=")):
            continue  # constants
        base = re.sub(r"\[.*\]$", "", tokens[0])
        base = re.sub(r"<=\d+$", "", base)
        if base in PRIMITIVES:
            continue
        if "/" in base:
            p, n = _split(base)
            out.append(f"{p}/{n}")
        elif base == "Header":
            out.append("std_msgs/Header")
        else:
            out.append(f"{pkg}/{base}")
    return out


@functools.lru_cache(maxsize=None)
def ros2msg_schema(type_name: str) -> str:
    """The full ``ros2msg`` schema (type text + dependencies, depth first, each once)."""
    pkg, name = _split(type_name)
    main = msg_text(type_name)
    seen: list[str] = []

    def visit(t: str):
        p, _ = _split(t)
        for dep in field_types(msg_text(t), p):
            if dep not in seen:
                seen.append(dep)
                visit(dep)

    visit(f"{pkg}/{name}")
    parts = [main.rstrip("\n")]
    for dep in seen:
        parts.append(f"{SEPARATOR}\nMSG: {dep}\n{msg_text(dep).rstrip(chr(10))}")
    return "\n".join(parts) + "\n"
