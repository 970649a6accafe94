"""Shared plumbing of the paper experiments: settings, presets, checks, saving."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.scenario import PRESETS, bias_axis_scale, preset_traits, scenario_from_dict
from ..errors import ConfigError

PRESET_NAMES = tuple(PRESETS)


@dataclass
class Settings:
    """How to run an experiment: preset, reduced size, seed, cores, progress bars.

    ``scheduler``: None runs campaigns on this machine's cores; ``local:N`` or ``tcp://HOST:PORT``
    on a Dask cluster (see :mod:`kilobot_twin.batch.cluster`), with the same results.
    """

    preset: str = "paper"
    quick: bool = False
    seed: int = 2023
    workers: int | None = None
    progress: bool = True
    scheduler: str | None = None

    def __post_init__(self):
        if self.preset not in PRESETS:
            raise ConfigError("preset", f"unknown preset {self.preset!r}", f"use one of {', '.join(PRESETS)}")

    def scenario(self, **overrides):
        """The preset's scenario with experiment-specific overrides (a nested dict)."""
        return scenario_from_dict({"preset": self.preset, **overrides}, source=f"preset {self.preset}")

    @property
    def bias_scale(self) -> float:
        """Wheel imbalance per unit of the paper's heading-bias axis under this preset."""
        return bias_axis_scale(self.preset)

    def noise_traits(self) -> dict:
        """Actuation-noise traits the preset implies (Gaussian for paper, wheel for argos-code)."""
        return {k: v for k, v in preset_traits(self.preset).items()}


@dataclass
class Check:
    """One row of the 'paper vs ours' table."""

    figure: str
    fact: str
    paper: str
    ours: str
    met: bool
    note: str = ""


@dataclass
class Outcome:
    """What an experiment returns: arrays to save, metadata, checks and plots."""

    name: str
    data: dict
    meta: dict = field(default_factory=dict)
    checks: list = field(default_factory=list)
    plots: list = field(default_factory=list)

    def save(self, out_dir: Path) -> Path:
        out_dir.mkdir(parents=True, exist_ok=True)
        path = out_dir / f"{self.name}.npz"
        np.savez_compressed(path, meta_json=np.array(json.dumps(self.meta, default=str)),
                            **{k: np.asarray(v) for k, v in self.data.items()})
        return path


def within(ours: float, target: float, abs_tol: float, rel_tol: float) -> bool:
    """|ours - target| <= max(abs_tol, rel_tol * |target|)."""
    return abs(ours - target) <= max(abs_tol, rel_tol * abs(target))
