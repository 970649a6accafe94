"""Named scenarios of ``kilobot-twin run`` and the world's scenario document (no ROS imports).

The world publishes one JSON document (:func:`world_document`) on a transient-local topic;
robots rebuild exactly the same :class:`~kilobot_twin.core.scenario.Scenario` from it
(:func:`scenario_from_document`), so a node evaluates the same analytic light field as the
batch engine.
"""

from __future__ import annotations

import json
from typing import Any, Mapping


from .scenario import Scenario, scenario_from_dict
from ..errors import ConfigError

#: ``run --scenario NAME``: the scenario dictionaries (duration is set by ``--duration``).
NAMED: dict[str, dict] = {
    # Robots fan out from a common start along their individual heading biases.
    "straight": {"preset": "paper", "behavior": "straight",
                 "start": {"kind": "uniform", "half_width_m": 0.5, "heading_rad": None, "shared": False}},
    # The authors' phototaxis controller climbing the light cone of paper Fig. 5.
    "phototaxis": {"preset": "paper", "behavior": {"kind": "phototaxis", "p_right": 0.5},
                   "start": {"kind": "uniform", "half_width_m": 1.0, "heading_rad": None, "shared": False}},
    # Random walk in a walled 1 m arena (coverage).
    "random_walk": {"behavior": "random_walk", "arena": {"walls": True, "width_m": 1.0, "height_m": 1.0},
                    "start": {"kind": "uniform", "half_width_m": 0.4, "heading_rad": None}},
    # Free-running blinkers on a grid: individual clock rates de-phase them (paper Fig. 9).
    "blink": {"behavior": {"kind": "blink", "half_period_ticks": 31}, "start": {"kind": "grid", "spacing_m": 0.06}},
    # The same blinkers pulled together by Kuramoto coupling to neighbours within 10 cm.
    "sync": {"behavior": {"kind": "blink", "half_period_ticks": 31}, "start": {"kind": "grid", "spacing_m": 0.06},
             "coupling_per_s": 0.5, "neighbour_radius_m": 0.1},
}

DOCUMENT_FORMAT = "kilobot-twin/world-v1"


def named_scenario(name: str, duration_s: float | None = None, field: str = "scenario") -> Scenario:
    """The named scenario, with ``duration_s`` if given (one-line error naming ``field``)."""
    if name not in NAMED:
        raise ConfigError(field, f"unknown scenario {name!r}", f"use one of {', '.join(NAMED)}")
    data = dict(NAMED[name])
    if duration_s is not None:
        if not duration_s > 0:
            raise ConfigError("duration", f"must be positive, got {duration_s}", "give a duration in seconds")
        data["duration_s"] = float(duration_s)
    return scenario_from_dict(data)


def scenario_file(path: str, duration_s: float | None = None, field: str = "scenario_file") -> Scenario:
    """A scenario YAML file (the scenario mapping itself, or a run config with ``scenario:``),
    with ``duration_s`` if given; one-line errors naming ``field``."""
    from pathlib import Path

    from .traits import load_yaml

    if not Path(path).is_file():
        raise ConfigError(field, f"{path}: file not found", "give a scenario YAML path or a named scenario")
    try:
        data = load_yaml(path)
    except ConfigError:
        raise ConfigError(field, f"{path}: not YAML", "give a scenario YAML file") from None
    if isinstance(data, Mapping) and "scenario" in data:
        data = data["scenario"]
    sc = scenario_from_dict(data, source=str(path))
    if duration_s is not None and duration_s > 0:
        sc = sc.replace(duration_s=float(duration_s))
    return sc


def is_scenario_file(name: str) -> bool:
    """``run --scenario`` takes a named scenario or a path to a YAML file."""
    return name not in NAMED and (name.endswith((".yaml", ".yml")) or "/" in name)


def world_document(scenario: Scenario, seed: int, run: int, n_robots: int, mode: str,
                   clock_period_s: float = 1.0) -> str:
    """The JSON the world publishes once (transient-local) for robots and recordings.

    ``clock_period_s``: simulated seconds between a robot's ``clock`` messages (0: every step).
    """
    return json.dumps({"format": DOCUMENT_FORMAT, "scenario": scenario.to_dict(), "seed": int(seed), "run": int(run),
                       "robots": int(n_robots), "mode": mode, "clock_period_s": float(clock_period_s)},
                      sort_keys=True)


def clock_period_from_document(doc: Mapping[str, Any]) -> float:
    """A world document's ``clock_period_s`` (documents without one: every step)."""
    return float(doc.get("clock_period_s", 0.0))


def parse_world_document(text: str) -> dict:
    doc = json.loads(text)
    if not isinstance(doc, Mapping) or doc.get("format") != DOCUMENT_FORMAT:
        raise ConfigError("world/scenario", "not a kilobot-twin world document", f"expected format {DOCUMENT_FORMAT}")
    return dict(doc)


def scenario_from_document(doc: Mapping[str, Any]) -> Scenario:
    return scenario_from_dict(doc["scenario"])


def start_pose(scenario: Scenario, seed: int, run: int, robot_id: int):
    """Start (x, y, theta) of one robot, as the batch engine places it: a function of
    (seed, run, id) only, for every start kind."""
    from . import sim

    return sim.start_poses(scenario, seed, [run], [robot_id])


#: The swarm drawn when no traits file is given (``run`` without ``--traits``): individuals
#: with the spreads measured in the paper (heading bias +-0.04, clock rates 1.5 % apart).
DEFAULT_POPULATION: dict = {
    "heading_bias": {"dist": "uniform", "low": -0.04, "high": 0.04},
    "sigma_omega": 0.02,
    "clock_rate": {"dist": "normal", "mean": 1.0, "sd": 0.015},
}


def load_swarm_traits(path: str, n_robots: int, seed: int, field: str = "traits_file"):
    """Swarm traits from a YAML file (robots: or population:), or drawn from the default population."""
    from .traits import draw_population, load_swarm

    if not path:
        return draw_population({"n": n_robots, **DEFAULT_POPULATION}, seed)
    from pathlib import Path

    if not Path(path).is_file():
        raise ConfigError(field, f"{path}: file not found", "give the path of a traits YAML file")
    return load_swarm(path, seed=seed, n=n_robots)
