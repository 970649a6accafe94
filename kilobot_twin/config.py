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

Two scales of heading bias, two names. ``heading_bias`` is always the wheel imbalance b the
model applies (paper Eq. 7; as in traits files). ``heading_bias_paper_axis`` is a value on the
paper's heading-bias axis; a run config may use it (in ``swarm.population``, ``swarm.defaults``
or ``swarm.robots.<id>``) and it is converted with the scenario's preset, b = scale x axis
(``paper``: 10, ``argos-code``: 1; see docs/presets.md). A file names one scale or the other, so
it cannot be read on the wrong one; without a preset the paper-axis key is refused.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

from .batch import Campaign
from .core.scenario import PRESETS, bias_axis_scale, preset_traits, scenario_from_dict
from .core.traits import load_swarm, load_yaml, swarm_from_dict
from .errors import ConfigError, is_number, is_whole

RUN_KEYS = {"scenario", "swarm", "seed", "runs", "grid", "record_every", "trials_from_runs"}
#: A heading bias on the paper's axis (converted with the preset's scale); ``heading_bias`` is b.
PAPER_AXIS_KEY = "heading_bias_paper_axis"


def _scale_spec(spec, scale: float):
    """A trait value or a population distribution, multiplied by ``scale`` (non-numbers left for the validator)."""
    num = (lambda v: v * scale if is_number(v, finite=False) else v)
    if not isinstance(spec, Mapping):
        return num(spec)
    out = dict(spec)
    for k in ("value", "low", "high", "mean", "sd"):
        if k in out:
            out[k] = num(out[k])
    if isinstance(out.get("values"), list):
        out["values"] = [num(v) for v in out["values"]]
    return out


def paper_axis_to_wheel(traits: Mapping, preset: str | None, where: str, source: str = "") -> dict:
    """Replace ``heading_bias_paper_axis`` in a traits or population mapping by ``heading_bias`` = scale x axis."""
    if not isinstance(traits, Mapping) or PAPER_AXIS_KEY not in traits:
        return traits
    if "heading_bias" in traits:
        raise ConfigError(f"{where}{PAPER_AXIS_KEY}", "given together with heading_bias",
                          "give one: heading_bias (wheel imbalance b) or heading_bias_paper_axis", source)
    if preset not in PRESETS:
        raise ConfigError(f"{where}{PAPER_AXIS_KEY}", "the paper's axis needs scenario.preset to set its scale",
                          f"add scenario: {{preset: paper}} (b = {bias_axis_scale('paper'):g} x axis) or write "
                          "heading_bias (wheel imbalance b)", source)
    out = {k: v for k, v in traits.items() if k != PAPER_AXIS_KEY}
    out["heading_bias"] = _scale_spec(traits[PAPER_AXIS_KEY], bias_axis_scale(preset))
    return out


def _swarm_on_wheel_scale(doc, preset, source):
    if not isinstance(doc, Mapping):
        return doc
    doc = dict(doc)
    if isinstance(doc.get("population"), Mapping):
        doc["population"] = paper_axis_to_wheel(doc["population"], preset, "swarm.population.", source)
    if isinstance(doc.get("defaults"), Mapping):
        doc["defaults"] = paper_axis_to_wheel(doc["defaults"], preset, "swarm.defaults.", source)
    if isinstance(doc.get("robots"), Mapping):
        doc["robots"] = {k: paper_axis_to_wheel(v, preset, f"swarm.robots.{k}.", source)
                         for k, v in doc["robots"].items()}
    return doc


def _int(data, key, default, source, minimum=0):
    v = data.get(key, default)
    if not is_whole(v) or v < minimum:
        raise ConfigError(key, f"expected an integer >= {minimum}, got {v!r}", f"write e.g. {key}: {max(minimum, 1)}", source)
    return v


def config_from_dict(data: Mapping[str, Any], source: str = "", traits_path: str | None = None,
                     seed: int | None = None, runs: int | None = None, n_robots: int | None = None) -> Campaign:
    """The validated :class:`~kilobot_twin.batch.Campaign` of a run configuration; command-line values
    override the file's."""
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
        preset = sc_data.get("preset") if isinstance(sc_data, Mapping) else None
        doc = _swarm_on_wheel_scale(doc, preset, source)
        if isinstance(doc, Mapping) and isinstance(doc.get("population"), Mapping):
            defaults = preset_traits(preset)
            pop = {**defaults, **doc["population"]}
            if n_robots is not None:
                pop["n"] = n_robots
            doc["population"] = pop
        swarm = swarm_from_dict(doc, seed=seed, n=n_robots if "robots" in (doc or {}) else None, source=source)
    grid = data.get("grid") or {}
    if not isinstance(grid, Mapping) or any(not isinstance(v, list) or not v for v in grid.values()):
        raise ConfigError("grid", "expected a mapping of scenario key: [values]", "write e.g. grid: {behavior.p_right: [0.25, 0.5]}", source)
    trials_from_runs = data.get("trials_from_runs", False)
    if not isinstance(trials_from_runs, bool):  # (bool() of .nan or of the string "false" is True)
        raise ConfigError("trials_from_runs", f"expected true or false, got {trials_from_runs!r}", "write true or false",
                          source)
    cfg = Campaign(scenario, swarm, seed, runs, dict(grid), _int(data, "record_every", 0, source), trials_from_runs)
    for point in cfg.points():  # surface bad grid values now, with their key, rather than inside a worker
        cfg.scenario_at(point)
    if scenario.start.kind == "poses":  # every (run, robot) has its start pose
        scenario.start.pose_table(range(runs), swarm.ids, source)
    return cfg


def load_config(path: str | Path, **overrides) -> Campaign:
    return config_from_dict(load_yaml(path), source=str(path), **overrides)
