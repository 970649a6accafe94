"""Do stated minimum detectable sizes hold in a fresh dataset when the within-robot variance they
rest on was estimated from the dataset's own trials?

A report states the size at which its emulation (workflow.naming_power) names an effect with 80 %
power, from the dataset's within-robot variance s^2, an estimate with N (K - 1) degrees of
freedom. A fresh dataset of the same noise has the true variance sigma^2. The emulation is
scale-free (every summary is noise of sd s plus robots' levels of sd tau: the power is a function
of tau / s alone), so a size stated from an estimate s^2 is c s, c the size at s = 1, and its power
in the fresh dataset is P(c s / sigma), P the power curve at known variance. Averaged over the
estimate's law, s^2 / sigma^2 ~ chi2(d) / d (d degrees of freedom, normal noise), that is the rate
at which stated sizes are named. This prints it for c taken with the variance as exact and with
the variance averaged over what it may be (naming_power's dof), per shape (robots x trials).

    python benchmarks/bench_mde_dof.py [--reps 2000]
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.stats import chi2, norm

from kilobot_twin.gap.workflow import _f_between, _first_crossing, naming_power


def rate(N: int, K: int, reps: int, alpha: float = 0.05, n_stats: int = 6) -> tuple:
    seen = np.ones((K, N), bool)
    d = N * (K - 1)
    rng = np.random.default_rng(0)
    s0 = float(np.std(_f_between(rng.standard_normal((4000, K, N))), ddof=1))  # the null's sd of log F
    thr = norm.isf(alpha / n_stats) * s0
    taus = np.geomspace(0.05, 6.0, 80)
    known = naming_power(seen, 1.0, taus, False, True, thr, reps=reps, seed=1)
    c_exact = _first_crossing(taus, known, 0.8)
    c_dof = _first_crossing(taus, naming_power(seen, 1.0, taus, False, True, thr, reps=reps, seed=1, dof=d), 0.8)
    q = np.sqrt(chi2.ppf((np.arange(2000) + 0.5) / 2000, d) / d)  # s / sigma, by its quantiles

    def fresh(c):
        return float(np.mean(np.interp(np.log(c * q), np.log(taus), known)))

    return d, fresh(c_exact), fresh(c_dof), c_dof / c_exact


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reps", type=int, default=2000, help="emulated datasets per power curve")
    a = ap.parse_args()
    print("robots x trials  dof  named in fresh datasets: variance as exact | averaged (size x)")
    for N, K in [(8, 3), (12, 4), (20, 5), (36, 3), (36, 7)]:
        d, exact, avg, ratio = rate(N, K, a.reps)
        print(f"{N:6d} x {K:<6d} {d:5d}  {exact:6.3f} | {avg:6.3f} (x{ratio:.3f})", flush=True)


if __name__ == "__main__":
    main()
