"""The paper's shape facts as assertions (reduced runs by default, full sizes marked slow).

Tolerances come from the sample: per-run statistics are independent across Monte Carlo runs,
so differences of means are compared with 3 standard errors of that difference.
"""

import numpy as np
import pytest

from kilobot_twin.analysis import mean_cost_by_robot
from kilobot_twin.experiments import run_experiment
from kilobot_twin.experiments.common import Settings
from kilobot_twin.experiments.walks import coverage_peak_stats

_CACHE = {}


def outcome(name, quick=True, preset="paper"):
    key = (name, quick, preset)
    if key not in _CACHE:
        _CACHE[key] = run_experiment(name, Settings(preset=preset, quick=quick, progress=False))
    return _CACHE[key]


def _per_run_mean(cost, axis, sel):
    """Mean over the selected robots, per run: (runs,) independent samples."""
    return cost[:, sel].mean(axis=1)


def _assert_less(a, b, k=3.0):
    """mean(a) < mean(b) by more than k standard errors of the difference (paired by run)."""
    d = b - a
    se = d.std(ddof=1) / np.sqrt(len(d))
    assert d.mean() > k * se, f"difference {d.mean():.3f} not > {k} x SE {se:.3f}"


def _minimum_ratio(axis, cost, side):
    """Cost near the P_R = 0.5 minimum on one side over the cost of the ideal robot, with SE.

    The minimum is located on the first half of the runs and measured on the second half, so
    picking the lowest of noisy points does not bias the ratio. Robots within +-0.0025 of a
    bias are pooled (the paper's mean line is smooth on that scale).
    """
    half = cost.shape[0] // 2
    pick, test = cost[:half].mean(axis=0), cost[half:]
    cand = np.flatnonzero((side * axis >= 0.012) & (side * axis <= 0.034))
    smooth = [pick[np.abs(axis - axis[i]) <= 0.0025].mean() for i in cand]
    b_min = axis[cand[int(np.argmin(smooth))]]
    m = test[:, np.abs(axis - b_min) <= 0.0025].mean(axis=1)
    z = test[:, np.abs(axis) <= 0.0025].mean(axis=1)
    ratio = m.mean() / z.mean()
    se = ratio * np.sqrt(m.var(ddof=1) / (len(m) * m.mean() ** 2) + z.var(ddof=1) / (len(z) * z.mean() ** 2))
    return b_min, ratio, se


def _phototaxis_shapes(o, strict):
    axis, cost = o.data["bias_axis"], o.data["cost_m"]
    g05, g1, g025 = 1, 2, 0
    for side in (-1, 1):
        b_min, ratio, se = _minimum_ratio(axis, cost[g05], side)
        assert 0.012 <= abs(b_min) <= 0.034
        assert ratio + 3 * se < 1.0, (b_min, ratio, se)     # a non-zero bias beats the ideal robot
        # The paper: at least 2x lower. At reduced size: not rejected at 3 SE; full size: met.
        assert ratio <= 0.5 + (0 if strict else 3 * se), (b_min, ratio, se)
    # U shape: the extremes are worse than the ideal robot.
    zero = np.abs(axis) <= 0.0025
    _assert_less(_per_run_mean(cost[g05], axis, zero), _per_run_mean(cost[g05], axis, np.abs(axis) >= 0.038))
    # P_R = 1.0 favours right-biased, P_R = 0.25 left-biased robots.
    _assert_less(_per_run_mean(cost[g1], axis, axis > 0.005), _per_run_mean(cost[g1], axis, axis < -0.005))
    _assert_less(_per_run_mean(cost[g025], axis, axis < -0.005), _per_run_mean(cost[g025], axis, axis > 0.005))


def test_phototaxis_shapes_quick():
    _phototaxis_shapes(outcome("phototaxis"), strict=False)


@pytest.mark.slow
def test_phototaxis_shapes_full():
    o = outcome("phototaxis", quick=False)
    _phototaxis_shapes(o, strict=True)
    # At full size the acceptable ranges and the P_R = 1 cliff match the paper's.
    checks = {c.fact: c for c in o.checks}
    for p in (0.25, 0.5, 1.0):
        assert checks[f"R_acc at delta_acc = 0.75 m, P_R = {p}"].met
    assert checks["P_R = 1.0: cliff between -0.009 and -0.005"].met


def test_argos_code_preset_runs_the_authors_controller_and_stays_flat():
    """With the bias axis taken literally, the P_R = 0.5 curve has no deep minima (why the
    paper preset scales it): the best robots are not 2x better than the ideal one."""
    o = outcome("phototaxis", preset="argos-code")
    assert o.meta["scenario"]["behavior"]["kind"] == "phototaxis_argos"
    mc = mean_cost_by_robot(o.data["cost_m"])[1]
    axis = o.data["bias_axis"]
    assert mc.min() > 0.5 * mc[np.argmin(np.abs(axis))]


@pytest.mark.parametrize("quick", [True, pytest.param(False, marks=pytest.mark.slow)])
def test_coverage_peaks_near_zero_bias(quick):
    o = outcome("random_walk", quick=quick)
    mid, ext, ratio, se = coverage_peak_stats(o.data["bias"], o.data["coverage_m2"])
    assert ratio + 3 * se < 1.0
    if not quick:
        assert abs(ratio - 0.75) < 0.1  # the paper's extremes keep ~75 %


def test_ensemble_sigma_exceeds_mean_individual_sigma():
    o = outcome("bias_per_robot")
    est = o.data["estimated"]  # (trials, robots)
    sigma_i = est.std(axis=0, ddof=1)
    sigma = est.std(ddof=1)
    # Bootstrap over robots for the SE of (sigma - mean sigma_i).
    rng = np.random.default_rng(0)
    diffs = []
    for _ in range(300):
        idx = rng.integers(0, est.shape[1], est.shape[1])
        e = est[:, idx]
        diffs.append(e.std(ddof=1) - e.std(axis=0, ddof=1).mean())
    assert sigma - sigma_i.mean() > 3 * np.std(diffs)


def test_switch_count_spread_matches_clock_rate_spread():
    o = outcome("frequency")
    sw = o.data["switches"].astype(float).mean(axis=0)
    rates = o.data["clock_rate"]
    # Expected counts: floor(31 c T / 30); their relative spread is the clock-rate spread.
    rel_sw = sw.std(ddof=1) / sw.mean()
    rel_rate = rates.std(ddof=1) / rates.mean()
    n = len(rates)
    # Rounding to whole switches adds variance 1/12 per robot; allow 3 SE of an sd estimate.
    tol = 3 * rel_rate / np.sqrt(2 * (n - 1)) + np.sqrt(1 / 12) / sw.mean()
    assert abs(rel_sw - rel_rate) < tol
    assert np.corrcoef(sw, rates)[0, 1] > 0.99


def test_medium_kuramoto_coupling_synchronises_weak_and_too_strong_do_not():
    o = outcome("kuramoto")
    k, final = o.data["k"], o.data["final_order"]
    assert final[k == 0][0] < 0.5 and final[k == 0.003][0] < 0.5
    assert final[k == 1.0][0] > 0.9
    assert final[k == k.max()][0] < 0.9


def test_sensing_and_decalibration_and_straight_checks_met():
    for name in ("sensing", "decalibration", "straight"):
        o = outcome(name)
        failed = [c.fact for c in o.checks if not c.met]
        assert not failed, (name, failed)
