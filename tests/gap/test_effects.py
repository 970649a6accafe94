"""The base fits every nuisance from within-robot statistics, each from its own signal."""

import numpy as np
import pytest

from kilobot_twin.gap import effects as E
from kilobot_twin.gap.model import Conditions, simulate
from kilobot_twin.gap.summaries import robust_sd
from . import benchmark


def _conditions(n=12, trials=4, duration=60.0, dt=0.1):
    T = int(round(duration / dt)) + 1
    rng = np.random.default_rng(0)
    start = (np.zeros((trials, n)), np.zeros((trials, n)), rng.uniform(-np.pi, np.pi, (trials, n)))
    return Conditions("motion", np.arange(n), trials, duration, dt, np.ones((trials, n, T), bool), start)


def _variances(m):
    return np.array([m.swarm.sigma_omega[0] ** 2, m.swarm.sigma_v[0] ** 2, m.speed_trial_sd ** 2])


def _check(truth_model, cond, seed):
    """Fit the noise levels of one simulated dataset of ``truth_model`` and return (fitted
    variances, true variances, their 4-sd tolerances) of heading noise, speed noise and trial
    speed jitter. The tolerance propagates the replicate covariance of the three statistics
    the fit solves for them (from 20 more datasets of the truth) through the linear map
    (probes simulated here, one at a time), the way the estimate itself is computed when the
    turn rates' bound does not bind."""
    nominal = E.nominal_model("motion", cond.robot_ids)
    n = len(cond.robot_ids)
    meas = {k: v[0] for k, v in simulate(cond, truth_model, 1, seed=seed).items()}
    calls = iter(range(100))
    fitted = E.fit_noise_levels(nominal, meas, lambda m: simulate(cond, m, 20, seed=1000 + next(calls)))
    stats = E._noise_stats(simulate(cond, truth_model, 20, seed=seed + 1))[:, :3]  # (20, 3)
    z = nominal.with_traits(sigma_omega=np.zeros(n), sigma_v=np.zeros(n), bias_trial_sd=np.zeros(n))
    probes = [z.with_traits(sigma_omega=np.full(n, 0.02)), z.with_traits(sigma_v=np.full(n, 0.001)),
              z.with_traits(speed_trial_sd=0.03)]
    s = [np.nanmean(E._noise_stats(simulate(cond, m, 20, seed=2000 + j))[:, :3], axis=0) for j, m in enumerate([z] + probes)]
    A = np.column_stack([(s[j + 1] - s[0]) / (_variances(p) - _variances(z))[j] for j, p in enumerate(probes)])
    Ai = np.linalg.inv(A)
    sd = np.sqrt(np.diag(Ai @ np.cov(stats.T) @ Ai.T))
    return _variances(fitted), _variances(truth_model), 4 * sd


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


def test_heading_noise_is_bounded_by_the_turn_rates_under_heavy_tracking_noise():
    """4.5 mm tracking noise and a quiet heading (0.003 rad/sqrt(s)), robots with persistent
    biases of 0.01-0.02 (what ``heading_bias`` hides): the heading diffusion then scatters by more
    than the noise it measures, and a fit on it alone gave sigma_omega 3x the truth. The fitted
    heading noise alone must not make the robots vary from trial to trial more than the data's
    do: the data's within-robot variance of the turn rates is not below the 0.5 % point of
    simulations of the fitted noise (the expected value comes from simulating the fit, not from
    the fit itself), on each of 6 datasets. (Less noise than the truth is allowed: the rest of
    that variance can be trial-to-trial bias, which the effects fit.)"""
    cond = _conditions(n=12, trials=4, duration=60.0, dt=0.1)
    cond = Conditions(**{**cond.__dict__, "tracking_noise_m": 0.0045})
    nominal = E.nominal_model("motion", cond.robot_ids)
    rng = np.random.default_rng(5)
    truth = nominal.with_traits(sigma_omega=np.full(12, 0.003), sigma_v=np.zeros(12),
                                heading_bias=rng.normal(0, 0.018, 12))
    for seed in range(6):
        meas = {k: v[0] for k, v in simulate(cond, truth, 1, seed=300 + seed).items()}
        calls = iter(range(100))
        fitted = E.fit_noise_levels(nominal, meas, lambda m: simulate(cond, m, 20, seed=4000 + 10 * seed + next(calls)))
        # the fitted noise on the true robots (per-robot biases do not change the within-robot variance)
        sims = simulate(cond, truth.with_traits(sigma_omega=fitted.swarm.sigma_omega), 40, seed=5000 + seed)
        within = E.within_var(sims["turn_rate"])  # (40,)
        data = E.within_var(meas["turn_rate"])
        assert data >= np.percentile(within, 0.5), (seed, fitted.swarm.sigma_omega[0], data, np.percentile(within, 0.5))


def test_fitted_speed_noise_does_not_make_trial_speeds_vary_more_than_the_data():
    """A world with no speed noise at all (item 1: zero where physical), 12 robots x 4 trials.
    The speed diffusion, from which sigma_v is read, scatters by about its own size; with the
    trial jitter at its floor of 0 the fit took whatever it read, and simulations of the fitted
    model gave trial speeds 1.5-2.7x as variable within robots as the data's in 6 of 12 such
    datasets, enough to keep a right speed effect from resolving its signal. The data's
    within-robot variance of trial speeds must not be below the 0.5 % point of simulations of
    the fitted noise (the expected value from simulating the fit), on each of 8 datasets."""
    cond = _conditions(n=12, trials=4, duration=60.0, dt=0.1)
    cond = Conditions(**{**cond.__dict__, "tracking_noise_m": 0.001})
    nominal = E.nominal_model("motion", cond.robot_ids)
    truth = nominal.with_traits(sigma_v=np.zeros(12))
    for seed in range(8):
        meas = {k: v[0] for k, v in simulate(cond, truth, 1, seed=900 + seed).items()}
        calls = iter(range(100))
        fitted = E.fit_noise_levels(nominal, meas, lambda m: simulate(cond, m, 20, seed=9000 + 10 * seed + next(calls)))
        within = E.within_var(simulate(cond, fitted, 40, seed=9500 + seed)["speed"])  # (40,)
        data = E.within_var(meas["speed"])
        assert data >= np.percentile(within, 0.5), (seed, fitted.swarm.sigma_v[0], data / np.mean(within))


def test_speed_factors_are_not_compressed_by_tracking_noise():
    """6.6 mm tracking noise lengthens every 2 s chord (2.3 cm) by about the same amount, so the
    speed summary is not proportional to the speed. Speed factors with sd 0.1 over 24 robots x 6
    trials must come back with a fitted-vs-true slope within 10 % of 1 (the issue's target; one
    ratio to the population's simulation gave 0.73 on such data). The slope's own sampling sd
    here is about 0.01 (per-robot means over 6 trials against a spread of 0.1)."""
    cond = _conditions(n=24, trials=6, duration=60.0, dt=0.1)
    cond = Conditions(**{**cond.__dict__, "tracking_noise_m": 0.0066})
    nominal = E.nominal_model("motion", cond.robot_ids)
    rng = np.random.default_rng(8)
    sf = 1.0 + 0.1 * rng.standard_normal(24)
    truth = nominal.with_traits(speed_factor=sf)
    meas = E.Summaries({k: v[0] for k, v in simulate(cond, truth, 1, seed=41).items()}, np.arange(6))
    calls = iter(range(100))

    def resim(m):
        return simulate(cond, m, 10, seed=6000 + next(calls))

    fitted = E.LIBRARY["speed_heterogeneity"].fit(nominal, meas, resim(nominal), resim)
    slope = np.polyfit(sf, fitted.swarm.speed_factor, 1)[0]
    assert abs(slope - 1) <= 0.1, slope


def test_probes_move_their_statistic_under_heavy_tracking_noise():
    """6.6 mm tracking noise at 7.5 Hz: a heading noise of 0.02 (the first probe) moves the heading
    diffusion by less than 20 simulations scatter, and the map's column read from it was noise
    (negative on a dataset of the independent world, sigma_omega fitted 9x the truth). The probe
    must be raised until it moves the statistic: the column comes out positive (more heading
    noise, more diffusion), on 4 datasets. (The fitted level itself is not checked: at this
    tracking noise and frame rate chords reverse so often that some tracks still slip, and one
    such track can carry a dataset's diffusion 4 sd above its expectation.)"""
    cond = _conditions(n=24, trials=6, duration=55.0, dt=2 / 15)
    cond = Conditions(**{**cond.__dict__, "tracking_noise_m": 0.0066})
    nominal = E.nominal_model("motion", cond.robot_ids)
    truth = nominal.with_traits(sigma_omega=np.full(24, 0.016))
    for seed in range(4):
        meas = {k: v[0] for k, v in simulate(cond, truth, 1, seed=700 + seed).items()}
        calls = iter(range(100))
        fitted = E.fit_noise_levels(nominal, meas, lambda m: simulate(cond, m, 20, seed=7000 + 50 * seed + next(calls)))
        assert fitted.noise_map["diffusion_per_var"] > 0, (seed, fitted.noise_map)


def _blink(lead: str, jitter: float, timing: float = 1e-3, n: int = 40, trials: int = 8, seed: int = 0):
    """Toggle rates of n robots with differing clocks, trial-to-trial clock jitter ``jitter`` and
    a timing-to-frames error of sd ``timing``. ``aligned``: clocks start with the frames, so the
    timing error of a (trial, robot) is the same in the data and in every simulated replicate;
    ``random``: a fresh one each time. Returns (meas, resim) for :class:`effects.ClockDrift`."""
    rng = np.random.default_rng(seed)
    clocks = 1.0 + 0.02 * rng.standard_normal(n)
    fixed = timing * rng.standard_normal((trials, n))

    def rates(clock, sd, shape):
        e = fixed if lead == "aligned" else timing * rng.standard_normal(shape)
        return clock * (1.0 + sd * rng.standard_normal(shape)) * (1.0 + e)

    meas = {"toggle_rate": rates(clocks, jitter, (trials, n))}

    def resim(m, M=40):
        return {"toggle_rate": rates(m.swarm.clock_rate, m.swarm.clock_trial_sd, (M, trials, n))}

    return meas, resim


def test_clock_jitter_is_what_is_left_beyond_the_timing_error_however_the_clocks_start():
    """The within-robot spread of the rates is jitter^2 + timing^2; clock_drift's jitter is what
    is left once timing alone is taken out. With clocks aligned to the frames the replicates of a
    trial share its timing error, so their spread over replicates is 0 and must not stand for it
    (it did: the jitter came out sqrt(jitter^2 + timing^2), a right clock_drift left the robots'
    differences flagged). Tolerance: 4 sd of a pooled variance on n (K - 1) degrees of freedom."""
    n, K, timing, jitter = 40, 8, 1e-3, 1e-3
    dof = n * (K - 1)
    for lead in ("aligned", "random"):
        meas, resim = _blink(lead, jitter, timing, n, K)
        start = E.nominal_model("blink", np.arange(n)).with_traits(clock_trial_sd=np.full(n, 0.01))
        m = E.LIBRARY["clock_drift"].fit(start, meas, resim(start), resim)
        got = m.swarm.clock_trial_sd[0] ** 2
        # sampling sd of the data's pooled variance (the simulations' mean over 40 replicates adds
        # little); a second variance, timing's alone, is subtracted in the random case
        tol = 4 * (jitter**2 + timing**2) * np.sqrt(2 / dof) * (1.0 if lead == "aligned" else 1.2)
        assert abs(got - jitter**2) < tol, (lead, got / jitter**2, tol / jitter**2)


@pytest.mark.parametrize("data_timing, lead", [(0.75e-3, "random"), (0.12e-3, "aligned")])
def test_the_frame_lead_is_the_one_whose_timing_is_nearer_the_data(data_timing, lead):
    """Toggle rates written here: 40 robots x 8 trials whose timing to frames varies the rates by
    1e-3 afresh in every replicate with a random lead, and by 1e-4 with clocks started with the
    frames (fixed per trial and robot, as then). Data timed at 0.75e-3 vary 0.56x the random
    lead's variance, below its 2.5 % point (280 degrees of freedom: the replicates' spreads
    scatter by about 8.5 %), yet 56x the aligned clocks': they are taken for a random lead, as
    the random lead is nearer on a log scale (log 0.56 against log 56). Data timed at 0.12e-3
    (1.44x the aligned) are taken as aligned."""
    n, K = 40, 8
    rng = np.random.default_rng(2)
    fixed = 1e-4 * rng.standard_normal((K, n))

    def resim(m, M=40):
        e = fixed if m.frame_lead == "aligned" else 1e-3 * rng.standard_normal((M, K, n))
        return {"toggle_rate": np.broadcast_to(1.0 + e, (M, K, n))}

    meas = {"toggle_rate": 1.0 + data_timing * rng.standard_normal((K, n))}
    start = E.nominal_model("blink", np.arange(n)).with_traits(clock_trial_sd=np.zeros(n))
    random = E._spread_own(resim(start.with_traits(frame_lead="random"))["toggle_rate"])
    assert E._spread_own(meas["toggle_rate"]) < np.percentile(random, 2.5)  # the case the test is about
    assert E._frame_lead(start, meas, resim) == lead


def test_clock_drift_takes_the_frame_lead_that_its_own_clocks_allow(tmp_path):
    """Synth blink 3017 (16 robots, clock rates sd 0.015, clocks started with the frames, no
    clock jitter, dropped frames and tracking gaps), from a base on identical clocks that took a
    random lead (it did so by itself when toggle rates were plain counts: gaps shifted a few
    robots' first or last toggle; it is forced here now that rates are timed to sharp toggles).
    With the robots' own rates, a random lead times their toggles more unevenly (2.5 % point
    1.2e-8, median 2.8e-8) than the data vary at all (3.8e-9): a clock_drift that kept the lead
    predicted each robot's trials several times as variable as they are, and a right name
    resolved nothing. The data's within-robot spread must not be below the 2.5 % point of
    simulations of the fitted model (expected values from simulating the fit)."""
    from kilobot_twin.gap import workflow as W
    from kilobot_twin.gap.synth import synth

    synth("blink", "clock_drift", tmp_path / "d", seed=3017, nuisance={"clock_trial_sd": 0.0})
    cond, meas = W.measured_summaries(W._load_data(str(tmp_path / "d")))
    meas = E.Summaries(meas, np.arange(cond.trials))
    gs = W.GapSettings(seed=1, m_null=80, m_ref=12, m_score=20, boot=300)
    fitter = W._Fitter(cond, meas, E.nominal_model("blink", cond.robot_ids), gs, True)
    trials = list(range(cond.trials))
    fitter.cache[((), tuple(trials))] = fitter.fit((), trials).with_traits(frame_lead="random")  # the situation
    m = fitter.fit(("clock_drift",), trials)
    sims = E._spread_own(simulate(cond, m, 80, seed=5)["toggle_rate"])  # (80,)
    assert E._spread_own(meas["toggle_rate"]) >= np.percentile(sims, 2.5), (m.frame_lead, np.percentile(sims, [2.5, 50]))



def _square_wave_blinks(folder, seed, jitter, drop, n=24, trials=6, hz=7.5, tick_hz=31.3, half=9, span=100.0):
    """A measured-v1 blink dataset written here, by hand rather than by ``measured.write`` (the
    loader reads it as another program's file): each robot a square wave of ``half`` ticks a
    half, anywhere in its cycle at frame 0, its clock ``tick_hz`` times 1 + N(0, jitter) afresh
    in every trial, read every 1 / hz s with each frame but the first lost with probability
    ``drop``."""
    import json

    rng = np.random.default_rng(seed)
    t = np.arange(int(span * hz) + 1) / hz
    rows = ["trial,robot_id,t_s,led"]
    for k in range(trials):
        ticks = rng.uniform(0, 2 * half, (n, 1)) + t * tick_hz * (1 + jitter * rng.standard_normal((n, 1)))
        led = np.floor(ticks / half) % 2
        seen = rng.random(led.shape) >= drop
        seen[:, 0] = True
        rows += [f"{k},{i},{tt:.6f},{'blue' if v else 'red'}" for i in range(n) for tt, v in zip(t[seen[i]], led[i, seen[i]])]
    folder.mkdir()
    meta = {"format": "kilobot-twin/measured-v1", "kind": "blink", "dt_s": 1 / hz, "half_period_ticks": half,
            "nominal_tick_hz": tick_hz, "robots": list(range(n)), "trials": trials, "duration_s": span}
    (folder / "meta.yaml").write_text(json.dumps(meta))
    (folder / "observations.csv").write_text("\n".join(rows) + "\n")


@pytest.mark.parametrize("drop", [0.0, 0.02])
def test_clock_jitter_is_read_where_frames_time_the_toggles_regularly(tmp_path, drop):
    """Square waves written here (24 robots x 6 trials at 7.5 Hz for 100 s, a phase of 2.16
    frames, clock jitter 5e-4 per trial), 12 datasets: the base's fitted jitter is 5e-4 within 3
    standard errors of the 12 (their own sd), and that sd is at most twice what the data's
    spread allows: about 140 rates whose relative variance (rounding to frames, about 3e-7, plus
    the jitter's 2.5e-7) is known to sqrt(2 / 100) of itself over the 100 or so cells that time
    regularly, so the jitter's square to 7.8e-8 and the jitter to 7.8e-5.

    With a frame lost in 50, two in a row (in a third of the tracks) can hide a whole phase, and
    the count then misses one (a rate off by 3e-3) in some replicates and not in others: the mean
    timing spread of all cells exceeded the data's and no jitter was fitted in half of such
    datasets (sd 4e-4). Without losses the common rate beats with the frames, and the
    jitter-free timing, which the rates' spread was read against, is not the timing at the
    fitted jitter: 3.3e-4 was fitted for 5e-4."""
    from kilobot_twin.gap import workflow as W
    from kilobot_twin.recording import measured

    truth, bound = 5e-4, np.sqrt(2 / 100) * (3e-7 + 2.5e-7) / (2 * 5e-4)
    fitted = []
    for seed in range(12):
        _square_wave_blinks(tmp_path / str(seed), seed, truth, drop)
        cond, meas = W.measured_summaries(measured.load(tmp_path / str(seed)))
        meas = E.Summaries(meas, np.arange(cond.trials))
        fitter = W._Fitter(cond, meas, E.nominal_model("blink", cond.robot_ids), W.GapSettings(seed=seed), True)
        m = fitter.fit((), list(range(cond.trials)))
        assert m.frame_lead == "random"
        fitted.append(m.swarm.clock_trial_sd[0])
    sd = np.std(fitted, ddof=1)
    assert abs(np.mean(fitted) - truth) < 3 * sd / np.sqrt(len(fitted)), (np.mean(fitted), sd)
    assert sd < 2 * bound, fitted


def test_clock_jitter_is_read_from_rates_that_tie_on_a_lattice():
    """Rates written here on a lattice of 1.2e-3 (counted toggles over frames), 30 robots x 8
    trials, each the lattice point nearest jitter (7e-4) plus timing (2.5e-4): most fall on the
    middle point, so their median absolute deviation is 0 (synth blink 3259's was, with an sd of
    7e-4), and a clip scaled by it cut the data at the timing's own spread. The fitted jitter is
    7e-4 within 4 sds of the data's spread (240 rates, their variance known to sqrt(2 / 239) of
    itself); the simulations are drawn the same way with the same random numbers in every call."""
    n, K, step, truth = 30, 8, 1.2e-3, 7e-4

    def lattice(rng, jitter, M=None):
        shape = (K, n) if M is None else (M, K, n)
        x = jitter * rng.standard_normal(shape) + 2.5e-4 * rng.standard_normal(shape)
        return 1.0 + step * np.round(x / step)

    def resim(m):
        return {"toggle_rate": lattice(np.random.default_rng(7), float(m.swarm.clock_trial_sd[0]), M=20)}

    rate = lattice(np.random.default_rng(1), truth)
    dev = rate / rate.mean() - 1
    assert robust_sd(dev) == 0.0  # the case the test is about
    m = E._jitter_at_its_timing(E.nominal_model("blink", np.arange(n)), rate, resim, own=False)
    var = E._spread_all(rate)
    assert m.swarm.clock_trial_sd[0] == pytest.approx(truth, abs=4 * np.sqrt(2 / (rate.size - 1)) * var / (2 * truth))


def test_a_phase_missed_now_and_then_does_not_set_the_clock_jitter():
    """Rates written here: 30 robots x 8 trials, jitter 5e-4 plus timing 5e-4, and in one cell in
    a hundred a count that missed or gained a phase (3e-3), in the data as in the simulations
    (drawn the same way, the same random numbers in every call of one fit). Over 100 datasets the fitted
    jitter is 5e-4 within 3 standard errors and its sd at most 1.5x what 240 Gaussian rates
    allow (variance known to sqrt(2 / 239) of itself: 4.6e-5); the sd of 100 fits is known to 7 %
    of itself. Unclipped, a missed phase adds 36x a typical cell's square: 1.9x."""
    n, K, truth, timing = 30, 8, 5e-4, 5e-4

    def draw(rng, jitter, M=None):
        shape = (K, n) if M is None else (M, K, n)
        x = jitter * rng.standard_normal(shape) + timing * rng.standard_normal(shape)
        return 1.0 + x + 3e-3 * np.sign(rng.standard_normal(shape)) * (rng.random(shape) < 0.01)

    def resim_for(seed):  # a simulator per dataset: Monte Carlo errors differ between fits
        return lambda m: {"toggle_rate": draw(np.random.default_rng(seed), float(m.swarm.clock_trial_sd[0]), M=20)}

    start = E.nominal_model("blink", np.arange(n))
    fits = np.array([E._jitter_at_its_timing(start, draw(np.random.default_rng(100 + s), truth), resim_for(1000 + s), own=False).swarm.clock_trial_sd[0]
                     for s in range(100)])
    bound = np.sqrt(2 / (n * K - 1)) * (truth**2 + timing**2) / (2 * truth)
    assert abs(fits.mean() - truth) < 3 * fits.std(ddof=1) / np.sqrt(len(fits))
    assert fits.std(ddof=1) < 1.5 * bound, (fits.std(ddof=1), bound)


def test_a_slipped_replicate_sets_neither_the_turn_rate_statistic_nor_its_scatter():
    """The heading noise's upper bound reads the simulated turn rates' within-robot variance
    (``_noise_stats``' last column) over 20 replicates. A 2 pi unwrapping slip in one trial of
    one replicate (2 pi / 60 s; simulations at 5 mm of tracking noise and low speed produce them
    now and then) multiplies that replicate's variance (12 robots x 4 trials, sigma_omega 0.01:
    about 10x) and, through a mean over replicates, had set the bound at a third of the heading
    noise the diffusion showed (independent world, tau 5 s, seed 3000). Centre and scatter of the
    replicates must stay within their own sampling noise of the clean ones: the median of 20 moves
    by at most a neighbour's gap when one value goes to the top."""
    cond = _conditions(n=12, trials=4, duration=60.0, dt=0.1)
    truth = E.nominal_model("motion", cond.robot_ids).with_traits(sigma_omega=np.full(12, 0.01))
    s = simulate(cond, truth, 20, seed=77)
    clean = E._noise_stats(s)
    s["turn_rate"][2, 1, 5] += 2 * np.pi / 60.0
    hit = E._noise_stats(s)
    assert hit[2, 3] > 5 * clean[2, 3]  # the slip is there
    assert np.mean(hit[:, 3]) > 1.3 * np.mean(clean[:, 3])  # and a mean follows it
    v = np.sort(clean[:, 3])
    gap = np.max(np.diff(v[8:12]))  # the spacing around the median
    assert abs(E._replicate_centre(hit)[3] - E._replicate_centre(clean)[3]) <= gap
    np.testing.assert_array_equal(E._replicate_centre(hit)[:3], E._replicate_centre(clean)[:3])
    assert robust_sd(hit[:, 3]) < 1.3 * robust_sd(clean[:, 3])
    assert np.std(hit[:, 3], ddof=1) > 2 * np.std(clean[:, 3], ddof=1)


def test_the_simulated_tracker_repeats_errors_that_persist_from_frame_to_frame(monkeypatch):
    """The twin's tracker with correlated errors: the noise itself against its theory (sd, and
    autocorrelation exp(-k dt / tau) at k frames; 400k samples give a standard error near 0.002),
    and simulated tracks carrying it (the span-5 second difference, 3/2 sd^2 for independent
    frames at every span, is larger than the span-1 one by the theory's factor, within 5 %)."""
    from kilobot_twin.gap.observe import correlated_noise

    dt, tau, sd = 0.1, 0.3, 0.003
    e = correlated_noise(np.random.default_rng(2), (200, 2000), sd, tau, dt)
    assert abs(e.std() / sd - 1) < 0.02
    for k in (1, 5):
        r = np.mean(e[:, k:] * e[:, :-k]) / np.mean(e * e)
        assert abs(r - np.exp(-k * dt / tau)) < 0.01, (k, r)
    cond = _conditions(n=12, trials=4)
    cond = Conditions(**{**cond.__dict__, "tracking_noise_m": 0.001, "tracking_correlated_m": sd, "tracking_tau_s": tau})
    from kilobot_twin.gap import summaries

    cap = {}
    real = summaries.motion

    def spy(x, y, *a, **k):
        cap["x"] = x
        return real(x, y, *a, **k)

    monkeypatch.setattr(summaries, "motion", spy)
    quiet = E.nominal_model("motion", cond.robot_ids).with_traits(sigma_omega=np.zeros(12), sigma_v=np.zeros(12))
    simulate(cond, quiet, 4, seed=1)
    x = cap["x"]
    v = [np.var(x[..., 2 * m:] - 2 * x[..., m:-m] + x[..., :-2 * m]) / 4 for m in (1, 5)]
    rho = np.exp(-dt / tau)

    def g(m):
        return 1.5 * 0.001**2 + sd**2 * (1.5 - 2 * rho**m + 0.5 * rho ** (2 * m))

    assert abs((v[1] / v[0]) / (g(5) / g(1)) - 1) < 0.05, (v, g(1), g(5))


def test_the_base_s_speed_level_is_fitted_at_its_own_noise_under_heavy_tracking_noise():
    """Identical robots at 0.8 of the nominal speed under 6.6 mm of tracking noise, fitted from
    the nominal model: the speed summary (mean 2 s chord over 2 s) is not proportional to the
    speed (the noise lengthens every chord by about the same amount), so one ratio to the start
    model's simulation does not land on the level. The fitted factor must be the truth's within
    4 standard errors of the data's mean speed (the robots' trial-to-trial speed jitter and the
    summary's noise, from the data's own spread over its 144 tracks; the fit's simulations add
    less than a tenth of that). The one ratio step to the start model's simulation was 6.3 %
    off (63 standard errors); a ratio step at the fitted noise without the secant, 1.9 %."""
    cond = _conditions(n=24, trials=6, duration=60.0, dt=0.1)
    cond = Conditions(**{**cond.__dict__, "tracking_noise_m": 0.0066})
    nominal = E.nominal_model("motion", cond.robot_ids)
    truth = nominal.with_traits(speed_factor=np.full(24, 0.8))
    meas = E.Summaries({k: v[0] for k, v in simulate(cond, truth, 1, seed=43).items()}, np.arange(6))
    calls = iter(range(1000))

    def resim(m):
        return simulate(cond, m, 20, seed=7000 + next(calls))

    fitted = E.fit_base(nominal, meas, resim(nominal), resim)
    speed = meas["speed"][np.isfinite(meas["speed"])]
    se = speed.std(ddof=1) / np.sqrt(speed.size) / speed.mean()  # relative, of the data's mean
    got = fitted.swarm.speed_factor.mean() / 0.8 - 1
    assert abs(got) <= 4 * se, (got, se)


def test_the_speed_level_s_secant_is_kept_to_the_summary_s_shape():
    """Two simulations a hair apart (the level nearly right after the ratio step) whose Monte
    Carlo errors all but cancel their true difference: the secant through them is a twentieth of
    the summary's slope, and a step along it goes 20x too far (one fold of synth seed 3000 went
    0.9 % off: a null gap of 36). The summary f(s) = a s + c / s has a slope between a quarter of
    f / s and f / s here (c / s^2 is a tenth of a), and the step uses one within that range: with
    an error e (relative) in the second simulation the level lands within 4 e of the truth, plus
    what the ratio step left, s1 - truth, times 1 + 4 f' s / f < 5 (by hand)."""
    a, c = 0.0113, 1.1e-6
    f = lambda s: a * s + c / s  # noqa: E731
    truth, s0 = 0.998, 0.99805
    start = E.nominal_model("motion", np.arange(4)).with_traits(speed_factor=np.full(4, s0))
    target = f(truth)
    s1 = s0 * target / f(s0)  # where the ratio step lands
    # the second simulation's error leaves a twentieth of the ratio's slope between the two
    err = iter([0.0, 0.05 * f(s0) / s0 * (s1 - s0) - (f(s1) - f(s0))])

    def resim(m):
        return {"speed": np.full((3, 2, 4), f(float(m.swarm.speed_factor.mean())) + next(err))}

    got = float(E._match_speed_level(start, target, resim)[0].swarm.speed_factor.mean())
    e = abs(0.05 * f(s0) / s0 * (s1 - s0) - (f(s1) - f(s0))) / f(s1)  # the error, relative
    assert abs(got / truth - 1) <= 4 * e + 5 * abs(s1 / truth - 1), (got, e, s1)


def test_bounded_combination_by_hand():
    """A variance read as d (variance var_d) and as t = it plus a part >= 0 (variance var_t):
    where t >= d the part takes the difference and d stands; below, the precision-weighted mean."""
    assert E.bounded_combination(4.0, 1.0, 5.0, 3.0) == 4.0
    assert E.bounded_combination(4.0, 1.0, 4.0, 3.0) == 4.0
    assert E.bounded_combination(4.0, 1.0, 1.0, 3.0) == pytest.approx((4 / 1 + 1 / 3) / (1 + 1 / 3))  # 3.25
    assert E.bounded_combination(4.0, 3.0, 1.0, 1.0) == pytest.approx(1.75)
    assert E.bounded_combination(4.0, 0.0, 1.0, 1.0) == 4.0  # an exact reading stands
    assert E.bounded_combination(4.0, 1.0, 1.0, 0.0) == 1.0
    assert E.bounded_combination(4.0, np.inf, 1.0, 1.0) == 1.0  # a reading of no weight drops out
    assert E.bounded_combination(4.0, 1.0, 1.0, np.nan) == 4.0
    assert E.bounded_combination(4.0, np.nan, 1.0, np.nan) == 2.5


def test_bounded_combination_against_theory():
    """Normal readings drawn here, s = 1, 200,000 each:
    - no part and a turn-rate reading far sharper than the wander (var_t -> 0): the estimate is
      min(d, s) in the limit, whose mean square error is var_d / 2 (the half of d's that lies
      above s is cut away), against var_d for d alone;
    - no part, equal variances V: the bias is -sqrt(V / (4 pi)) (with u, v the two errors,
      a = (u - v) / sqrt 2 and b = (u + v) / sqrt 2 are independent; the error is u where a <= 0,
      b / sqrt 2 elsewhere, so the mean is E[a; a <= 0] / sqrt 2 = -sqrt(V / (2 pi)) / sqrt 2);
    - a part of 10 sds: d stands, unbiased.
    Tolerances: 4 Monte Carlo sds of each mean."""
    rng = np.random.default_rng(12)
    n, s = 200_000, 1.0
    comb = np.vectorize(E.bounded_combination)
    d = s + rng.standard_normal(n) * 0.3
    t = s + rng.standard_normal(n) * 1e-4
    e2 = (comb(d, 0.09, t, 1e-8) - s) ** 2
    assert abs(e2.mean() - 0.09 / 2) < 4 * e2.std() / np.sqrt(n)
    d, t = s + rng.standard_normal(n) * 0.5, s + rng.standard_normal(n) * 0.5
    err = comb(d, 0.25, t, 0.25) - s
    assert abs(err.mean() + np.sqrt(0.25 / (4 * np.pi))) < 4 * err.std() / np.sqrt(n)
    d, t = s + rng.standard_normal(n) * 0.5, s + 5.0 + rng.standard_normal(n) * 0.5
    err = comb(d, 0.25, t, 0.25) - s
    assert abs(err.mean()) < 4 * err.std() / np.sqrt(n) and np.mean(err == d - s) > 0.999


def _synth_as_evaluated(tmp_path, hidden: str, seed: int):
    """A motion dataset as `eval_gap.py --generator synth --random-nuisance` writes it (its
    ``_write``): (folder, truth)."""

    ev = benchmark.load("eval_gap")
    ds = tmp_path / "motion"
    truth = ev._write({"kind": "motion", "hidden": hidden, "seed": seed, "generator": "synth", "random_nuisance": True},
                      ds, 1.0)
    return ds, truth


def test_a_heading_bias_under_tracking_noise_that_swamps_the_wander_is_named(tmp_path):
    """Synth 3042 as `eval_gap.py --generator synth --random-nuisance` draws it: 12 robots x 4
    trials, 6.8 mm of tracking noise, a heading noise of 0.0030 rad/sqrt(s) (correlated over 0.84
    s), heading biases 10.6x the report's minimum detectable size. The wander read the heading
    noise at 0.0060 and the turn rates' bound (their variance plus two sampling sds taken at the
    bound) let it stand: the twin's trial turn rates then varied 2.4x as much as the data's, the
    between-robot F stayed flagged after the right heading bias (z 3.6), and nothing was named.
    With the readings combined the heading bias is named, and the noise is the truth's within 4
    sds of the turn rates' reading (a within-robot variance over 12 x 3 degrees of freedom:
    relative sd sqrt(2 / 36) = 0.24 in sigma^2, 0.12 in sigma).

    At this tracking noise the fit also carries the Monte Carlo error of its simulations, larger
    than the data's: over the workflow's seeds 3040-3047 the fits scatter by 0.29 of the truth
    (0.0008-0.0040; one seed's fit passing or failing a band of 0.12 is luck, and a simulated
    start heading moved seed 3042's from 0.0031 to 0.0012). So the noise is read as the median of
    the base's fit over those eight seeds, within 4 sds of both errors: the data's 0.12 and the
    median's Monte Carlo sd, 1.25 x the fits' sample sd / sqrt(8)."""
    from kilobot_twin.gap import effects as E
    from kilobot_twin.gap import workflow as W

    ds, truth = _synth_as_evaluated(tmp_path, "heading_bias", 3042)
    assert truth["observation"]["tracking_noise_m"] == pytest.approx(0.006773, abs=1e-6)
    rep = W.run_gap([str(ds)], tmp_path / "out", gs=W.GapSettings(seed=3042), log=lambda *a: None)
    assert rep["named_effects"] == ["heading_bias"] and not rep["unexplained"]
    cond, meas = W.measured_summaries(W._load_data(str(ds)))
    meas = E.Summaries(meas, np.arange(cond.trials))
    rel = []
    for seed in range(3040, 3048):
        start = E.nominal_model("motion", cond.robot_ids, cond.forward_speed_m_s)
        base = W._Fitter(cond, meas, start, W.GapSettings(seed=seed), True).fit((), list(range(cond.trials)))
        rel.append(base.swarm.sigma_omega[0] / 0.00296)
    mc = 1.2533 * np.std(rel, ddof=1) / np.sqrt(len(rel))
    assert abs(np.median(rel) - 1) < 4 * np.hypot(0.12, mc), (rel, mc)


def test_a_speed_spread_whose_trials_vary_less_than_the_model_says_is_named(tmp_path):
    """Synth pair 3049 as `eval_gap.py --generator synth --random-nuisance` draws it: 12 robots x
    4 trials, heading biases and speed factors (the speed spread 27x the report's minimum
    detectable size), no speed noise, 0.9 mm of tracking noise and 2.0 mm correlated over 0.29 s
    (fitted at 0.95, 2.0 and 0.30). The data's trial speeds vary 0.39x as much as the fitted
    model's (0.41x the base's, below the 5 % quantile of its replicates at 0.60x), so with the
    robots' speeds fitted the between-robot F still stood 4.0 sds above its null and the right
    speed spread resolved nothing: heading bias was named alone, `unexplained`. Once a model fits
    robots' own speeds, the signal also needs their between-robot mean square above the null,
    and both effects are named."""
    from kilobot_twin.gap.workflow import GapSettings, run_gap

    ds, truth = _synth_as_evaluated(tmp_path, "heading_bias,speed_heterogeneity", 3049)
    assert truth["observation"]["tracking_correlated_m"] == pytest.approx(0.002031, abs=1e-6)
    assert truth["nuisance"]["sigma_v"] == 0.0
    rep = run_gap([str(ds)], tmp_path / "out", gs=GapSettings(seed=3049), log=lambda *a: None)
    assert sorted(rep["named_effects"]) == ["heading_bias", "speed_heterogeneity"] and not rep["unexplained"]


def test_smoothing_over_robots_averages_the_monte_carlo_error_away():
    """``smooth_over_robots`` fits a constant, the traits and the first trait's square by least
    squares: on a summary that is exactly such a function plus independent noise of variance s^2
    per robot, ordinary least squares theory gives fitted values whose mean squared error is
    p s^2 / N (p = 4 terms, N robots), against s^2 for each robot's own value: their sum of
    squares over the robots, divided by s^2, is chi^2 with p degrees of freedom (mean p, sd
    sqrt(2 p)), so its mean over ``reps`` draws has sd sqrt(2 p / reps)."""
    rng = np.random.default_rng(3)
    N, s, reps = 40, 0.5, 400
    g = rng.uniform(1.5, 3.0, N)
    o = rng.normal(5.0, 6.0, N)
    truth = 2.0 + 3.0 * (g - 2.2) - 0.4 * (g - 2.2) ** 2 + 0.05 * o
    sse = np.array([np.sum((E.smooth_over_robots(truth + rng.normal(0, s, N), g, o) - truth) ** 2) for _ in range(reps)])
    p = 4
    # SSE / s^2 ~ chi^2(p) exactly for a least-squares fit of a model that holds
    assert abs(sse.mean() / s**2 - p) < 4 * np.sqrt(2 * p / reps)
    # a robot's own value errs by s^2 each: N s^2 in all, 10x as much here
    assert sse.mean() < 0.2 * N * s**2
    # robots whose values are missing keep them missing
    y = truth + rng.normal(0, s, N)
    y[[3, 7]] = np.nan
    out = E.smooth_over_robots(y, g, o)
    assert np.isnan(out[[3, 7]]).all() and np.isfinite(np.delete(out, [3, 7])).all()
    # with few robots the square goes (3 robots a term), each trait's own term stays: 4 robots,
    # one trait, the least-squares line (by hand: slope 4 / 5 through (2.5, 2.5))
    few = E.smooth_over_robots(np.array([1.0, 2.0, 4.0, 3.0]), np.array([1.0, 2.0, 3.0, 4.0]))
    np.testing.assert_allclose(few, [1.3, 2.1, 2.9, 3.7])
    # 7 robots, two traits: a summary linear in both comes back exactly (a fit that kept the
    # constant and the first trait alone read every robot at the mean offset)
    lin = 2.0 + 3.0 * (g[:7] - 2.2) + 1.0 * o[:7]
    np.testing.assert_allclose(E.smooth_over_robots(lin, g[:7], o[:7]), lin, rtol=1e-9)


def _chord_world(c, n=16, trials=6, reps=10, noise=0.0, seed=0):
    """A stand-in simulator whose per-robot speed summary is sqrt(f^2 + c^2) for speed factor f:
    a chord lengthened by independent tracking noise of a fixed size, whose elasticity
    d log y / d log f = f^2 / (f^2 + c^2) is below 1, and whose inverse is f = sqrt(y^2 - c^2)."""
    rng = np.random.default_rng(seed)

    def resim(m):
        f = m.swarm.speed_factor
        return {"speed": np.sqrt(f**2 + c**2)[None, None, :] + noise * rng.standard_normal((reps, trials, n))}

    return resim


def test_the_robots_own_fixed_point_steps_by_the_summary_s_elasticity():
    """A summary y = sqrt(f^2 + c^2) with c^2 = 2/3 has elasticity 0.6 at f = 1: a ratio step
    leaves 1 - 0.6 = 0.4 of each robot's error, two of them 0.16 (what the third world's
    heavy-noise datasets showed). Newton's step on the log scale with the elasticity read off
    the smooth fit over robots converges quadratically: after two steps each robot's factor is
    the hand inverse sqrt(y^2 - c^2) up to the fit's own misfit. Robots alike (no spread to read an
    elasticity from) take the ratio step."""
    n, c = 16, np.sqrt(2 / 3)
    truth = 1.0 + 0.12 * np.random.default_rng(5).standard_normal(n)
    target = np.sqrt(truth**2 + c**2)
    # the start a single ratio to the population would give: proportional to the summary
    model = E.nominal_model("motion", np.arange(n))
    start = target / np.sqrt(1 + c**2)
    m0 = model.with_traits(speed_factor=start)
    resim = _chord_world(c, n)
    model2, e = E._own_fixed_point(m0, "speed_factor", "speed", target, resim, 2, elastic=True)
    fitted = model2.swarm.speed_factor
    # the fixed point is where the fit over robots (a quadratic in f) meets the target, so it
    # misses the inverse by the quadratic's own misfit to sqrt(f^2 + c^2) over the slope
    misfit = np.polyval(np.polyfit(truth, target, 2), truth) - target
    bound = 2 * np.max(np.abs(misfit)) / np.min(truth / target)
    assert bound < 0.01 * truth.std()  # (the misfit is small: 0.3 % of the spread)
    assert np.max(np.abs(fitted - truth)) < bound, (np.max(np.abs(fitted - truth)), bound)
    # the elasticity the last step took, against the hand derivative f^2 / (f^2 + c^2) at the
    # traits it was read at (0.47-0.68 over these robots), to the quadratic fit's accuracy
    before = E._own_fixed_point(m0, "speed_factor", "speed", target, resim, 1, elastic=True)[0].swarm.speed_factor
    np.testing.assert_allclose(e, before**2 / (before**2 + c**2), atol=0.01)
    # the ratio steps leave 0.16 of the error (0.4 per step, as the elasticity 0.6 says)
    ratio, ones = E._own_fixed_point(m0, "speed_factor", "speed", target, resim, 2)
    ratio = ratio.swarm.speed_factor
    assert np.all(ones == 1.0)
    left = np.polyfit(start - truth, ratio - truth, 1)[0]
    assert abs(left - 0.4**2) < 0.02, left
    # with Monte Carlo error in the simulated summaries (sd 0.02 per robot-trial, 60 a robot),
    # the fit over robots still reads the elasticity: factors within 4 sd of the error a
    # robot's own mean would carry (0.02 / sqrt(60) / 0.6 in f, before the smoothing)
    noisy = E._own_fixed_point(m0, "speed_factor", "speed", target, _chord_world(c, n, noise=0.02, seed=1), 2, elastic=True)[0]
    assert np.max(np.abs(noisy.swarm.speed_factor - truth)) < 4 * 0.02 / np.sqrt(60) / 0.6
    # robots alike: the elasticity is not measured, so the step is the ratio (no 4x amplification
    # of the population's mismatch by a clipped elasticity of 0.25)
    alike = model.with_traits(speed_factor=np.full(n, 1.0))
    goal = np.full(n, 1.05 * np.sqrt(1 + c**2))
    one = E._own_fixed_point(alike, "speed_factor", "speed", goal, resim, 1, elastic=True)[0].swarm.speed_factor
    np.testing.assert_allclose(one, 1.05, rtol=1e-12)


def test_spread_keeping_speed_factors_go_through_the_elasticity():
    """The spread-keeping estimate of a robot's speed factor is the factor whose summary is the
    robot's own, unpooled one. In the chord world (summary sqrt(f^2 + c^2), elasticity 0.6 near
    f = 1) that is the hand inverse sqrt(y^2 - c^2) of the spread-keeping summary y: 16 robots x 3
    trials with trial noise that pools them by about a fifth. Scaling the pooled factor by the
    summaries' plain ratio (as if the elasticity were 1) misses the inverse by (1/0.6 - 1) of that
    ratio's distance from 1, up to 0.7 % here."""
    n, K, c = 16, 3, np.sqrt(2 / 3)
    rng = np.random.default_rng(9)
    f = 1.0 + 0.12 * rng.standard_normal(n)
    speed = np.sqrt(f**2 + c**2)[None, :] + 0.05 * rng.standard_normal((K, n))
    meas = E.Summaries({"speed": speed}, np.arange(K))
    resim = _chord_world(c, n, trials=K)
    nominal = E.nominal_model("motion", np.arange(n))
    fitted = E.LIBRARY["speed_heterogeneity"].fit(nominal, meas, resim(nominal), resim)
    # each robot's spread-keeping factor over its pooled one, against the hand inverse's ratio at
    # the spread-keeping and the pooled summaries (the pooled factor's own small miss, the fit's
    # misfit of 0.1 %, cancels)
    y, yp = E.partial_pool(speed, keep_spread=True)[0], E.partial_pool(speed)[0]
    hand = np.sqrt(y**2 - c**2) / np.sqrt(yp**2 - c**2)
    plain = y / yp
    assert np.max(np.abs(plain / hand - 1)) > 5e-3  # as if the elasticity were 1: off by this much here
    np.testing.assert_allclose(fitted.individual["speed_factor"] / fitted.swarm.speed_factor, hand, rtol=1e-3)


def _sweep_stats(gain_var, offset_var, n=6):
    """Summaries (1, 2, n) whose within-robot variances are exactly these (each robot's two
    trials +-sqrt(v / 2) about its level: a deviation square sum of v on one degree of freedom)."""
    def two(v):
        d = np.sqrt(v / 2.0)
        return np.stack([np.full(n, 100.0 - d), np.full(n, 100.0 + d)])[None]
    return {"gain": two(gain_var), "offset": two(offset_var)}


@pytest.mark.parametrize("data_gain_var, base_kind", [(0.085, "without noise"), (0.072, "with noise")])
def test_a_refit_keeps_the_kind_of_sensor_it_is_given(data_gain_var, base_kind):
    """``fit_sensor_noise(..., like=base)`` refits the levels of the base's kind of sensor, never
    the other kind. A linear world of statistics written here: a sensor without noise leaves its
    gains a within-robot variance of 0.070, the floor's dither (1/12 counts^2) 0.080, and reading
    noise adds 0.1 per counts^2 beyond it; the offsets vary by 0.003 (1 + sigma^2) plus the
    offset's trial spread s^2. Data at 0.085 sit above the dither: on its own the fit takes the
    dither and 0.05 counts^2 more (sigma^2 = 1/12 + 0.05), where the data ask for it (by hand from
    the map), and given a base without noise, no noise and the offsets' spread. Data at 0.072 sit
    below the dither and near no noise: on its own the fit takes no noise, and given a base with
    noise, the dither's floor. The offsets' variance of 26 is s^2 = 26 - 0.003 (no noise) or
    26 - 0.003 (1 + sigma^2) (with it), to the solver's precision. (Independent world 3247: the
    base came out without noise and the sensor gain's refit with the dither, and a gain at its
    stated size scored -36 on held-out sweeps where the base's kind gives +33.)"""
    n = 6
    floor = E.ADC_ROUNDING_VAR

    def world(m):
        sigma2, s2 = float(m.swarm.sensor_noise[0]) ** 2, float(m.swarm.sensor_offset_trial_sd[0]) ** 2
        g = 0.070 if sigma2 == 0 else 0.080 + 0.1 * (sigma2 - floor)
        return _sweep_stats(g, 0.003 * (1 + sigma2) + s2, n)

    start = E.nominal_model("light_sweep", np.arange(n))
    meas = {k: v[0] for k, v in _sweep_stats(data_gain_var, 26.0, n).items()}
    alone = E.fit_sensor_noise(start, meas, world)
    quiet = start.with_traits(sensor_noise=np.zeros(n), sensor_offset_trial_sd=np.full(n, 5.0))
    noisy = start.with_traits(sensor_noise=np.full(n, 0.4), sensor_offset_trial_sd=np.full(n, 5.0))
    kept = E.fit_sensor_noise(start, meas, world, like=quiet if base_kind == "without noise" else noisy)
    sigma2 = lambda m: float(m.swarm.sensor_noise[0]) ** 2  # noqa: E731
    s2 = lambda m: float(m.swarm.sensor_offset_trial_sd[0]) ** 2  # noqa: E731
    if base_kind == "without noise":
        assert sigma2(alone) == pytest.approx(floor + 0.05, rel=1e-6)  # 0.085 = 0.080 + 0.1 x 0.05
        assert sigma2(kept) == 0.0
        assert s2(kept) == pytest.approx(26.0 - 0.003, rel=1e-6)
    else:
        assert sigma2(alone) == 0.0
        assert sigma2(kept) == pytest.approx(floor, rel=1e-9)
        assert s2(kept) == pytest.approx(26.0 - 0.003 * (1 + floor), rel=1e-6)
