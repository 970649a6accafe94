"""The detection's F statistics where the model's robots differ in noise. Weighed by each robot's
variance under the model, the one-way F of robots over trials is F(N - 1, n - N) and the trend F
is F(N, N (K - 2)) exactly, whatever the variances (a weighted least-squares fit's sums of
squares over known variances): the expected laws come from that theory (scipy's F), the data
from plain normal draws here. The pooled statistics, which the workflow used before, fail the
same checks once one robot is noisier, which is what the checks are shown to catch."""

import numpy as np
from scipy import stats

from kilobot_twin.gap.workflow import _f_between, _f_trend, detect, model_variances

N, K = 8, 5
ONE_NOISY = np.r_[15.0, np.ones(N - 1)]
LOGNORMAL = np.exp(0.8 * np.random.default_rng(5).standard_normal(N))


def _draws(var, reps=20000, seed=1, level=3.0):
    rng = np.random.default_rng(seed)
    return level + rng.standard_normal((reps, K, N)) * np.sqrt(var)


def _ks_p(sample, dist):
    return stats.kstest(sample, dist.cdf).pvalue


def test_weighed_between_robot_f_has_the_f_law_whatever_the_robots_noise():
    law = stats.f(N - 1, N * (K - 1))
    for var in (ONE_NOISY, LOGNORMAL):
        x = _draws(var)
        # the weights' scale does not matter: only ratios of variances enter
        assert _ks_p(np.exp(_f_between(x, v=7.0 * var)), law) > 1e-3
    # the pooled F does not have that law with one robot 15x as variable (what the check catches)
    assert _ks_p(np.exp(_f_between(_draws(ONE_NOISY))), law) < 1e-6


def test_weighed_trend_f_has_the_f_law_whatever_the_robots_noise():
    law = stats.f(N, N * (K - 2))
    for var in (ONE_NOISY, LOGNORMAL):
        assert _ks_p(np.exp(_f_trend(_draws(var, seed=2), 0.01 * var)), law) > 1e-3
    assert _ks_p(np.exp(_f_trend(_draws(ONE_NOISY, seed=2))), law) < 1e-6


def test_weighed_f_with_gaps_keeps_its_law():
    """Robots missing from trials (NaN) count with the trials they have."""
    var = ONE_NOISY
    x = _draws(var, seed=3)
    x[:, 1, 2] = np.nan
    x[:, 3, 0] = np.nan
    n = K * N - 2
    assert _ks_p(np.exp(_f_between(x, v=var)), stats.f(N - 1, n - N)) > 1e-3


def test_model_variances_read_each_robots_variance_off_the_null():
    rng = np.random.default_rng(4)
    M = 120
    noisy = model_variances("motion", {"turn_rate": rng.standard_normal((M, K, N)) * np.sqrt(ONE_NOISY)})
    for key in ("turn_rate", "turn_rate:line"):
        ratio = noisy[key] / np.median(noisy[key])
        # each robot's variance from M (K - 1) = 480 (or M (K - 2)) degrees of freedom: a few % of sd
        assert abs(np.log(ratio[0] / 15.0)) < 4 * np.sqrt(2 / (M * (K - 2)))
        assert np.all(np.abs(np.log(ratio[1:])) < 4 * np.sqrt(2 / (M * (K - 2))))
    alike = model_variances("motion", {"turn_rate": rng.standard_normal((M, K, N))})
    # robots alike are pulled to one variance by as much as they differ only by replicate noise
    assert np.ptp(np.log(alike["turn_rate"])) < np.sqrt(2 / (M * (K - 1)))
    # robots missing from trials: a robot seen in 2 of 3 trials lies on its line exactly and
    # has no variance of its own about it (it takes the typical robot's), and the others' are read
    # on their own counts of trials (studentised), so robots alike still weigh alike
    x = rng.standard_normal((M, 3, N))
    x[:, 0, 2] = x[:, 1, 4] = x[:, 2, 5] = x[:, 0, 5] = np.nan  # robot 5 seen in one trial only
    gaps = model_variances("motion", {"turn_rate": x})
    for key in ("turn_rate", "turn_rate:line"):
        assert np.all(np.isfinite(gaps[key])) and np.ptp(np.log(gaps[key])) < 4 * np.sqrt(2 / M)
    # kinds without such summaries weigh nothing
    assert model_variances("blink", {"toggle_rate": rng.standard_normal((M, K, N))}) == {}


def _motion(rng, turn):
    shape = turn.shape
    return {"turn_rate": turn, "speed": 0.01 + 1e-4 * rng.standard_normal(shape),
            "diffusion": 1.0 + 0.1 * rng.standard_normal(shape), "heading": rng.uniform(-np.pi, np.pi, shape)}


def test_detect_does_not_flag_a_noisy_robots_line_that_its_own_noise_explains():
    """One robot 15x as variable as the rest (the model knows it) whose trials lie on a line
    3.5 of its own sds long (t about 3.5 on its 6 degrees of freedom): weighed, the trend is that
    robot's chance; pooled, its squares were the whole statistic (independent world 3087)."""
    K8, M = 8, 120
    var = np.r_[15.0, np.ones(N - 1)] * 1e-6
    rng = np.random.default_rng(6)
    null = _motion(rng, rng.standard_normal((M, K8, N)) * np.sqrt(var))
    turn = rng.standard_normal((K8, N)) * np.sqrt(var)
    k = np.arange(K8) - (K8 - 1) / 2
    line = k / np.sqrt((k**2).sum()) * 3.5 * np.sqrt(var[0])  # slope^2 S_kk = 3.5^2 of its variance
    turn[:, 0] = line + 0.3 * np.sqrt(var[0]) * rng.standard_normal(K8)
    meas = _motion(rng, turn)
    found = {f["signal"]: f for f in detect("motion", meas, null, K8, 0.01)}
    assert not found["turn_rate:trial_trend"]["flagged"]
    # the quiet robots' own drift, 0.5 of their sd per trial, is flagged beside the noisy robot
    drift = np.where(var > 2e-6, 0.0, 0.5 * np.sqrt(1e-6)) * k[:, None]
    meas = _motion(rng, rng.standard_normal((K8, N)) * np.sqrt(var) + drift)
    found = {f["signal"]: f for f in detect("motion", meas, null, K8, 0.01)}
    assert found["turn_rate:trial_trend"]["flagged"]
