"""benchmarks/drift_bound.py: the smallest drift a test at the workflow's level flags with 80 %
power, checked against a Monte Carlo of the tests written out (normal trial values, drifts of
exactly the stated sd), and the residual about robots' lines it reads (``workflow.about_lines``, which
``minimum_detectable`` reads the drift's noise with) against a hand computation."""


import numpy as np
import pytest

from kilobot_twin.gap.workflow import about_lines, f_test_size
from . import benchmark

db = benchmark.load("drift_bound")


def test_the_known_spread_bound_has_the_power_it_is_computed_for():
    """(The bound with the spread estimated is ``workflow.f_test_size``: tests/gap/test_designs.py.)"""
    N, K, alpha, reps = 12, 4, 0.01 / 6, 20000
    d = db.known_sigma_size(N, K * (K * K - 1) / 12.0, alpha)
    power = db.monte_carlo_power(N, K, d, alpha, True, reps=reps, seed=7)
    # the Monte Carlo's binomial error at 80 %: sd sqrt(0.8 * 0.2 / reps) = 0.0028; 4 sd
    assert abs(power - 0.8) < 4 * np.sqrt(0.16 / reps)


def test_an_estimated_spread_needs_a_larger_drift_than_a_known_one():
    alpha = 0.01 / 6
    assert f_test_size(12, 4, True, alpha) > db.known_sigma_size(12, 5.0, alpha)
    # more trials: more residual dof and a longer lever arm, so a smaller drift
    assert f_test_size(12, 6, True, alpha) < f_test_size(12, 4, True, alpha)


def test_residual_about_lines_by_hand():
    # robot 0 on a line (residual 0); robot 1: 0, 1, 0, 1 about its line 0.2 + 0.2 k: residuals
    # -0.2, 0.6, -0.6, 0.2, sum of squares 0.8; robot 2 misses trial 3: 1, 2, 4 about 0.833 + 1.5 k:
    # residuals 1/6, -1/3, 1/6, sum of squares 1/6. dof (4 - 2) + (4 - 2) + (3 - 2) = 5.
    x = np.array([[1.0, 0.0, 1.0], [2.0, 1.0, 2.0], [3.0, 0.0, 4.0], [4.0, 1.0, np.nan]])
    var, dof, skk = about_lines(x)
    assert dof == 5
    assert var == pytest.approx((0.8 + 1 / 6) / 5, rel=1e-12)
    assert skk == pytest.approx((5.0 + 5.0 + 2.0) / 3, rel=1e-12)
