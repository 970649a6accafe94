"""How small a drift can any test see on 12 robots x 4 trials, at 2x the nominal nuisances?

The issue asks that on 12 robots x 4 trials the minimum detectable drift lie below the earlier
issue's size (0.0045 rad/s per trial) for nuisance levels up to 2x nominal. This measures, on the
independent world (``indep_world.py``, fixed shape, every nuisance at ``--nuisance-scale`` x
nominal, no effect), how much a robot's turn rate scatters from trial to trial about its own line
over the trials (sigma_t: the trial-to-trial bias spread of Eq. 6 plus the error of one trial's
turn rate), read with the project's reader, and from it, by theory, the smallest drift that a
test at the workflow's level (``GapSettings.alpha`` over the number of motion statistics, as
``workflow.minimum_detectable`` takes it) flags with 80 % power:

- **known sigma_t** (what a test of the robots' slopes could do if the trial-to-trial spread
  were known from elsewhere; the data give it only through their own trials): a robot's fitted slope is its drift plus noise of variance
  sigma_t^2 / S_kk (S_kk: the sum of squared trial offsets, 5 for 4 trials), so
  sum_i S_kk b_i^2 / sigma_t^2 is noncentral chi^2 on N robots with
  lambda = S_kk sum_i d_i^2 / sigma_t^2 = S_kk (N - 1) d^2 / sigma_t^2 for drifts of sd d
  (ddof 1, about 0: the spread of the dataset's own robots, as the workflow states sizes);
- **sigma_t estimated from the same trials** (the F of trends over the residual about the lines,
  N (K - 2) degrees of freedom: what ``workflow.detect``'s trend statistic is): noncentral F.

Both are detection alone; naming needs more (the held-out score). A Monte Carlo check of the two
formulas (normal trial values, drifts of exactly sd d, the tests written out) prints the power at
each bound, which should read 0.80 within its Monte Carlo error.

    python benchmarks/drift_bound.py [--seeds 20] [--first-seed 3080] [--nuisance-scale 2]
"""

from __future__ import annotations

import argparse
import importlib.util
import tempfile
from pathlib import Path

import numpy as np
from scipy import optimize, stats

from kilobot_twin.gap.model import measured_summaries
from kilobot_twin.gap.workflow import GapSettings, about_lines, f_test_size, statistics
from kilobot_twin.recording import measured

EARLIER_DRIFT = 0.0045  # rad/s per trial, the earlier gap issue's drift
POWER = 0.8


def _indep_world():
    spec = importlib.util.spec_from_file_location("indep_world", Path(__file__).parent / "indep_world.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def known_sigma_size(N: int, skk: float, alpha: float, power: float = POWER) -> float:
    """The drift sd d (in units of sigma_t) that the chi^2 test with sigma_t known flags with
    ``power``: noncentrality lambda = S_kk (N - 1) d^2 on N dof. (Estimated from the trials, the
    F test's size is ``workflow.f_test_size``, which the report scales its designs by.)"""
    crit = stats.chi2.isf(alpha, N)
    lam = optimize.brentq(lambda lam: stats.ncx2.sf(crit, N, lam) - power, 1e-6, 1e4)
    return float(np.sqrt(lam / (skk * (N - 1))))


def monte_carlo_power(N: int, K: int, d: float, alpha: float, known: bool, reps: int = 20000, seed: int = 1) -> float:
    """Power of the test written out, at drift sd d (sigma_t = 1), balanced K x N."""
    rng = np.random.default_rng(seed)
    dk = np.arange(K) - (K - 1) / 2
    skk = float((dk**2).sum())
    z = rng.standard_normal((reps, N))
    z -= z.mean(1, keepdims=True)
    drift = d * z / z.std(1, ddof=1, keepdims=True)  # sd exactly d over the robots
    x = rng.standard_normal((reps, K, N)) + drift[:, None, :] * dk[None, :, None]
    dev = x - x.mean(1, keepdims=True)
    b = (dk[None, :, None] * dev).sum(1) / skk
    ms_trend = skk * (b**2).sum(1)
    if known:
        return float(np.mean(ms_trend > stats.chi2.isf(alpha, N)))
    res = ((dev - b[:, None, :] * dk[None, :, None]) ** 2).sum((1, 2)) / (N * (K - 2))
    return float(np.mean(ms_trend / N / res > stats.f.isf(alpha, N, N * (K - 2))))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=3080)
    ap.add_argument("--nuisance-scale", type=float, default=2.0)
    a = ap.parse_args(argv)
    from tqdm import tqdm

    world = _indep_world()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in tqdm(range(a.first_seed, a.first_seed + a.seeds), desc="datasets", unit="dataset"):
            out = Path(tmp) / f"motion_{seed}"
            world.generate("motion", "", out, seed=seed, nuisance_scale=a.nuisance_scale, fixed_shape=True)
            _, s = measured_summaries(measured.load(out))
            K, N = s["turn_rate"].shape
            n_stats = len(statistics("motion", s, K))
            rows.append((*about_lines(s["turn_rate"]), N, K, n_stats))
    var, dof, skk, N, K, n_stats = (np.array(c) for c in zip(*rows))
    N, K, n_stats = int(np.median(N)), int(np.median(K)), int(np.median(n_stats))
    sigma = float(np.sqrt(np.median(var)))
    alpha = GapSettings().alpha / n_stats
    dof_m, skk_m = int(np.median(dof)), float(np.median(skk))
    if dof_m != N * (K - 2) or skk_m != K * (K * K - 1) / 12.0:
        raise SystemExit(f"the fixed shape has trials missing (dof {dof_m}, S_kk {skk_m:g}): the sizes are for a balanced design")
    known = known_sigma_size(N, skk_m, alpha)
    est = f_test_size(N, K, True, alpha)
    print(f"independent world, {N} robots x {K} trials, nuisances {a.nuisance_scale:g}x nominal, {a.seeds} null datasets")
    print(f"  sigma_t (a robot's turn rate about its line, trial to trial): median {sigma:.5f} rad/s "
          f"(range {np.sqrt(var.min()):.5f} .. {np.sqrt(var.max()):.5f}); residual dof {dof_m}, S_kk {skk_m:g}")
    print(f"  level: alpha {GapSettings().alpha:g} / {n_stats} motion statistics = {alpha:.5f}; power {POWER:.0%}")
    print(f"  smallest drift flagged, sigma_t known:           {known:.3f} sigma_t = {known * sigma:.5f} rad/s per trial")
    print(f"  smallest drift flagged, sigma_t from the trials: {est:.3f} sigma_t = {est * sigma:.5f} rad/s per trial")
    print(f"  the earlier issue's drift: {EARLIER_DRIFT} rad/s per trial = {EARLIER_DRIFT / sigma:.3f} sigma_t")
    level = optimize.brentq(lambda la: f_test_size(N, K, True, la) * sigma - EARLIER_DRIFT, 1e-8, 0.5)
    print(f"  level at which the F test flags {EARLIER_DRIFT} with {POWER:.0%} power: {level:.4f} "
          f"({level * n_stats:.3f} over the {n_stats} statistics)")
    for k in range(K, 9):
        if f_test_size(N, k, True, alpha) * sigma <= EARLIER_DRIFT:
            print(f"  trials the F test needs to flag {EARLIER_DRIFT} with {POWER:.0%} power on {N} robots: {k}")
            break
    print("  check of the formulas (Monte Carlo, balanced, 20000 replicates; power at each bound): "
          f"known {monte_carlo_power(N, K, known, alpha, True):.3f}, estimated {monte_carlo_power(N, K, est, alpha, False):.3f}")


if __name__ == "__main__":
    main()
