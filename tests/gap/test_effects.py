"""The base fits every nuisance from within-robot statistics, each from its own signal."""

import numpy as np

from kilobot_twin.gap import effects as E
from kilobot_twin.gap.model import Conditions, simulate


def _conditions(n=12, trials=4, duration=60.0, dt=0.1):
    T = int(round(duration / dt)) + 1
    rng = np.random.default_rng(0)
    start = (np.zeros((trials, n)), np.zeros((trials, n)), rng.uniform(-np.pi, np.pi, (trials, n)))
    return Conditions("motion", np.arange(n), trials, duration, dt, np.ones((trials, n, T), bool), start)


def _check(truth_model, cond, seed):
    """Fit the noise levels of one simulated dataset of ``truth_model`` and return (fitted
    variances, true variances, their 4-sd tolerances). The tolerance propagates the replicate
    covariance of the three statistics (from 20 more datasets of the truth) through the fitted
    linear map, the way the estimate itself is computed."""
    nominal = E.nominal_model("motion", cond.robot_ids)
    meas = {k: v[0] for k, v in simulate(cond, truth_model, 1, seed=seed).items()}
    calls = iter(range(100))
    fitted = E.fit_noise_levels(nominal, meas, lambda m: simulate(cond, m, 20, seed=1000 + next(calls)))
    stats = E._noise_stats(simulate(cond, truth_model, 20, seed=seed + 1))  # (20, 3)
    pw, pv, ps = E.PROBE["sigma_omega"], E.PROBE["sigma_v"], E.PROBE["speed_trial_sd"]
    z = nominal.with_traits(sigma_omega=np.zeros(len(cond.robot_ids)), sigma_v=np.zeros(len(cond.robot_ids)))
    s = [np.nanmean(E._noise_stats(simulate(cond, m, 20, seed=2000 + j)), axis=0) for j, m in enumerate((
        z, z.with_traits(sigma_omega=np.full(len(cond.robot_ids), pw)),
        z.with_traits(sigma_v=np.full(len(cond.robot_ids), pv)), z.with_traits(speed_trial_sd=ps)))]
    A = np.column_stack([(s[1] - s[0]) / pw**2, (s[2] - s[0]) / pv**2, (s[3] - s[0]) / ps**2])
    Ai = np.linalg.inv(A)
    sd = np.sqrt(np.diag(Ai @ np.cov(stats.T) @ Ai.T))
    got = np.array([fitted.swarm.sigma_omega[0] ** 2, fitted.swarm.sigma_v[0] ** 2, fitted.speed_trial_sd ** 2])
    true = np.array([truth_model.swarm.sigma_omega[0] ** 2, truth_model.swarm.sigma_v[0] ** 2,
                     truth_model.speed_trial_sd ** 2])
    return got, true, 4 * sd


def test_noise_levels_are_fitted_separately():
    """Speed noise 4x the nominal robot's, heading noise nominal, no trial-to-trial speed
    jitter: each variance comes back within 4 sd (one common scale could not do it)."""
    cond = _conditions(n=16, trials=6)
    nominal = E.nominal_model("motion", cond.robot_ids)
    truth = nominal.with_traits(sigma_v=4 * nominal.swarm.sigma_v)
    got, true, tol = _check(truth, cond, seed=21)
    assert np.all(np.abs(got - true) <= tol), (got, true, tol)
    assert tol[1] < 0.5 * true[1]  # the speed-noise estimate is informative


def test_absent_speed_noise_and_trial_speed_jitter():
    """A world with no speed noise at all and 3 % trial-to-trial speed jitter: the fit does not
    break (variances are non-negative) and attributes the jitter to the trials, not the noise."""
    cond = _conditions(n=16, trials=6)
    nominal = E.nominal_model("motion", cond.robot_ids)
    truth = nominal.with_traits(sigma_v=np.zeros(16), speed_trial_sd=0.03)
    got, true, tol = _check(truth, cond, seed=31)
    assert np.all(got >= 0) and np.all(np.abs(got - true) <= tol), (got, true, tol)
    assert tol[2] < true[2]  # the jitter is told apart from none (more than 4 sd)
