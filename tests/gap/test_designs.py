"""The detection size a report states for more robots or trials (``workflow.other_designs``).

Its scale comes from ``f_test_size``, the spread the exact F test flags with 80 % power. Checked
against the tests written out in numpy and run on normal data drawn at that spread (a second
implementation: one-way ANOVA of robots over trials here; each robot's slope over its trials
against the scatter about its line, ``benchmarks/drift_bound.py``'s), at the level they are
given; the share flagged must be 0.8 within 3 binomial sds of its Monte Carlo error. ``benchmarks/design_sizes.py`` checks the sizes
on the independent world, through the workflow.
"""

import numpy as np
import pytest
from scipy import stats

from kilobot_twin.gap import workflow as W
from . import benchmark

db = benchmark.load("drift_bound")

REPS = 4000
TOL = 3 * np.sqrt(0.8 * 0.2 / REPS)


def _own_sd(rng, shape, sd):
    """Values of exactly mean 0 and sd ``sd`` (ddof 1) over the last axis: robots' own spread."""
    x = rng.normal(size=shape)
    x -= x.mean(-1, keepdims=True)
    return x * sd / x.std(-1, ddof=1, keepdims=True)


def _between_flagged(rng, N, K, tau, alpha):
    means = _own_sd(rng, (REPS, 1, N), tau)
    x = means + rng.normal(size=(REPS, K, N))
    m = x.mean(1)  # (R, N)
    msb = K * ((m - m.mean(-1, keepdims=True)) ** 2).sum(-1) / (N - 1)
    msw = ((x - m[:, None]) ** 2).sum((1, 2)) / (N * (K - 1))
    return stats.f.sf(msb / msw, N - 1, N * (K - 1)) < alpha


@pytest.mark.parametrize("N, K, drift, alpha", [(12, 4, False, 0.01 / 6), (6, 3, False, 0.05), (30, 8, False, 0.01 / 6),
                                                (12, 4, True, 0.01 / 6), (12, 6, True, 0.01 / 6), (24, 3, True, 0.01)])
def test_the_f_tests_size_is_flagged_with_80_percent_power_by_the_tests_written_out(N, K, drift, alpha):
    def power(size):
        if drift:  # drift_bound.py's trend test, written out
            return db.monte_carlo_power(N, K, size, alpha, False, reps=REPS, seed=N * 100 + K)
        return _between_flagged(np.random.default_rng(N * 100 + K), N, K, size, alpha).mean()

    tau = W.f_test_size(N, K, drift, alpha)
    assert abs(power(tau) - 0.8) < TOL, (power(tau), tau)
    # and a size 15 % smaller is flagged clearly less often (the check can tell sizes apart)
    assert power(0.85 * tau) < 0.8 - TOL


def test_other_designs_scale_this_dataset_s_size_by_the_f_tests_at_the_family_s_level():
    """Motion on 2 trials has 5 statistics (no trend), on 3 or more 6 (docs/gap_methods.md): the
    family's level of each design is alpha over its count. The sizes scale the dataset's own
    detection size by the F test's size there over here, and no design appears twice (on 2 trials
    two more trials are twice as many)."""
    alpha, det, N = 0.01, 0.004, 10
    got = W.other_designs("motion", det, N, 2, False, alpha)
    assert [(x["robots"], x["trials"]) for x in got] == [(10, 3), (10, 4), (20, 2)]
    here = W.f_test_size(N, 2, False, alpha / 5)
    want = [det * W.f_test_size(10, 3, False, alpha / 6) / here, det * W.f_test_size(10, 4, False, alpha / 6) / here,
            det * W.f_test_size(20, 2, False, alpha / 5) / here]
    assert [x["detection_size"] for x in got] == pytest.approx(want, rel=1e-9)
    # more data, smaller sizes; a drift over 4 trials: a fifth trial helps it more than twice the robots
    assert all(x["detection_size"] < det for x in got)
    drift = {(x["robots"], x["trials"]): x["detection_size"] for x in W.other_designs("motion", det, 12, 4, True, alpha)}
    assert drift[(12, 5)] < drift[(24, 4)] < det
