"""ROS parameters whose defaults come from the core dataclasses, validated at the boundary.

Parameters are declared with dynamic typing so that ``-p clock_rate:=1`` (an integer) is
accepted for a float trait; every value then goes through the core's validators and a bad
one raises :class:`~kilobot_twin.errors.ConfigError` naming the parameter. Node ``main``
functions print that one line and exit with code 2 (:func:`kilobot_twin.ros.executors.run_node`).

Parameters are read-only unless declared otherwise: ``ros2 param set`` on them is refused
(what a node read at start-up would not change). A robot's traits and behaviour can change at
run time (see :class:`~kilobot_twin.nodes.robot.RobotNode`), through the same validators.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from rcl_interfaces.msg import ParameterDescriptor

from ..core import behaviors as B
from ..core.scenario import behavior_from_dict
from ..core.traits import TRAIT_DEFAULTS, TRAIT_NAMES, RobotTraits, traits_from_mapping
from ..errors import ConfigError, is_number, is_whole


def declare(node, name: str, default: Any, description: str = "", read_only: bool = True) -> Any:
    """Declare one parameter (dynamic typing) and return its value."""
    desc = ParameterDescriptor(dynamic_typing=True, description=description, read_only=read_only)
    return node.declare_parameter(name, default, desc).value


def number(node, name: str, default: float, minimum: float | None = None, strict: bool = False) -> float:
    v = declare(node, name, float(default))
    if not is_number(v):
        raise ConfigError(name, f"expected a finite number, got {v!r}", f"e.g. -p {name}:={default}")
    v = float(v)
    if minimum is not None and (v < minimum or (strict and v == minimum)):
        bound = ">" if strict else ">="
        raise ConfigError(name, f"must be {bound} {minimum:g}, got {v:g}", f"e.g. -p {name}:={default}")
    return v


def integer(node, name: str, default: int, minimum: int | None = None) -> int:
    v = declare(node, name, int(default))
    if not is_whole(v):
        raise ConfigError(name, f"expected an integer, got {v!r}", f"e.g. -p {name}:={default}")
    if minimum is not None and v < minimum:
        raise ConfigError(name, f"must be >= {minimum}, got {v}", f"e.g. -p {name}:={default}")
    return v


def text(node, name: str, default: str, choices=None, description: str = "", read_only: bool = True) -> str:
    v = declare(node, name, str(default), description, read_only)
    if not isinstance(v, str):
        raise ConfigError(name, f"expected a string, got {v!r}", f"e.g. -p {name}:={default}")
    if choices is not None and v not in choices:
        shown = ", ".join(repr(c) if c == "" else c for c in choices)
        raise ConfigError(name, f"unknown value {v!r}", f"use one of {shown}")
    return v


def declare_traits(node) -> RobotTraits:
    """One parameter per trait (defaults from :class:`RobotTraits`), validated by the core; settable."""
    values = {}
    for name in TRAIT_NAMES:
        values[name] = declare(node, name, TRAIT_DEFAULTS[name], "robot trait, see kilobot_twin.core.traits.RobotTraits",
                               read_only=False)
    return traits_from_mapping(values)


@dataclasses.dataclass
class BehaviorChoice:
    """What a robot was told about its behaviour: ``kind`` ('' = the world's) and the fields set
    explicitly (``<kind>.<field>`` given as an override or with ``ros2 param set``)."""

    kind: str
    explicit: dict[str, dict[str, Any]]

    def resolve(self, world_behavior) -> Any:
        """The behaviour to run in a world whose scenario runs ``world_behavior``."""
        kind = self.kind or world_behavior.name
        base = behavior_to_values(world_behavior) if kind == world_behavior.name else {"kind": kind}
        return behavior_from_dict({**base, **self.explicit.get(kind, {})}, where=f"{kind}.")

    def with_parameter(self, name: str, value: Any) -> "BehaviorChoice":
        """A copy with one ``behavior`` / ``<kind>.<field>`` parameter changed; the kind's values
        are validated (raises :class:`ConfigError`), what they give in a world by :meth:`resolve`."""
        if name == "behavior":
            if value != "":
                behavior_from_dict({"kind": value, **self.explicit.get(value, {})}, where=f"{value}.")
            return BehaviorChoice(value, self.explicit)
        kind, _, fld = name.partition(".")
        fields = {**self.explicit.get(kind, {}), fld: value}
        behavior_from_dict({"kind": kind, **fields}, where=f"{kind}.")
        return BehaviorChoice(self.kind, {**self.explicit, kind: fields})


def is_behavior_parameter(name: str) -> bool:
    kind, dot, fld = name.partition(".")
    return name == "behavior" or (dot == "." and kind in B.BEHAVIORS)


def declare_behavior(node) -> BehaviorChoice:
    """``behavior`` (the kind; empty: the world's) plus ``<kind>.<field>`` for every behaviour's
    fields (defaults: the core dataclasses'), settable. Every kind's values are validated at once
    (a typo never waits silently); the fields given explicitly are kept for :meth:`BehaviorChoice.resolve`.
    """
    kind = text(node, "behavior", "", choices=[""] + list(B.BEHAVIORS),
                description=f"empty: the world's behaviour; or one of {', '.join(B.BEHAVIORS)}", read_only=False)
    given = set(node._parameter_overrides)  # the names set on the command line or in a params file
    explicit: dict[str, dict[str, Any]] = {}
    for k, cls in B.BEHAVIORS.items():
        values = {f.name: declare(node, f"{k}.{f.name}", f.default, f"behaviour {k}: {f.name}", read_only=False)
                  for f in dataclasses.fields(cls) if f.init}
        behavior_from_dict({"kind": k, **values}, where=f"{k}.")
        explicit[k] = {name: v for name, v in values.items() if f"{k}.{name}" in given}
    return BehaviorChoice(kind, explicit)


def behavior_to_values(behavior) -> dict:
    """``{"kind": ..., field: value}`` of a behaviour (for the ``traits`` record)."""
    d = {f.name: getattr(behavior, f.name) for f in dataclasses.fields(behavior) if f.init}
    return {"kind": behavior.name, **d}


def behavior_overrides(behavior) -> list[tuple[str, Any]]:
    """(parameter name, value) pairs that make a robot node run ``behavior``."""
    vals = behavior_to_values(behavior)
    kind = vals.pop("kind")
    return [("behavior", kind)] + [(f"{kind}.{k}", v) for k, v in vals.items()]
