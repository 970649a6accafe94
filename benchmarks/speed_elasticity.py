"""How much a robot's speed summary moves with its speed: in a generated world and in the fitted twin.

A speed spread is recovered with the right scale only if the twin's speed summary responds to a
robot's speed as the data's does. The summary (mean speed over 2 s chords) is not proportional to
the speed: tracking noise lengthens every chord by about the same amount, and a camera whose lens
is not corrected makes a robot that drives far from the image's centre look faster. This prints,
for a dataset that carries its truth (``truth.json`` with per-robot ``speed_factor``, as
``eval_gap.py``'s generators write), the elasticity of the robots' mean speed summaries to their
true speed factors (the slope of log summary on log factor over robots), and the same for the
twin fitted to the data (the base model simulated at its speed level x 0.9 and x 1.1). Their
ratio is about the slope that ``SpeedHeterogeneity`` recovers the factors with.

    python benchmarks/speed_elasticity.py DATASET [DATASET ...] [--replicates 20]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from kilobot_twin.gap import effects as E
from kilobot_twin.gap.model import measured_summaries, simulate
from kilobot_twin.gap.workflow import GapSettings, _Fitter
from kilobot_twin.recording import measured


def elasticities(path: Path, replicates: int) -> tuple[float, float, float]:
    """(the world's, its standard error over robots, the fitted twin's) elasticity of the speed
    summary to the speed factor."""
    truth = json.loads((path / "truth.json").read_text())
    cond, meas = measured_summaries(measured.load(path))
    factor = np.array([truth["robots"][str(int(i))]["speed_factor"] for i in cond.robot_ids])
    speed = np.nanmean(meas["speed"], axis=0)
    ok = np.isfinite(speed) & (speed > 0) & (factor > 0)
    coef, cov = np.polyfit(np.log(factor[ok]), np.log(speed[ok]), 1, cov=True)
    world, se = float(coef[0]), float(np.sqrt(cov[0, 0]))
    start = E.nominal_model("motion", cond.robot_ids, cond.forward_speed_m_s)
    base = _Fitter(cond, meas, start, GapSettings(seed=1), True).fit((), tuple(range(cond.trials)))
    level = base.swarm.speed_factor
    lo, hi = (float(np.nanmean(simulate(cond, base.with_traits(speed_factor=level * g), replicates, 5)["speed"]))
              for g in (0.9, 1.1))
    return world, se, float(np.log(hi / lo) / np.log(1.1 / 0.9))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("datasets", nargs="+", help="dataset folders with truth.json (motion, speed factors in the truth)")
    ap.add_argument("--replicates", type=int, default=20, help="simulated replicates per speed level (default 20)")
    a = ap.parse_args(argv)
    if a.replicates < 2:
        print("error: --replicates: must be at least 2; give e.g. --replicates 20", file=sys.stderr)
        return 2
    for d in map(Path, a.datasets):
        if not (d / "truth.json").is_file():
            print(f"error: {d}: no truth.json; give a dataset written by eval_gap.py's generators", file=sys.stderr)
            return 2
    print(f"{'dataset':60s} {'world':>7s} {'(se)':>7s} {'twin':>7s} {'ratio':>7s}")
    for d in map(Path, a.datasets):
        world, se, twin = elasticities(d, a.replicates)
        print(f"{d.name:60s} {world:7.3f} {se:7.3f} {twin:7.3f} {world / twin:7.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
