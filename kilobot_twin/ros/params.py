"""ROS parameters whose defaults come from the core dataclasses, validated at the boundary.

Parameters are declared with dynamic typing so that ``-p clock_rate:=1`` (an integer) is
accepted for a float trait; every value then goes through the core's validators and a bad
one raises :class:`~kilobot_twin.errors.ConfigError` naming the parameter. Node ``main``
functions print that one line and exit with code 2 (:func:`report_and_exit`).
"""

from __future__ import annotations

import dataclasses
import sys
from typing import Any

from rcl_interfaces.msg import ParameterDescriptor

from ..core import behaviors as B
from ..core.scenario import Scenario
from ..core.traits import TRAIT_DEFAULTS, TRAIT_NAMES, RobotTraits, traits_from_mapping
from ..errors import ConfigError

_DYNAMIC = ParameterDescriptor(dynamic_typing=True)


def declare(node, name: str, default: Any, description: str = "") -> Any:
    """Declare one parameter (dynamic typing) and return its value."""
    desc = ParameterDescriptor(dynamic_typing=True, description=description)
    return node.declare_parameter(name, default, desc).value


def number(node, name: str, default: float, minimum: float | None = None, strict: bool = False) -> float:
    v = declare(node, name, float(default))
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ConfigError(name, f"expected a number, got {v!r}", f"e.g. -p {name}:={default}")
    v = float(v)
    if minimum is not None and (v < minimum or (strict and v == minimum)):
        bound = ">" if strict else ">="
        raise ConfigError(name, f"must be {bound} {minimum:g}, got {v:g}", f"e.g. -p {name}:={default}")
    return v


def integer(node, name: str, default: int, minimum: int | None = None) -> int:
    v = declare(node, name, int(default))
    if isinstance(v, bool) or not isinstance(v, int):
        raise ConfigError(name, f"expected an integer, got {v!r}", f"e.g. -p {name}:={default}")
    if minimum is not None and v < minimum:
        raise ConfigError(name, f"must be >= {minimum}, got {v}", f"e.g. -p {name}:={default}")
    return v


def text(node, name: str, default: str, choices=None) -> str:
    v = declare(node, name, str(default))
    if not isinstance(v, str):
        raise ConfigError(name, f"expected a string, got {v!r}", f"e.g. -p {name}:={default}")
    if choices is not None and v not in choices:
        raise ConfigError(name, f"unknown value {v!r}", f"use one of {', '.join(choices)}")
    return v


def declare_traits(node) -> RobotTraits:
    """One parameter per trait (defaults from :class:`RobotTraits`), validated by the core."""
    values = {}
    for name in TRAIT_NAMES:
        v = declare(node, name, TRAIT_DEFAULTS[name], "robot trait, see kilobot_twin.core.traits.RobotTraits")
        values[name] = v
    return traits_from_mapping(values)


def declare_behavior(node) -> Any:
    """``behavior`` (the kind) plus ``<kind>.<field>`` for every behaviour's fields.

    Defaults are the core dataclasses'; only the chosen kind's values are used.
    """
    default_kind = Scenario().behavior.name
    kind = declare(node, "behavior", default_kind, f"one of {', '.join(B.BEHAVIORS)}")
    if kind not in B.BEHAVIORS:
        raise ConfigError("behavior", f"unknown behaviour {kind!r}", f"use one of {', '.join(B.BEHAVIORS)}")
    built = {}
    for k, cls in B.BEHAVIORS.items():
        values = {f.name: declare(node, f"{k}.{f.name}", f.default) for f in dataclasses.fields(cls) if f.init}
        built[k] = behavior_from_values(k, values)  # validate every kind: a typo never waits silently
    return built[kind]


def behavior_from_values(kind: str, values: dict) -> Any:
    cls = B.BEHAVIORS[kind]
    out = {}
    for f in dataclasses.fields(cls):
        if f.name not in values:
            continue
        v = values[f.name]
        if isinstance(f.default, int) and not isinstance(f.default, bool):
            if isinstance(v, float) and v.is_integer():
                v = int(v)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ConfigError(f"{kind}.{f.name}", f"expected a positive integer, got {v!r}", "write e.g. 31")
        elif isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ConfigError(f"{kind}.{f.name}", f"expected a number, got {v!r}", "write a plain number")
        elif v < 0:
            raise ConfigError(f"{kind}.{f.name}", f"must be non-negative, got {v}", "use a value >= 0")
        out[f.name] = float(v) if not isinstance(f.default, int) else v
    if kind == "phototaxis" and not 0.0 <= out.get("p_right", 0.5) <= 1.0:
        raise ConfigError("phototaxis.p_right", f"{out['p_right']} is not a probability", "use a value in [0, 1]")
    return cls(**out)


def behavior_to_values(behavior) -> dict:
    """``{"kind": ..., field: value}`` of a behaviour (for the ``traits`` record)."""
    d = {f.name: getattr(behavior, f.name) for f in dataclasses.fields(behavior) if f.init}
    return {"kind": behavior.name, **d}


def behavior_overrides(behavior) -> list[tuple[str, Any]]:
    """(parameter name, value) pairs that make a robot node run ``behavior``."""
    vals = behavior_to_values(behavior)
    kind = vals.pop("kind")
    return [("behavior", kind)] + [(f"{kind}.{k}", v) for k, v in vals.items()]


def report_and_exit(prog: str, exc: BaseException) -> None:
    """Print the one-line error of a bad parameter and exit with code 2."""
    print(f"{prog}: error: {exc}", file=sys.stderr)
    sys.exit(ConfigError.exit_code)
