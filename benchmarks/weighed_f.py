"""How often the detection's F statistics flag robots that do not differ, when the model says
some robots are noisier than others (robots that differ in noise, ``motion_noise``).

A model whose robots differ in noise simulates its null with them, so a pooled F is calibrated
against it in the mean and sd; but the pooled squares are the noisiest robots', so its null has
the tail of one robot's few degrees of freedom, which the detection's normal-tail z does not. The
statistics now weigh each robot by its variance under the model (workflow.model_variances, read
off the simulated null as the workflow reads it), and with the weights right the weighted F of
robots over trials is F(N - 1, n - N) and the trend F is F(N, N (K - 2)) exactly, whatever the
robots' variances.

Every dataset and its null are drawn here from a normal model with the given per-robot
variances and no effect; the rate at which detect's rule (p < alpha / 6, the motion family)
flags each statistic is printed, pooled and weighted, against the nominal alpha / 6, and the
power of both for a drift carried by the quiet robots beside one noisy robot.

    python benchmarks/weighed_f.py [--datasets 3000] [--robots 10] [--trials 8]
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.stats import norm
from tqdm import tqdm

from kilobot_twin.gap.workflow import _f_between, _f_trend, model_variances


def flag_rate(obs, sim, alpha):
    z = (obs - sim.mean(-1)) / sim.std(-1, ddof=1)
    return float(np.mean(norm.sf(z) < alpha))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--datasets", type=int, default=3000)
    ap.add_argument("--robots", type=int, default=10)
    ap.add_argument("--trials", type=int, default=8)
    ap.add_argument("--null", type=int, default=120, help="replicates of the null per dataset (the workflow's m_null)")
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args(argv)
    N, K, M, D = a.robots, a.trials, a.null, a.datasets
    alpha = 0.01 / 6
    rng = np.random.default_rng(a.seed)
    models = {"robots alike": np.ones(N), "one robot 15x as variable": np.r_[15.0, np.ones(N - 1)],
              "lognormal, sd 0.8 in ln variance": np.exp(0.8 * np.random.default_rng(5).standard_normal(N))}
    k = np.arange(K, dtype=float)[:, None] - (K - 1) / 2
    print(f"{N} robots x {K} trials, {D} datasets per model, null of {M} replicates; flagged at p < {alpha:.5f}")
    print(f"{'model':34s} {'statistic':22s} {'pooled':>8s} {'weighed':>8s}")
    for label, var in models.items():
        sd = np.sqrt(var)
        rates = {"between": [0, 0], "trend": [0, 0], "drift power": [0, 0]}
        drift = np.where(var > 1.5, 0.0, 0.25) * k  # quiet robots drift by 0.25 sd per trial
        for _ in tqdm(range(D), desc=label, leave=False):
            null = rng.standard_normal((M, K, N)) * sd
            v = model_variances("motion", {"turn_rate": null})
            data = rng.standard_normal((K, N)) * sd
            for j, w in enumerate((None, v)):
                rates["between"][j] += flag_rate(_f_between(data, v=None if w is None else w["turn_rate"]),
                                                 _f_between(null, v=None if w is None else w["turn_rate"]), alpha)
                rates["trend"][j] += flag_rate(_f_trend(data, None if w is None else w["turn_rate:line"]),
                                               _f_trend(null, None if w is None else w["turn_rate:line"]), alpha)
                rates["drift power"][j] += flag_rate(_f_trend(data + drift, None if w is None else w["turn_rate:line"]),
                                                     _f_trend(null, None if w is None else w["turn_rate:line"]), alpha)
        for stat, (p, w) in rates.items():
            print(f"{label:34s} {stat:22s} {100 * p / D:7.2f}% {100 * w / D:7.2f}%")
    print(f"nominal false-flag rate {100 * alpha:.2f}% (binomial sd over {D} datasets: {100 * np.sqrt(alpha * (1 - alpha) / D):.2f}%)")


if __name__ == "__main__":
    main()
