"""The base's noise levels come with intervals (effects.noise_intervals): a bootstrap over robots
of the statistics the fit solves, on the fit's map. Checked here against a world written out in
the test (per-robot summaries drawn with numpy, robots that differ in how much they wander) whose
statistics are linear in the noise variances by construction: over fresh datasets, each 90 %
interval must hold the truth about 90 % of the time."""

import numpy as np
import pytest

from kilobot_twin.core.constants import WHEEL_SEPARATION_M
from kilobot_twin.gap import effects as E

K = 4
TRUE = {"sigma_omega": 0.01, "sigma_v": 6e-4, "speed_trial_sd": 0.02, "bias_trial_sd": 0.0035}
SPEED = 0.013  # m/s, the model's forward speed; a trial's bias is b = -omega L / v (paper Eq. 7)
# The map from (sigma_omega^2, sigma_v^2, speed_trial_sd^2, bias_trial_sd^2) to the four statistics
# (diffusion, within-robot variance of trial speeds, speed diffusion, within-robot variance of
# trial turn rates) and the noiseless intercept, as the twin's simulations gave them for 12 robots
# x 4 trials at 10 Hz; the bias column is (v / L)^2, so that b's variance reads bias_trial_sd^2.
A = np.array([[0.616, -2.58, -4.5e-4, -8.8e-4],
              [-2.2e-8, 0.0179, 1.63e-4, 1.6e-7],
              [3.3e-5, 0.922, 1.3e-5, 3.5e-5],
              [0.0209, 1.5e-3, 2.5e-6, (SPEED / WHEEL_SEPARATION_M) ** 2]])
S0 = np.array([1.46e-6, 9e-10, 1.17e-7, 4.1e-8])


def _dataset(rng, N=30, S0=S0):
    """One dataset of the written-out world: (K, N) summaries whose means are S0 + A @ variances.
    The diffusion is skewed (gamma) and carries a per-robot factor (robots wander differently),
    so robots, not cells, are the units that sample it; the speeds and turn rates carry per-robot
    levels, which the within-robot statistics must not see."""
    v = np.array([TRUE["sigma_omega"] ** 2, TRUE["sigma_v"] ** 2, TRUE["speed_trial_sd"] ** 2, 0.0])
    mean = S0 + A @ v
    robot = np.exp(rng.normal(0.0, 0.5, N) - 0.125)  # each robot's own wander, mean 1
    diffusion = mean[0] * robot[None, :] * rng.gamma(2.0, 0.5, (K, N))
    speed = SPEED * rng.uniform(0.8, 1.2, N)[None, :] + np.sqrt(mean[1]) * rng.standard_normal((K, N))
    speed_diffusion = mean[2] * rng.gamma(2.0, 0.5, (K, N))
    # turn rates: what measurement and the noises make (mean[3]) plus the trial-to-trial bias
    # spread, in turn-rate units (rad/s): b = -omega L / v
    sd = np.sqrt(mean[3] + A[3, 3] * TRUE["bias_trial_sd"] ** 2)
    turn_rate = -0.002 + sd * rng.standard_normal((K, N))
    return {"diffusion": diffusion, "speed": speed, "speed_diffusion": speed_diffusion, "turn_rate": turn_rate}


def _model(N=30):
    m = E.nominal_model("motion", np.arange(N), SPEED)
    m.noise_map = {"map": A, "intercept": S0,
                   # what measurement and white noise make of a trial's bias variance
                   "bias_est_var": (WHEEL_SEPARATION_M / SPEED) ** 2 * (S0[3] + A[3, :3] @ [TRUE[k] ** 2 for k in
                                                                                            ("sigma_omega", "sigma_v", "speed_trial_sd")])}
    return m


R = 300  # fresh datasets per coverage check: a coverage's binomial sd is 0.017 at 0.90


def _coverage(model, draw, truth: dict, rng) -> dict:
    """How often each level's 90 % interval holds its truth over R datasets ``draw(rng)``; the
    model (or a fresh one, when ``model`` is callable) states an interval for every level."""
    hits = {k: 0 for k in truth}
    for _ in range(R):
        m = model(rng) if callable(model) else model
        ci = E.noise_intervals(m, draw(rng), rng, boot=200, level=0.9)
        assert set(ci) == set(truth)
        for k, (lo, hi) in ci.items():
            hits[k] += lo <= truth[k] <= hi
    return {k: v / R for k, v in hits.items()}


def _within(cover: dict, floor: float, ceiling: float = 0.90) -> None:
    """Each coverage within floor - 3 sd .. ceiling + 3 sd (binomial sd at 0.90)."""
    sd = np.sqrt(0.9 * 0.1 / R)
    for k, c in cover.items():
        assert floor - 3 * sd <= c <= ceiling + 3 * sd, (k, c)


@pytest.mark.parametrize("robots, floor", [(30, 0.87), (6, 0.84)])
def test_ninety_percent_intervals_hold_the_truth_about_ninety_percent_of_the_time(robots, floor):
    """300 fresh datasets: each level's coverage is binomial about its true coverage (sd 0.017 at
    0.90). A bootstrap interval covers a little below its level on skewed data and few units;
    ``floor`` is the least coverage of the four levels' intervals measured over 400 datasets of
    this world (30 robots: 0.87-0.895; 6 robots: 0.84-0.87), and the band is floor - 3 sd ..
    0.90 + 3 sd. It fails if a robot's trials are resampled as if they were robots (the
    per-robot wander is then left out), if the solve forgets the noiseless intercept, or on 6
    robots if the percentiles are not expanded (plain ones cover 0.74-0.80 there)."""
    rng = np.random.default_rng(20261130 + robots)
    _within(_coverage(_model(robots), lambda g: _dataset(g, robots), TRUE, rng), floor)


def _simulated_model(rng, N, S0_sim, M, sd):
    """A base whose map and intercept were read off simulations of M replicates each (the
    noiseless one, then each noise at its probe level), every statistic of a replicate off its
    mean by ``sd`` (relative, normal): the map carries Monte Carlo error, as a fit's does."""
    probes = [0.02, 0.001, 0.03, 0.02]
    means = [S0_sim] + [S0_sim + A[:, j] * p**2 for j, p in enumerate(probes)]
    reps = [mu * (1 + sd * rng.standard_normal((M, 4))) for mu in means]
    centre = [np.r_[r[:, :3].mean(0), np.median(r[:, 3])] for r in reps]  # as the fit centres them
    A_hat = np.column_stack([(centre[j + 1] - centre[0]) / p**2 for j, p in enumerate(probes)])
    m = _model(N)
    m.noise_map.update(map=A_hat, intercept=centre[0], replicates=reps, probe_levels=probes)
    return m


def test_intervals_carry_the_maps_monte_carlo_error_where_the_intercept_is_most_of_the_signal():
    """Heavy tracking noise makes most of the diffusion (here 6x what the heading noise adds):
    the intercept, read off 5 replicates that scatter by 30 %, is then about as uncertain as the
    robots' mean. Over 300 fresh datasets, each with its own simulations, the intervals
    (replicates resampled beside the robots) hold the truth at least about as often as their
    level: over 400 datasets (another seed) 0.88-0.965, the map's noisy columns dividing making
    some wider than the level asks; solved on the map as read, the replicates not resampled,
    0.69-0.875. The band's floor is 0.87 - 3 sd."""
    rng = np.random.default_rng(11)
    N = 30
    S0_sim = S0 + np.array([6 * A[0, 0] * TRUE["sigma_omega"] ** 2, 0.0, 0.0, 0.0])
    cover = _coverage(lambda g: _simulated_model(g, N, S0_sim, M=5, sd=0.3), lambda g: _dataset(g, N, S0_sim), TRUE, rng)
    _within(cover, 0.87, ceiling=1.0)


def test_more_robots_narrow_the_intervals_as_one_over_root_n():
    """The width of an interval from a bootstrap over robots falls as 1 / sqrt(robots): 4x the
    robots, half the width (averaged over 20 datasets each, so the ratio's sd is a few per cent;
    on 60 and 15 robots the expansion differs by 1 %)."""
    rng = np.random.default_rng(7)
    widths = {}
    for n in (15, 60):
        model = _model(n)
        widths[n] = np.mean([np.diff(E.noise_intervals(model, _dataset(rng, n), rng, boot=200)["sigma_omega"])[0]
                             for _ in range(20)])
    assert widths[60] / widths[15] == pytest.approx(0.5, abs=0.08)


def test_a_model_whose_noise_was_not_fitted_here_has_no_intervals():
    """A base read from the user's model file (no map) and the other kinds state none."""
    rng = np.random.default_rng(1)
    assert E.noise_intervals(E.nominal_model("motion", np.arange(30)), _dataset(rng), rng) == {}
    assert E.noise_intervals(E.nominal_model("light_sweep", np.arange(30)), {}, rng) == {}


# The light sensor's two noises (effects.fit_sensor_noise): the within-robot variances of a
# robot's fitted gain and offset from sweep to sweep are linear in the reading noise's variance
# above the ADC's rounding floor and the offset's trial-to-trial variance; map, intercept and row
# weights as a fit to 12 robots x 4 sweeps of the independent world gave them.
SENSOR_MAP = np.array([[0.482, -0.00226], [0.00615, 1.05]])
SENSOR_R0 = np.array([0.465, 0.00469])
SENSOR_TRUE = {"sensor_noise": 26.7, "sensor_offset_trial_sd": 4.6}  # counts: per sample; per sweep
ROUNDING_VAR = 1.0 / 12.0  # a 1-count ADC step


def _sweeps(rng, N):
    """(K, N) gains and offsets, each robot its own level, the sweep-to-sweep deviations normal
    (a gain and an offset are fitted over hundreds of readings) with the variances the map gives."""
    v = np.array([SENSOR_TRUE["sensor_noise"] ** 2 - ROUNDING_VAR, SENSOR_TRUE["sensor_offset_trial_sd"] ** 2])
    var = SENSOR_R0 + SENSOR_MAP @ v

    def dev():
        return rng.standard_normal((K, N))

    return {"gain": 3300 * rng.uniform(0.8, 1.2, N)[None, :] + np.sqrt(var[0]) * dev(),
            "offset": rng.normal(0, 10, N)[None, :] + np.sqrt(var[1]) * dev()}


def _sensor_model(N, quiet=False):
    m = E.nominal_model("light_sweep", np.arange(N))
    # fitted without reading noise: the offsets' column alone
    m.noise_map = {"sensor_map": SENSOR_MAP[:, 1:] if quiet else SENSOR_MAP, "sensor_intercept": SENSOR_R0,
                   "sensor_weights": 1.0 / np.abs(SENSOR_MAP).max(axis=1)}
    return m


@pytest.mark.parametrize("robots, floor", [(12, 0.87), (6, 0.84)])
def test_the_sensor_noises_intervals_hold_the_truth_about_ninety_percent_of_the_time(robots, floor):
    """As for motion: 300 fresh datasets of the written-out sweeps, the band floor - 3 sd .. 0.90 +
    3 sd, ``floor`` the least coverage of the two levels measured over 400 datasets (12 robots:
    0.87-0.905; 6 robots: 0.84-0.85). (A variance's bootstrap covers less where the deviations
    are heavy-tailed: t on 5 dof, 0.78-0.84.)"""
    rng = np.random.default_rng(20261201 + robots)
    _within(_coverage(_sensor_model(robots), lambda g: _sweeps(g, robots), SENSOR_TRUE, rng), floor)


def test_a_sensor_fitted_without_noise_states_an_interval_for_its_offsets_alone():
    """The kind of sensor is chosen by simulation, not estimated: a base without reading noise
    keeps none in every resample, and its offsets' spread is read from the offsets' column alone."""
    rng = np.random.default_rng(3)
    ci = E.noise_intervals(_sensor_model(12, quiet=True), _sweeps(rng, 12), rng, boot=200)
    assert set(ci) == {"sensor_offset_trial_sd"} and ci["sensor_offset_trial_sd"][0] > 0


# The clocks' trial-to-trial jitter (effects._jitter_at_its_timing): identical clocks whose rate
# each trial scales by 1 + jitter z, counted against frames with a relative timing error of its
# own; the fit puts TIMING^2 of the rates' spread down to timing.
JITTER, TIMING = 0.002, 0.0015


def _clocks(rng, N, K=4):
    return {"toggle_rate": 0.26 * (1 + JITTER * rng.standard_normal((K, N)) + TIMING * rng.standard_normal((K, N)))}


def _clock_model(N, K=4):
    m = E.nominal_model("blink", np.arange(N))
    m.noise_map = {"clock_timing": TIMING**2, "clock_keep": np.ones((K, N), bool), "clock_clip": np.inf, "clock_own": False}
    return m


@pytest.mark.parametrize("robots, floor", [(16, 0.825), (6, 0.83)])
def test_the_clock_jitters_interval_holds_the_truth_about_ninety_percent_of_the_time(robots, floor):
    """300 fresh datasets of the written-out clocks, the band floor - 3 sd .. 0.90 + 3 sd,
    ``floor`` the least coverage measured over 400 datasets (16 robots: 0.825, 0.845 and 0.865 in
    three runs; 6 robots: 0.83). A percentile interval of a variance from a few dozen rates covers
    below its level: the sampling distribution is skewed the other way (bias-corrected
    percentiles gained 2 points in a trial, not adopted). Without the timing part taken off, the
    interval misses the truth in nearly every dataset."""
    rng = np.random.default_rng(20261202 + robots)
    _within(_coverage(_clock_model(robots), lambda g: _clocks(g, robots), {"clock_trial_sd": JITTER}, rng), floor)
