"""Individuality as data: per-robot traits, swarms of them, populations that draw them.

A robot's individuality is one frozen :class:`RobotTraits`; a swarm's is one array per trait
(:class:`SwarmTraits`). Both load from and save to YAML; every value is validated at that
boundary with a one-line :class:`~kilobot_twin.errors.ConfigError` naming the field.

Sign convention (as in the paper's figures): ``heading_bias > 0`` makes the robot curve to the
right, i.e. clockwise seen from above; negative curves left (counter-clockwise).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..errors import ConfigError, is_number, is_whole
from . import rng as _rng


@dataclass(frozen=True)
class RobotTraits:
    """The individual parameters of one Kilobot.

    Attributes
    ----------
    heading_bias : float
        Dimensionless wheel imbalance b (paper Eq. 7, as a fraction of the commanded wheel
        speed): the left wheel runs at ``(1 + b/2)``, the right at ``(1 - b/2)`` times its
        command, so driving straight at speed v the robot turns clockwise at
        ``b * v / 0.025 m`` rad/s and draws a circle of radius ``0.025 m / |b|``.
    speed_factor : float
        Multiplies both wheel speeds (per-robot speed heterogeneity).
    sigma_v : float
        White-noise intensity on forward speed, m/sqrt(s) (paper Eq. 5, eta_v): the path length
        over time t has variance ``sigma_v**2 * t``. Applied only while a wheel is driven.
    sigma_omega : float
        White-noise intensity on turn rate, rad/sqrt(s) (paper Eq. 5, eta_omega): the heading
        of a robot driving straight diffuses with variance ``sigma_omega**2 * t``.
    wheel_noise : float
        Half-width a of the authors' simulator's per-tick multiplicative wheel noise: each
        wheel's speed is multiplied by ``1 + U``, U uniform on [-a, a], drawn every step.
    bias_trial_sd : float
        Trial-to-trial spread of the heading bias (sigma_i of paper Eq. 6); each trial draws
        its own offset ~ N(0, bias_trial_sd**2) that stays fixed for that trial.
    bias_drift : float
        Change of heading bias per trial (decalibration, paper Fig. 1f): in trial k the bias is
        ``heading_bias + k * bias_drift``.
    sensor_gain, sensor_offset : float
        Light-sensor response: ``reading = offset + gain * intensity`` before saturation at
        1023 (paper Fig. 8). Offset in ADC counts.
    sensor_noise : float
        Standard deviation of one light sample, ADC counts (the controller averages 10).
    clock_rate : float
        Relative rate of the robot's clock: it ticks at ``31 Hz * clock_rate`` (paper Fig. 9).
    clock_trial_sd : float
        Relative trial-to-trial spread of the clock rate (battery, temperature): each trial
        runs at ``clock_rate * (1 + clock_trial_sd * z)``, z ~ N(0, 1) fixed for the trial.
    heading_noise_tau : float
        Correlation time of the turn-rate noise, s (0: white, as in paper Eq. 5). Real robots'
        heading noise is coloured (wheel slip and floor texture last a while): the turn-rate
        noise is then an Ornstein-Uhlenbeck-like process with this correlation time, scaled so
        the heading still diffuses with variance ``sigma_omega**2 * t`` at times long against
        it, while over shorter times it wanders less (see :func:`kinematics.turn_noise_coefficients`).
    sensor_offset_trial_sd : float
        Trial-to-trial spread of the sensor offset, ADC counts (the sensor's counterpart of
        ``bias_trial_sd``: ambient light, temperature and battery shift a robot's dark reading
        from one trial to the next): each trial reads with its own offset
        ``sensor_offset + sensor_offset_trial_sd * z``, z ~ N(0, 1) fixed for the trial.
    """

    heading_bias: float = 0.0
    speed_factor: float = 1.0
    sigma_v: float = 0.0
    sigma_omega: float = 0.0
    wheel_noise: float = 0.0
    bias_trial_sd: float = 0.0
    bias_drift: float = 0.0
    sensor_gain: float = 1.0
    sensor_offset: float = 0.0
    sensor_noise: float = 0.0
    clock_rate: float = 1.0
    clock_trial_sd: float = 0.0
    heading_noise_tau: float = 0.0
    sensor_offset_trial_sd: float = 0.0  # new traits go last: a trait's position keys its population stream

    def __post_init__(self):
        for f in fields(self):
            _check_trait(f.name, getattr(self, f.name), "")

    def replace(self, **changes) -> "RobotTraits":
        return dataclasses.replace(self, **changes)


TRAIT_NAMES: tuple[str, ...] = tuple(f.name for f in fields(RobotTraits))
TRAIT_DEFAULTS: dict[str, float] = {f.name: f.default for f in fields(RobotTraits)}

# (low, high, inclusive-low, inclusive-high, fix hint)
_RANGES: dict[str, tuple[float, float, bool, bool, str]] = {
    "heading_bias": (-1.0, 1.0, True, True, "use a value in [-1, 1] (Kilobots measure about +-0.04)"),
    "speed_factor": (0.0, 5.0, False, True, "use a positive value, 1 for a nominal robot"),
    "sigma_v": (0.0, 1.0, True, True, "use a non-negative noise intensity in m/sqrt(s)"),
    "sigma_omega": (0.0, 10.0, True, True, "use a non-negative noise intensity in rad/sqrt(s)"),
    "wheel_noise": (0.0, 1.0, True, False, "use a half-width in [0, 1) (the authors' simulator uses 0.5)"),
    "bias_trial_sd": (0.0, 1.0, True, True, "use a non-negative standard deviation"),
    "bias_drift": (-0.5, 0.5, True, True, "use a per-trial change in [-0.5, 0.5]"),
    "sensor_gain": (0.0, 100.0, False, True, "use a positive gain, 1 for a nominal sensor"),
    "sensor_offset": (-1023.0, 1023.0, True, True, "use an offset in ADC counts within [-1023, 1023]"),
    "sensor_noise": (0.0, 1023.0, True, True, "use a non-negative standard deviation in ADC counts"),
    "clock_rate": (0.0, 10.0, False, True, "use a positive relative rate, 1 for a nominal clock"),
    "clock_trial_sd": (0.0, 0.2, True, True, "use a relative standard deviation in [0, 0.2]"),
    "heading_noise_tau": (0.0, 60.0, True, True, "use a correlation time in seconds within [0, 60] (0: white noise)"),
    "sensor_offset_trial_sd": (0.0, 1023.0, True, True, "use a non-negative standard deviation in ADC counts"),
}


def _check_trait(name: str, value: Any, where: str, source: str = "") -> float:
    label = f"{where}{name}"
    if not is_number(value, finite=False):
        raise ConfigError(label, f"expected a number, got {value!r}", "write a plain number", source)
    v = float(value)
    if not np.isfinite(v):
        raise ConfigError(label, f"must be finite, got {v}", _RANGES[name][4], source)
    lo, hi, lo_inc, hi_inc, fix = _RANGES[name]
    if (v < lo or (v == lo and not lo_inc)) or (v > hi or (v == hi and not hi_inc)):
        lb, rb = "[" if lo_inc else "(", "]" if hi_inc else ")"
        raise ConfigError(label, f"{v} is outside {lb}{lo:g}, {hi:g}{rb}", fix, source)
    return v


def traits_from_mapping(data: Mapping[str, Any], where: str = "", source: str = "",
                        base: RobotTraits | None = None) -> RobotTraits:
    """Build validated traits from a mapping; unknown keys are an error (typos are common)."""
    if not isinstance(data, Mapping):
        raise ConfigError(where.rstrip(".") or "traits", f"expected a mapping of trait: value, got {type(data).__name__}",
                          "write e.g. {heading_bias: 0.01}", source)
    values = dataclasses.asdict(base) if base is not None else dict(TRAIT_DEFAULTS)
    for key, value in data.items():
        if key not in TRAIT_DEFAULTS:
            raise ConfigError(f"{where}{key}", "unknown trait", f"known traits: {', '.join(TRAIT_NAMES)}", source)
        values[key] = _check_trait(key, value, where, source)
    return RobotTraits(**values)


@dataclass(frozen=True)
class SwarmTraits:
    """Traits of N robots, one float64 array of shape (N,) per trait, plus the robot ids."""

    ids: np.ndarray
    values: Mapping[str, np.ndarray] = field(repr=False)

    def __post_init__(self):
        ids = np.asarray(self.ids, dtype=np.int64)
        object.__setattr__(self, "ids", ids)
        # A trait not given takes its default (files written before the trait existed).
        vals = {k: np.asarray(self.values[k] if k in self.values else np.full(ids.shape, TRAIT_DEFAULTS[k]),
                              dtype=np.float64).reshape(-1) for k in TRAIT_NAMES}
        for k, v in vals.items():
            if v.shape != ids.shape:
                raise ValueError(f"trait {k} has shape {v.shape}, expected {ids.shape}")
        if len(np.unique(ids)) != len(ids):
            raise ConfigError("robots", "robot ids must be unique", "give every robot its own id")
        object.__setattr__(self, "values", vals)

    def __len__(self) -> int:
        return len(self.ids)

    def __getattr__(self, name: str) -> np.ndarray:
        # Only reached when normal lookup fails: expose traits as attributes.
        values = object.__getattribute__(self, "values")
        if name in values:
            return values[name]
        raise AttributeError(name)

    @classmethod
    def from_robots(cls, robots: list[RobotTraits], ids=None) -> "SwarmTraits":
        ids = np.arange(len(robots)) if ids is None else np.asarray(ids)
        return cls(ids, {k: np.array([getattr(r, k) for r in robots], dtype=np.float64) for k in TRAIT_NAMES})

    @classmethod
    def uniform(cls, n: int, traits: RobotTraits | None = None) -> "SwarmTraits":
        """N identical robots (the paper's population model, Eq. 4)."""
        return cls.from_robots([traits or RobotTraits()] * n)

    def robot(self, i: int) -> RobotTraits:
        """Traits of the robot at position i (not id)."""
        return RobotTraits(**{k: float(v[i]) for k, v in self.values.items()})

    def subset(self, index) -> "SwarmTraits":
        index = np.asarray(index)
        return SwarmTraits(self.ids[index], {k: v[index] for k, v in self.values.items()})

    def with_values(self, **arrays) -> "SwarmTraits":
        vals = dict(self.values)
        for k, v in arrays.items():
            if k not in TRAIT_DEFAULTS:
                raise ConfigError(k, "unknown trait", f"known traits: {', '.join(TRAIT_NAMES)}")
            vals[k] = np.broadcast_to(np.asarray(v, dtype=np.float64), self.ids.shape).copy()
        return SwarmTraits(self.ids, vals)

    def to_dict(self) -> dict:
        """YAML-ready mapping: ``{robots: {id: {trait: value}}}`` (only non-default values)."""
        robots = {}
        for i, rid in enumerate(self.ids):
            robots[int(rid)] = {k: float(v[i]) for k, v in self.values.items() if float(v[i]) != TRAIT_DEFAULTS[k]}
        return {"format": TRAITS_FORMAT, "robots": robots}


TRAITS_FORMAT = "kilobot-twin/traits-v1"

# ---------------------------------------------------------------------------------------
# Populations: distributions per trait from which a swarm is drawn with a seed.

_DISTS = {
    "constant": ("value",),
    "uniform": ("low", "high"),
    "normal": ("mean", "sd"),
    "linspace": ("low", "high"),
    "list": ("values",),
}


def _draw_trait(name: str, spec: Any, n: int, gen: np.random.Generator, where: str, source: str) -> np.ndarray:
    if is_number(spec, finite=False):
        spec = {"dist": "constant", "value": spec}
    if not isinstance(spec, Mapping) or "dist" not in spec:
        raise ConfigError(f"{where}{name}", "expected a number or {dist: ..., ...}",
                          f"dist is one of {', '.join(_DISTS)}", source)
    dist = spec["dist"]
    if dist not in _DISTS:
        raise ConfigError(f"{where}{name}.dist", f"unknown distribution {dist!r}", f"use one of {', '.join(_DISTS)}", source)
    for key in _DISTS[dist]:
        if key not in spec:
            raise ConfigError(f"{where}{name}.{key}", f"missing for dist {dist}", f"{dist} needs {', '.join(_DISTS[dist])}", source)
    extra = set(spec) - set(_DISTS[dist]) - {"dist"}
    if extra:
        raise ConfigError(f"{where}{name}.{sorted(extra)[0]}", f"not a parameter of dist {dist}",
                          f"{dist} takes {', '.join(_DISTS[dist])}", source)

    def num(key):
        v = spec[key]
        if not is_number(v):
            raise ConfigError(f"{where}{name}.{key}", f"expected a finite number, got {v!r}", "write a plain number", source)
        return float(v)

    if dist == "constant":
        out = np.full(n, num("value"))
    elif dist == "uniform":
        lo, hi = num("low"), num("high")
        if hi < lo:
            raise ConfigError(f"{where}{name}.high", f"{hi} is below low {lo}", "swap low and high", source)
        out = gen.uniform(lo, hi, n)
    elif dist == "linspace":
        out = np.linspace(num("low"), num("high"), n)
    elif dist == "normal":
        sd = num("sd")
        if sd < 0:
            raise ConfigError(f"{where}{name}.sd", f"{sd} is negative", "use a non-negative sd", source)
        out = gen.normal(num("mean"), sd, n)
    else:
        vals = spec["values"]
        if not isinstance(vals, list) or len(vals) != n:
            raise ConfigError(f"{where}{name}.values", f"expected a list of {n} numbers",
                              "give one value per robot", source)
        out = np.array([_check_trait(name, v, f"{where}{name}.values.", source) for v in vals])
    for v in out:
        _check_trait(name, v, where, source)
    return out


def draw_population(spec: Mapping[str, Any], seed: int, n: int | None = None, source: str = "",
                    where: str = "population.") -> SwarmTraits:
    """Draw a swarm from per-trait distributions.

    Parameters
    ----------
    spec : mapping
        ``{n: 100, heading_bias: {dist: uniform, low: -0.04, high: 0.04}, clock_rate: 1.01, ...}``;
        traits not named keep their defaults. ``n`` may be overridden by the argument.
    seed : int
        Root seed; each trait draws from its own stream so adding a trait does not change the
        others.
    """
    if not isinstance(spec, Mapping):
        raise ConfigError(where.rstrip("."), "expected a mapping", "write e.g. {n: 10, heading_bias: {...}}", source)
    n_robots = n if n is not None else spec.get("n")
    if not is_whole(n_robots) or n_robots < 1:
        raise ConfigError(f"{where}n", f"expected a positive integer, got {n_robots!r}", "set n: NUMBER_OF_ROBOTS", source)
    values = {}
    for k, s in spec.items():
        if k == "n":
            continue
        if k == "seed":  # (it was passed over, and the draw took the file's or the caller's seed)
            raise ConfigError(f"{where}seed", "a population takes the file's seed", "write seed: N at the top level of the file",
                              source)
        if k not in TRAIT_DEFAULTS:
            raise ConfigError(f"{where}{k}", "unknown trait", f"known traits: {', '.join(TRAIT_NAMES)}", source)
        values[k] = _draw_trait(k, s, n_robots, _rng.generator(seed, _rng.SPAWN_POPULATION, TRAIT_NAMES.index(k)), where, source)
    full = {k: values.get(k, np.full(n_robots, TRAIT_DEFAULTS[k])) for k in TRAIT_NAMES}
    return SwarmTraits(np.arange(n_robots), full)


# ---------------------------------------------------------------------------------------
# YAML boundary.

def swarm_from_dict(data: Any, seed: int = 0, n: int | None = None, source: str = "") -> SwarmTraits:
    """Swarm traits from a parsed traits document (``robots:`` and/or ``population:``).

    ``defaults:`` applies to every listed robot; ``robots:`` maps robot id to its traits;
    ``population:`` draws robots instead. Exactly one of ``robots`` and ``population``.
    """
    if not isinstance(data, Mapping):
        raise ConfigError("traits", "the file must hold a mapping with robots: or population:",
                          "see config/traits_example.yaml", source)
    known = {"format", "defaults", "robots", "population", "seed"}
    for key in data:
        if key not in known:
            raise ConfigError(str(key), "unknown top-level key", f"use {', '.join(sorted(known))}", source)
    fmt = data.get("format", TRAITS_FORMAT)
    if fmt != TRAITS_FORMAT:
        raise ConfigError("format", f"unsupported format {fmt!r}", f"write format: {TRAITS_FORMAT}", source)
    if ("robots" in data) == ("population" in data):
        raise ConfigError("robots", "give exactly one of robots: and population:",
                          "list robots by id, or describe a population to draw", source)
    seed = data.get("seed", seed)
    if not is_whole(seed) or seed < 0:
        raise ConfigError("seed", f"expected an integer >= 0, got {seed!r}", "write e.g. seed: 1", source)
    if "population" in data:
        return draw_population(data["population"], seed, n, source)
    base = traits_from_mapping(data.get("defaults") or {}, "defaults.", source)
    robots = data["robots"]
    if isinstance(robots, list):
        robots = dict(enumerate(robots))
    if not isinstance(robots, Mapping) or not robots:
        raise ConfigError("robots", "expected a non-empty mapping of id: {traits}", "write e.g. robots: {0: {heading_bias: 0.01}}", source)
    ids, items = [], []
    for rid, tr in robots.items():
        try:
            rid_int = int(rid)
        except (TypeError, ValueError):
            raise ConfigError(f"robots.{rid}", "robot id must be an integer", "use ids like 0, 1, 2", source) from None
        if rid_int < 0:
            raise ConfigError(f"robots.{rid}", "robot id must be non-negative", "use ids like 0, 1, 2", source)
        ids.append(rid_int)
        items.append(traits_from_mapping(tr or {}, f"robots.{rid}.", source, base))
    swarm = SwarmTraits.from_robots(items, ids)
    if n is not None and n != len(swarm):
        raise ConfigError("robots", f"the file lists {len(swarm)} robots but {n} were requested",
                          "drop --robots or make them agree", source)
    return swarm


def load_yaml(path: str | Path) -> Any:
    """Parse a YAML file with a one-line error for a missing file or a syntax error."""
    import yaml

    p = Path(path)
    if not p.is_file():
        raise ConfigError(str(p), "file not found", "check the path")
    try:
        return yaml.safe_load(p.read_text())
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or "invalid YAML"
        raise ConfigError(str(p), f"YAML syntax error{line}: {problem}", "fix the YAML syntax") from None


def load_swarm(path: str | Path, seed: int = 0, n: int | None = None) -> SwarmTraits:
    """Load swarm traits from a YAML file (see :func:`swarm_from_dict`)."""
    return swarm_from_dict(load_yaml(path), seed=seed, n=n, source=str(path))


def save_swarm(swarm: SwarmTraits, path: str | Path) -> None:
    import yaml

    Path(path).write_text(yaml.safe_dump(swarm.to_dict(), sort_keys=False))
