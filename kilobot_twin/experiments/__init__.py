"""The paper's experiments: each a function returning arrays (an :class:`Outcome`), a plot
function reading them, and checks against the numbers read off the published figures."""

from __future__ import annotations

from pathlib import Path

from . import motion, other, phototaxis, walks
from .common import Check, Outcome, Settings

#: name -> (run, plot, figure(s) it reproduces)
EXPERIMENTS = {
    "straight": (motion.run_straight, motion.plot_straight, "Fig. 1 b-d"),
    "bias_per_robot": (motion.run_bias_per_robot, motion.plot_bias_per_robot, "Fig. 2"),
    "decalibration": (motion.run_decalibration, motion.plot_decalibration, "Fig. 1f"),
    "phototaxis": (phototaxis.run_phototaxis, phototaxis.plot_phototaxis, "Figs. 4, 5, 6"),
    "random_walk": (walks.run_random_walk, walks.plot_random_walk, "Fig. 7"),
    "sensing": (other.run_sensing, other.plot_sensing, "Fig. 8"),
    "frequency": (other.run_frequency, other.plot_frequency, "Fig. 9 a-c"),
    "kuramoto": (other.run_kuramoto, other.plot_kuramoto, "Fig. 9 d-f"),
}


def run_experiment(name: str, settings: Settings, out_dir: str | Path | None = None) -> Outcome:
    """Run one experiment; with ``out_dir`` also save its arrays (.npz) and plots (.png)."""
    from ..errors import ConfigError

    if name not in EXPERIMENTS:
        raise ConfigError("experiment", f"unknown experiment {name!r}", f"use one of {', '.join(EXPERIMENTS)}")
    run, plot, _ = EXPERIMENTS[name]
    outcome = run(settings)
    if out_dir is not None:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        outcome.meta["data"] = str(outcome.save(out))
        outcome.plots = [str(p) for p in plot(outcome, out)]
    return outcome


__all__ = ["EXPERIMENTS", "Check", "Outcome", "Settings", "run_experiment"]
