"""A scenario: everything about an experiment except the robots' individuality and the seed.

Loaded from YAML (see ``config/``) with one-line errors naming the field. Presets give
named starting points that a file can override.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from ..errors import ConfigError
from . import behaviors as B
from .arena import Arena
from .constants import TICK_HZ
from .kinematics import MotorConfig
from .light import ConeField, LightField, SensorModel, field_from_dict, field_to_dict


@dataclass(frozen=True)
class StartSpec:
    """Where robots start.

    kind ``origin``: at (0, 0); ``uniform``: uniform in the square [-half_width, half_width]^2;
    ``grid``: on a square lattice of ``spacing_m`` with ``columns`` per row, centred.
    ``heading_rad``: a fixed start heading, or None for uniform on [-pi, pi).
    ``shared``: True gives every robot of a run the same start pose (the paper's phototaxis
    study distributes 100 start poses once, one per Monte Carlo run, for all robots).
    ``random_phase``: start each robot's clock at a random phase of the blink period instead
    of all at tick 0 (the paper's robots were started in sync by a broadcast).
    """

    kind: str = "origin"
    half_width_m: float = 1.0
    spacing_m: float = 0.06
    columns: int = 7
    heading_rad: float | None = 0.0
    shared: bool = False
    random_phase: bool = False


@dataclass(frozen=True)
class Scenario:
    """One experiment's conditions.

    Attributes
    ----------
    behavior : Straight | Phototaxis | RandomWalk | Blink
    dt_s : float
        Physics step; the controller runs once per step on the robot's own tick count.
    duration_s : float
    tick_hz : float
        Nominal clock rate (31 Hz on a Kilobot, 10 in the authors' simulator).
    coupling_per_s, neighbour_radius_m :
        Kuramoto coupling strength k and neighbourhood radius (blink only).
    cost_window_steps : int
        The phototaxis cost is the mean distance to the light centre over this many final steps.
    floor_tilt, floor_tilt_direction_rad :
        A tilted floor: every robot's speed is multiplied by ``1 + floor_tilt * cos(theta - direction)``
        (faster downhill). Not an individual trait: an environment effect, used to test that the
        gap workflow says "unexplained" for effects outside its library.
    """

    behavior: Any = field(default_factory=B.Straight)
    dt_s: float = 0.1
    duration_s: float = 200.0
    tick_hz: float = TICK_HZ
    motors: MotorConfig = field(default_factory=MotorConfig)
    light: LightField = field(default_factory=ConeField)
    sensor: SensorModel = field(default_factory=SensorModel)
    arena: Arena = field(default_factory=Arena)
    start: StartSpec = field(default_factory=StartSpec)
    coupling_per_s: float = 0.0
    neighbour_radius_m: float = 0.10
    cost_window_steps: int = 100
    floor_tilt: float = 0.0
    floor_tilt_direction_rad: float = 0.0

    @property
    def n_steps(self) -> int:
        return int(round(self.duration_s / self.dt_s))

    def replace(self, **changes) -> "Scenario":
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        beh = {k: v for k, v in dataclasses.asdict(self.behavior).items() if k not in ("name", "needs_light")}
        return {
            "behavior": {"kind": self.behavior.name, **beh},
            "dt_s": self.dt_s,
            "duration_s": self.duration_s,
            "tick_hz": self.tick_hz,
            "motors": dataclasses.asdict(self.motors),
            "light": field_to_dict(self.light),
            "sensor": dataclasses.asdict(self.sensor),
            "arena": dataclasses.asdict(self.arena),
            "start": dataclasses.asdict(self.start),
            "coupling_per_s": self.coupling_per_s,
            "neighbour_radius_m": self.neighbour_radius_m,
            "cost_window_steps": self.cost_window_steps,
            "floor_tilt": self.floor_tilt,
            "floor_tilt_direction_rad": self.floor_tilt_direction_rad,
        }


_NULLABLE = {"heading_rad"}


def _sub(cls, data, where, source, converters=None):
    """Build dataclass ``cls`` from a mapping, rejecting unknown keys and non-numbers."""
    if data is None:
        return cls()
    if not isinstance(data, Mapping):
        raise ConfigError(where.rstrip("."), f"expected a mapping, got {data!r}", "see config/scenario_example.yaml", source)
    names = {f.name: f for f in dataclasses.fields(cls) if f.init}
    out = {}
    for k, v in data.items():
        if k not in names:
            raise ConfigError(f"{where}{k}", "unknown key", f"use one of {', '.join(sorted(names))}", source)
        default = names[k].default
        if converters and k in converters:
            out[k] = converters[k](v, f"{where}{k}")
        elif isinstance(default, bool):
            if not isinstance(v, bool):
                raise ConfigError(f"{where}{k}", f"expected true or false, got {v!r}", "write true or false", source)
            out[k] = v
        elif isinstance(default, (int, float)) or default is None:
            if v is None and (default is None or k in _NULLABLE):
                out[k] = None
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
                raise ConfigError(f"{where}{k}", f"expected a number, got {v!r}", "write a plain number", source)
            out[k] = int(v) if isinstance(default, int) and not isinstance(default, bool) else float(v)
        else:
            out[k] = v
    try:
        return cls(**out)
    except TypeError as exc:  # pragma: no cover - guarded by the key check above
        raise ConfigError(where.rstrip("."), str(exc), "check the keys", source) from None


def _positive(d: Mapping, keys, where, source):
    for k in keys:
        if k in d and d[k] is not None and not (isinstance(d[k], (int, float)) and d[k] > 0):
            raise ConfigError(f"{where}{k}", f"must be positive, got {d[k]!r}", "use a positive value", source)


def behavior_from_dict(data: Mapping[str, Any] | str, where: str = "behavior.", source: str = "") -> Any:
    """The validated behaviour of ``{kind: ..., field: value}`` (or just the kind's name).

    The one behaviour validator (YAML files, ROS parameters): unknown kinds and keys are errors;
    integer fields take whole numbers >= 1 (``half_period_ticks``, ...) or >= 0
    (``loop_overhead_ticks``); every other field is a non-negative number; probabilities lie in
    [0, 1]. ``where`` prefixes the field names in messages (``phototaxis.`` for a ROS parameter).
    """
    if isinstance(data, str):
        data = {"kind": data}
    kind = data.get("kind") if isinstance(data, Mapping) else data
    if kind not in B.BEHAVIORS:
        raise ConfigError(f"{where}kind" if where == "behavior." else "behavior", f"unknown behaviour {kind!r}",
                          f"use one of {', '.join(B.BEHAVIORS)}", source)
    values = {k: v for k, v in data.items() if k != "kind"}
    cls = B.BEHAVIORS[kind]
    for f in dataclasses.fields(cls):
        v = values.get(f.name)
        if v is None or isinstance(v, bool) or not isinstance(v, (int, float)):
            continue  # absent, or a type error that _sub reports
        if isinstance(f.default, int) and not isinstance(f.default, bool):
            low = 0 if f.name == "loop_overhead_ticks" else 1
            if not float(v).is_integer() or v < low:
                raise ConfigError(f"{where}{f.name}", f"expected a whole number >= {low}, got {v!r}", "write e.g. 31",
                                  source)
        elif f.name.startswith("p_") and not 0.0 <= v <= 1.0:
            raise ConfigError(f"{where}{f.name}", f"{v} is not a probability", "use a value in [0, 1]", source)
        elif v < 0:
            raise ConfigError(f"{where}{f.name}", f"must be non-negative, got {v}", "use a value >= 0", source)
    return _sub(cls, values, where, source)


def scenario_from_dict(data: Mapping[str, Any], source: str = "") -> Scenario:
    """Validated :class:`Scenario` from a parsed YAML mapping (``preset:`` first, then overrides)."""
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        raise ConfigError("scenario", "expected a mapping", "see config/scenario_example.yaml", source)
    data = dict(data)
    preset = data.pop("preset", None)
    base: dict = {}
    if preset is not None:
        if preset not in PRESETS:
            raise ConfigError("preset", f"unknown preset {preset!r}", f"use one of {', '.join(PRESETS)}", source)
        base = _deep_merge({}, PRESETS[preset])
    data = _deep_merge(base, data)
    data.pop("traits", None)  # population defaults of a preset; read by the caller
    data.pop("bias_axis_scale", None)  # how the preset reads the paper's bias axis; see PRESETS
    known = {f.name for f in dataclasses.fields(Scenario)}
    for k in data:
        if k not in known:
            raise ConfigError(str(k), "unknown scenario key", f"use one of {', '.join(sorted(known))}", source)
    _positive(data, ("dt_s", "duration_s", "tick_hz", "neighbour_radius_m"), "", source)

    kw: dict[str, Any] = {"behavior": behavior_from_dict(data.get("behavior", {"kind": "straight"}), source=source)}
    for k in ("dt_s", "duration_s", "tick_hz", "coupling_per_s", "neighbour_radius_m", "cost_window_steps",
              "floor_tilt", "floor_tilt_direction_rad"):
        if k in data:
            v = data[k]
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise ConfigError(k, f"expected a number, got {v!r}", "write a plain number", source)
            kw[k] = int(v) if k == "cost_window_steps" else float(v)
    kw["motors"] = _sub(MotorConfig, data.get("motors"), "motors.", source)
    kw["sensor"] = _sub(SensorModel, data.get("sensor"), "sensor.", source)
    kw["arena"] = _sub(Arena, data.get("arena"), "arena.", source)
    kw["start"] = _sub(StartSpec, data.get("start"), "start.", source)
    if kw["start"].kind not in ("origin", "uniform", "grid"):
        raise ConfigError("start.kind", f"unknown start {kw['start'].kind!r}", "use origin, uniform or grid", source)
    if "light" in data:
        kw["light"] = field_from_dict(data["light"], source)
    sc = Scenario(**kw)
    if not -0.9 <= sc.floor_tilt <= 0.9:
        raise ConfigError("floor_tilt", f"{sc.floor_tilt} is outside [-0.9, 0.9]", "give the relative speed change downhill", source)
    if sc.n_steps < 1:
        raise ConfigError("duration_s", "shorter than one step", "make duration_s at least dt_s", source)
    return sc


def preset_traits(preset: str | None) -> dict:
    """Population defaults a preset implies (e.g. the authors' wheel noise)."""
    return dict(PRESETS.get(preset or "", {}).get("traits", {}))


def _deep_merge(a: dict, b: Mapping) -> dict:
    """Merge b over a, recursively; a mapping with a different ``kind`` replaces, not merges."""
    out = dict(a)
    for k, v in b.items():
        if isinstance(v, str) and k == "behavior" and isinstance(out.get(k), Mapping):
            v = {"kind": v}
        if isinstance(v, Mapping) and isinstance(out.get(k), Mapping) and v.get("kind", out[k].get("kind")) == out[k].get("kind"):
            out[k] = _deep_merge(dict(out[k]), v)
        else:
            out[k] = v
    return out


def bias_axis_scale(preset: str | None) -> float:
    """Wheel imbalance b per unit of the paper's heading-bias axis under a preset."""
    return float(PRESETS.get(preset or "", {}).get("bias_axis_scale", 1.0))


#: Named starting points. ``traits`` holds population defaults for robots the user does not
#: describe (used by experiments and ``simulate``) and ``bias_axis_scale`` how the preset reads
#: the paper's heading-bias axis; neither is a scenario field.
PRESETS: dict[str, dict] = {
    # Chosen to reproduce the published figures (docs/presets.md has the evidence):
    # the authors' simulator's timing (10 ticks/s, 2000 s runs, per-tick uniform wheel noise
    # +-0.5), the light cone reaching 0 at the corners of a 4 m arena (r = 2.83 m), start points
    # uniform in [-1, 1]^2 shared by all robots of a run, and the paper's bias axis read as one
    # tenth of the wheel imbalance: Fig. 1c's colour bar (+-0.02) draws circles of r ~ 0.125 m =
    # 0.025 m / 0.2; Fig. 5 only takes its shape for scales 8-12 (best 10); Fig. 7's coverage
    # loss (extremes keep 75 %) appears at scale 10 in the authors' own arena.
    "paper": {
        "dt_s": 0.1,
        "duration_s": 2000.0,
        "tick_hz": 10.0,
        "light": {"kind": "cone", "radius_m": 0.7071 * 4.0, "peak": 1024.0},
        "arena": {"width_m": 4.0, "height_m": 4.0, "walls": False},
        "start": {"kind": "uniform", "half_width_m": 1.0, "heading_rad": None, "shared": True},
        "behavior": {"kind": "phototaxis", "reference": 2000.0},
        "traits": {"wheel_noise": 0.5},
        "bias_axis_scale": 10.0,
    },
    # The authors' ARGoS code as shipped, as far as we know it: 10 ticks/s, 2000 s, per-tick
    # uniform wheel noise of +-0.5, their phototaxis loop tick by tick (PhototaxisArgos) with
    # reference 2000 (robots climb the gradient and never 'arrive'), cone with W = 4 m, and the
    # paper's bias axis taken literally as the wheel imbalance.
    "argos-code": {
        "dt_s": 0.1,
        "duration_s": 2000.0,
        "tick_hz": 10.0,
        "light": {"kind": "cone", "radius_m": 0.7071 * 4.0, "peak": 1024.0},
        "arena": {"width_m": 4.0, "height_m": 4.0, "walls": False},
        "start": {"kind": "uniform", "half_width_m": 1.0, "heading_rad": None, "shared": True},
        "behavior": {"kind": "phototaxis_argos", "reference": 2000.0},
        "traits": {"wheel_noise": 0.5},
        "bias_axis_scale": 1.0,
    },
}
