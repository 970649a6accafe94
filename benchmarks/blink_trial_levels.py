"""Is a blink dataset's trial-to-trial scatter typical of the independent world that wrote it?

For a dataset written by ``benchmarks/indep_world.py`` (its ``truth.json`` beside it), prints how
much the trial means of the toggle rates vary, as a multiple of what the robots' spread within
trials allows (variance of the trial means over the mean within-trial variance / robots), and the
same ratio for ``--runs`` more datasets that the world's own ``blink`` writes with the dataset's
shape, LED program and nuisance levels but other random numbers. A ratio far beyond those is a
draw of the world, not something the twin misses:

    python benchmarks/blink_trial_levels.py OUT/data/indep_rand_prog_blink_none_3229 --runs 100

Toggle rates are read by ``kilobot_twin.gap``'s own summary (what the workflow compares).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np
from tqdm import tqdm

sys.path.insert(0, str(Path(__file__).resolve().parent))
import indep_world  # noqa: E402

from kilobot_twin.errors import ConfigError  # noqa: E402
from kilobot_twin.gap.model import measured_summaries  # noqa: E402
from kilobot_twin.recording import measured  # noqa: E402


def level_ratio(folder) -> float:
    """Variance of the trials' mean relative toggle rate over the mean within-trial variance per robot."""
    _, meas = measured_summaries(measured.load(folder))
    x = np.asarray(meas["toggle_rate"], dtype=float)
    x = x / np.nanmean(x) - 1
    n = np.sum(np.isfinite(x), axis=1)
    within = np.nanvar(x, axis=1, ddof=1) / n
    return float(np.var(np.nanmean(x, axis=1), ddof=1) / np.mean(within))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dataset", help="a blink dataset of benchmarks/indep_world.py (folder with truth.json)")
    ap.add_argument("--runs", type=int, default=100, help="datasets of the same world to compare with")
    ap.add_argument("--seed", type=int, default=0, help="seed of the comparison datasets' random numbers")
    a = ap.parse_args(argv)
    truth_path = Path(a.dataset) / "truth.json"
    try:
        truth = json.loads(truth_path.read_text())
    except (OSError, ValueError):
        print(f"error: {truth_path}: not readable; give a dataset folder written by benchmarks/indep_world.py", file=sys.stderr)
        return 2
    if truth.get("generator") != "indep_world" or truth.get("kind") != "blink" or truth.get("hidden"):
        print(f"error: {truth_path}: not a null blink of indep_world; give one (hidden: [])", file=sys.stderr)
        return 2
    if a.runs < 2:
        print("error: --runs must be 2 or more", file=sys.stderr)
        return 2
    try:
        data = level_ratio(a.dataset)
    except ConfigError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    shape = dict(truth["shape"], missing=[tuple(m) for m in truth["shape"]["missing"]])
    ratios = []
    with tempfile.TemporaryDirectory() as tmp:
        for run in tqdm(range(a.runs), desc="datasets of the same world", unit="dataset"):
            rng = np.random.default_rng([a.seed, run])
            rows, columns, meta, _, _ = indep_world.blink(rng, shape, truth["nuisance"], [], 1.0, truth["program"])
            meta.update({"robots": list(range(shape["robots"])), "trials": shape["trials"],
                         "duration_s": float(max(shape["lengths_s"]))})
            out = Path(tmp) / str(run)
            indep_world._write(out, meta, columns, rows)
            ratios.append(level_ratio(out))
    ratios = np.array(ratios)
    print(f"trial means vary {data:.2f}x what the spread within trials allows")
    print(f"{a.runs} datasets of the same world: median {np.median(ratios):.2f}, 99th percentile "
          f"{np.percentile(ratios, 99):.2f}, max {ratios.max():.2f}; at or above the dataset's: {np.sum(ratios >= data)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
