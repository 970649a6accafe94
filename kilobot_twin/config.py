"""Run configurations: a scenario, a swarm, a seed and a Monte Carlo plan in one YAML file.

```yaml
scenario: {preset: paper, behavior: {kind: phototaxis, p_right: 0.5}}
swarm:                       # a traits document: robots: {...} or population: {...}
  population: {n: 100, heading_bias: {dist: linspace, low: -0.04, high: 0.04}}
seed: 1
runs: 100
grid: {behavior.p_right: [0.25, 0.5, 1.0]}
record_every: 0              # >0 streams trajectories to disk
```

A population inherits the preset's trait defaults (e.g. ``argos-code`` sets
``wheel_noise: 0.5``) unless it names the trait itself.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from .batch import Campaign
from .core.scenario import Scenario, preset_traits, scenario_from_dict
from .core.traits import SwarmTraits, load_swarm, load_yaml, swarm_from_dict
from .errors import ConfigError

RUN_KEYS = {"scenario", "swarm", "seed", "runs", "grid", "record_every", "trials_from_runs"}


@dataclass
class RunConfig:
    scenario: Scenario
    swarm: SwarmTraits
    seed: int = 0
    runs: int = 1
    grid: dict = field(default_factory=dict)
    record_every: int = 0
    trials_from_runs: bool = False
    raw: dict = field(default_factory=dict)

    def campaign(self) -> Campaign:
        return Campaign(self.scenario, self.swarm, self.seed, self.runs, self.grid, self.record_every,
                        self.trials_from_runs)


def _int(data, key, default, source, minimum=0):
    v = data.get(key, default)
    if isinstance(v, bool) or not isinstance(v, int) or v < minimum:
        raise ConfigError(key, f"expected an integer >= {minimum}, got {v!r}", f"write e.g. {key}: {max(minimum, 1)}", source)
    return v


def config_from_dict(data: Mapping[str, Any], source: str = "", traits_path: str | None = None,
                     seed: int | None = None, runs: int | None = None, n_robots: int | None = None) -> RunConfig:
    """Validated :class:`RunConfig`; command-line values override the file's."""
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        raise ConfigError("config", "expected a mapping with scenario:, swarm:, seed:, runs:", "see config/", source)
    for k in data:
        if k not in RUN_KEYS:
            raise ConfigError(str(k), "unknown key", f"use one of {', '.join(sorted(RUN_KEYS))}", source)
    sc_data = data.get("scenario") or {}
    scenario = scenario_from_dict(sc_data, source)
    seed = _int(data, "seed", 0, source) if seed is None else seed
    runs = _int(data, "runs", 1, source, 1) if runs is None else runs
    if traits_path is not None:
        swarm = load_swarm(traits_path, seed=seed, n=n_robots)
    else:
        doc = data.get("swarm")
        if doc is None:
            doc = {"population": {"n": n_robots or 1}}
        doc = dict(doc) if isinstance(doc, Mapping) else doc
        if isinstance(doc, Mapping) and isinstance(doc.get("population"), Mapping):
            defaults = preset_traits(sc_data.get("preset") if isinstance(sc_data, Mapping) else None)
            pop = {**defaults, **doc["population"]}
            if n_robots is not None:
                pop["n"] = n_robots
            doc["population"] = pop
        swarm = swarm_from_dict(doc, seed=seed, n=n_robots if "robots" in (doc or {}) else None, source=source)
    grid = data.get("grid") or {}
    if not isinstance(grid, Mapping) or any(not isinstance(v, list) or not v for v in grid.values()):
        raise ConfigError("grid", "expected a mapping of scenario key: [values]", "write e.g. grid: {behavior.p_right: [0.25, 0.5]}", source)
    cfg = RunConfig(scenario, swarm, seed, runs, dict(grid), _int(data, "record_every", 0, source),
                    bool(data.get("trials_from_runs", False)), dict(data))
    # Surface bad grid values now, with their key, rather than inside a worker.
    cfg.campaign().points() and [cfg.campaign().scenario_at(p) for p in cfg.campaign().points()]
    if scenario.start.kind == "poses":  # every (run, robot) has its start pose
        scenario.start.pose_table(range(runs), swarm.ids, source)
    return cfg


def load_config(path: str | Path, **overrides) -> RunConfig:
    return config_from_dict(load_yaml(path), source=str(path), **overrides)
