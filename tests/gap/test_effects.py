"""Named effects recover what was hidden, each parameter from its own signal."""

import numpy as np

from kilobot_twin.gap import effects as E
from kilobot_twin.gap.model import Conditions, simulate


def _conditions(n=12, trials=4, duration=60.0, dt=0.1):
    T = int(round(duration / dt)) + 1
    rng = np.random.default_rng(0)
    start = (np.zeros((trials, n)), np.zeros((trials, n)), rng.uniform(-np.pi, np.pi, (trials, n)))
    return Conditions("motion", np.arange(n), trials, duration, dt, np.ones((trials, n, T), bool), start)


def test_motion_noise_fits_heading_and_speed_noise_separately():
    """Only the speed noise is 4x the nominal robot's: the fit must raise sigma_v about 4x and leave
    sigma_omega near nominal (one common scale for both cannot do both). 24 robots x 8 trials, so
    that the heading-diffusion statistic is precise enough to tell."""
    cond = _conditions(n=24, trials=8)
    nominal = E.nominal_model("motion", cond.robot_ids)
    truth = nominal.swarm.with_values(sigma_v=4 * nominal.swarm.sigma_v)
    meas = {k: v[0] for k, v in simulate(cond, truth, 1, seed=21).items()}
    meas["_trials"] = np.arange(cond.trials)
    ref = simulate(cond, nominal.swarm, 20, seed=22)
    fitted = E.LIBRARY["motion_noise"].fit(nominal, meas, ref, lambda m: simulate(cond, m.swarm, 20, seed=23))
    # Tolerances from the statistics: each scale is the square root of a variance-like statistic,
    # so its relative sd is half that statistic's relative sd across replicates (of the truth);
    # 4 of those either side.
    stats = E._noise_stats(simulate(cond, truth, 20, seed=24))  # (M, 2): diffusion, speed variance
    tol_w, tol_v = 4 * 0.5 * stats.std(axis=0, ddof=1) / stats.mean(axis=0)
    v_ratio = fitted.swarm.sigma_v[0] / nominal.swarm.sigma_v[0]
    w_ratio = fitted.swarm.sigma_omega[0] / nominal.swarm.sigma_omega[0]
    assert 4 * (1 - tol_v) < v_ratio < 4 * (1 + tol_v), (v_ratio, tol_v)
    assert 1 - tol_w < w_ratio < 1 + tol_w, (w_ratio, tol_w)
