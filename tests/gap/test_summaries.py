"""Summaries against theory and the closed-form blink path against stepping."""

import warnings

import numpy as np
import pytest

from kilobot_twin.core import sim
from kilobot_twin.core.traits import SwarmTraits, draw_population
from kilobot_twin.gap import summaries, synth
from kilobot_twin.gap.model import blink_leds, measured_summaries
from kilobot_twin.recording import measured

from . import unicycle


def test_turn_rate_and_speed_of_noisy_gappy_tracks_match_kinematics():
    b = np.linspace(-0.04, 0.04, 9)
    sc = synth.motion_scenario(60.0, 0.1)
    res = sim.simulate(sc, SwarmTraits.uniform(9).with_values(heading_bias=b), 0, record_every=1)
    rng = np.random.default_rng(0)
    x = res.traj["x"] + 0.002 * rng.standard_normal(res.traj["x"].shape)
    y = res.traj["y"] + 0.002 * rng.standard_normal(res.traj["y"].shape)
    drop = rng.random(x.shape) < 0.05
    drop[..., 100:130] = True  # a 3 s tracking loss
    s = summaries.motion(np.where(drop, np.nan, x), np.where(drop, np.nan, y), 0.1)
    v = synth.FORWARD_SPEED_M_S
    np.testing.assert_allclose(s["turn_rate"][0], -b * v / 0.025, atol=3e-4)  # omega = -b v / L
    np.testing.assert_allclose(-s["turn_rate"][0] * 0.025 / v, b, atol=0.001)  # b = -omega L / v, by hand
    assert np.all(np.abs(s["speed"][0] / v - 1) < 0.05)


def test_a_glitch_that_reverses_a_chord_does_not_slip_the_heading():
    """A straight track at the Kilobot's speed, 2 mm tracking noise, and a glitch: one frame 3 cm
    off, against the direction of travel (chords are 2.3 cm over the 2 s lag). Unwrapped naively,
    the chords that end and start at the glitch reverse and the heading slips by 2 pi, which shows
    as a turn rate and a diffusion orders above the track's own. The true turn rate is 0."""
    rng = np.random.default_rng(3)
    T, dt, v = 601, 0.1, synth.FORWARD_SPEED_M_S
    t = np.arange(T) * dt
    x = v * t + 0.002 * rng.standard_normal(T)
    y = 0.002 * rng.standard_normal(T)
    clean = summaries.motion(x[None], y[None], dt)
    x[300] -= 0.03
    s = summaries.motion(x[None], y[None], dt)
    # without the glitch: turn rate 0 to within the noise (2 mm over 60 s: ~1e-4 rad/s)
    assert abs(clean["turn_rate"][0]) < 3e-4
    assert abs(s["turn_rate"][0]) < 3e-4 and abs(s["diffusion"][0] - clean["diffusion"][0]) < 1e-4, (s, clean)
    assert abs(s["speed"][0] / v - 1) < 0.02


def test_a_heading_that_slips_by_whole_turns_leaves_no_turn_rate():
    """A straight track (true turn rate 0) whose tracked point circles 4 cm around the robot once
    over 3 s, then stays on it: chords are 2.3 cm, so each chord's heading winds round once as its
    end, then its start, passes the loop, each step within a quarter turn of the last (no chord is
    refused), and the unwrapped heading ends 4 pi off. Its least-squares turn rate would be a
    fiction of the tracker; the track has none. Ordinary tracks (the tests' own unicycle, 2 mm of
    tracking noise, headings diffusing at 4x the nominal intensity) all keep theirs."""
    rng = np.random.default_rng(5)
    T, dt, v = 601, 0.1, synth.FORWARD_SPEED_M_S
    t = np.arange(T) * dt
    x = v * t + 0.002 * rng.standard_normal(T)
    y = 0.002 * rng.standard_normal(T)
    assert np.isfinite(summaries.motion(x[None], y[None], dt)["turn_rate"][0])
    phi = np.clip((t - 30.0) / 3.0, 0, 1) * 2 * np.pi
    xs, ys = x + 0.04 * (np.cos(phi) - 1), y + 0.04 * np.sin(phi)
    s = summaries.motion(xs[None], ys[None], dt)
    assert np.isnan(s["turn_rate"][0]) and abs(s["speed"][0] / v - 1) < 0.2
    th = unicycle.brownian_headings(rng, 400, T, dt, 16e-4)
    xo, yo = unicycle.tracks(rng, th, v, dt, 0.002)
    assert np.isfinite(summaries.motion(xo, yo, dt)["turn_rate"]).all()


def test_diffusion_of_a_diffusing_heading_matches_theory():
    """A unicycle of its own (not the twin's): speed 1 cm/s, heading a Brownian motion of intensity
    sigma^2 = 4e-4 rad^2/s, 10 minute tracks at 10 Hz, 2 mm tracking noise. The sideways second
    difference over s seconds has variance 2/3 v^2 sigma^2 s^3 + 6 e^2 (by hand: it is v times the
    integral of dW under a triangle of base 2 s), so ``diffusion`` must give sigma^2, less what
    centring each track takes out: the variance of the track's mean, v^2 sigma^2 s^4 / T (the
    triangle's area squared), 1.5 s / T of the wander at the longer lag (2.5 % here). The mean
    over 200 tracks within 4 of its standard errors (from the tracks' own scatter). With the
    speed noise of a Kilobot added along the path, the same."""
    rng = np.random.default_rng(11)
    R, T, dt, v, sig2, e = 200, 6001, 0.1, 0.01, 4e-4, 0.002
    expected = sig2 * (1 - 1.5 * 10.0 / ((T - 1) * dt))
    th = unicycle.brownian_headings(rng, R, T, dt, sig2)
    for speed_noise in (0.0, 0.0005):
        x, y = unicycle.tracks(rng, th, v, dt, e, speed_noise)
        d = summaries.motion(x, y, dt, wander_lags_s=(1.0, 10.0))["diffusion"]
        se = d.std(ddof=1) / np.sqrt(R)
        assert abs(d.mean() - expected) < 4 * se, (speed_noise, d.mean() / sig2, se / sig2)
        assert se < 0.015 * sig2  # the check has teeth: a factor 1.1 off fails it


def _slope_variance(T: int, dt: float, L: int, sig2: float, tau: float) -> float:
    """The exact variance of a track's turn rate, by hand: the least-squares slope over time of its
    chord headings, each chord's heading the mean of the unicycle's headings over its L steps
    (``unicycle.tracks`` moves step k along heading k), under a Brownian heading of intensity sig2
    (tau 0) or one whose turn rate is the unicycle's Ornstein-Uhlenbeck noise of correlation time
    tau and long-run intensity sig2 (stationary sd sqrt(sig2 / (2 tau)))."""
    k = np.arange(T)
    if tau == 0:
        cov = sig2 * dt * (np.minimum.outer(k, k) + 1.0)
    else:
        rate = sig2 / (2 * tau) * np.exp(-dt / tau) ** np.abs(np.subtract.outer(k, k))
        integrate = np.tril(np.ones((T, T))) * dt
        cov = integrate @ rate @ integrate.T
    m = T - L
    chords = np.zeros((m, T))
    for j in range(m):
        chords[j, j + 1:j + L + 1] = 1.0 / L
    t = np.arange(m) * dt
    w = (t - t.mean()) / ((t - t.mean()) ** 2).sum() @ chords
    return float(w @ cov @ w)


def test_turn_rate_of_a_diffusing_heading_scatters_as_its_least_squares_slope():
    """The tests' unicycle at 1 cm/s and 10 Hz, heading noise of intensity 4e-4 rad^2/s, no tracking
    noise: the trial turn rates' variance over 6000 tracks is the exact slope variance
    (:func:`_slope_variance`) within 4 sds of a sample variance (sqrt(2 / 5999): 7.3 %), for a
    white heading over 60 s and for turn noise correlated over 2 s on 10 s tracks. There the colour
    takes 24 % off the white value (more than 4 sds from white). The per-robot noise reading and
    the between-robot F tests rest on this variance. Broken by hand: turn rates 6 % too large fail
    it (white: 1.09x the theory); chords of 1 s or 4 s instead of 2 s barely move a 60 s slope
    (0.96x, 1.01x) and pass."""
    rng = np.random.default_rng(31)
    R, dt, v, sig2, L = 6000, 0.1, 0.01, 4e-4, 20  # L: the summary's 2 s chords
    tol = 4 * np.sqrt(2 / (R - 1))
    for T, tau in ((601, 0.0), (101, 2.0)):
        if tau == 0:
            th = unicycle.brownian_headings(rng, R, T, dt, sig2)
        else:
            th = np.cumsum(unicycle.ou_noise(rng, R, T, dt, np.sqrt(sig2 / (2 * tau)), tau) * dt, axis=-1)
        x, y = unicycle.tracks(rng, th, v, dt, 0.0)
        got = np.var(summaries.motion(x, y, dt)["turn_rate"], ddof=1)
        assert abs(got / _slope_variance(T, dt, L, sig2, tau) - 1) < tol, (T, tau, got / _slope_variance(T, dt, L, sig2, tau))
        if tau > 0:
            assert abs(got / _slope_variance(T, dt, L, sig2, 0.0) - 1) > tol


def _pixel_tracks(seed, v, sig, p=0.00375, o=0.0007, R=40, T=601, dt=0.1):
    """The tests' own unicycle (heading diffusion 4e-4 rad^2/s) at speed v, tracker noise sig,
    reported in whole pixels of p (grid origin o), rounded here by hand: (x, y, true x, true y)."""
    rng = np.random.default_rng(seed)
    th = rng.uniform(-np.pi, np.pi, (R, 1)) + unicycle.brownian_headings(rng, R, T, dt, 4e-4)
    x, y = unicycle.tracks(rng, th, v, dt, sig)
    x, y = x + rng.uniform(-0.3, 0.3, (R, 1)), y + rng.uniform(-0.3, 0.3, (R, 1))
    return o + np.round((x - o) / p) * p, o + np.round((y - o) / p) * p


def test_positions_in_whole_pixels_are_found_on_their_grid():
    """Tracks reported in whole pixels of 1.2536 mm from an origin 0.7 mm off, written to 5
    decimals (as a file holds them: each value rounded by up to 5 um, so that their spacings read
    1.25 or 1.26 mm, and the median one, 3.6 um short, puts the far end of the 1,300 steps 3.7
    steps off its index): the grid's step and origin come back to well within the rounding (1e-8
    m: a mean over hundreds of steps). Continuous positions (a tracker that interpolates, written
    to 1 um) and a grid finer than 10 um have none; positions written to 0.1 mm lie on a 0.1 mm
    grid, which is so; a grid whose error is small beside the tracker's noise is left to it."""
    x, y = _pixel_tracks(1, 0.01, 0.001, p=0.0012536, R=80)
    grid = summaries.position_lattice(np.round(x, 5), np.round(y, 5))
    assert grid is not None
    for step, origin in grid:
        assert abs(step - 0.0012536) < 1e-8 and abs(origin - 0.0007) < 1e-6
    rng = np.random.default_rng(2)
    c = 0.3 * rng.standard_normal((2, 5, 601))
    assert summaries.position_lattice(np.round(c[0], 6), np.round(c[1], 6)) is None
    assert summaries.position_lattice(np.round(c[0] / 5e-6) * 5e-6, np.round(c[1] / 5e-6) * 5e-6) is None
    g = summaries.position_lattice(np.round(c[0], 4), np.round(c[1], 4))
    assert g is not None and all(abs(step - 1e-4) < 1e-12 for step, _ in g)
    # a grid that matters beside the tracker's noise only: 10 um (a file's 5 decimals, densely
    # visited) under 1 mm adds 1e-5 of its variance (left to the noise), 1.25 mm pixels 0.13 (kept)
    c5 = np.round(0.02 * rng.standard_normal((2, 20, 601)), 5)
    assert summaries.position_lattice(*c5) is not None and summaries.position_lattice(*c5, noise_m=0.001) is None
    assert summaries.position_lattice(np.round(x, 5), np.round(y, 5), noise_m=0.001) is not None


def test_the_tracker_s_noise_behind_a_pixel_grid():
    """Tracks in whole pixels of 3.75 mm (step / sqrt(12) = 1.08 mm) at 0.3 and 1.2 mm per frame,
    with 0, 0.6 and 1.5 mm of tracker noise before the rounding: the median-based estimate reads 0
    or a grid value whatever the noise; the twin's noise behind the grid comes back so that what it
    adds in all, sqrt(sigma^2 + step^2 / 12), is within 3 % of the truth (the estimator's bias in
    this range at most 1.6 %, its scatter over 10 seeds 0.6 %), and without noise no more than
    0.25 mm. The twin observed through the grid then has what the data have: positions on it."""
    p = 0.00375
    for v in (0.003, 0.012):
        for sig in (0.0, 0.0006, 0.0015):
            x, y = _pixel_tracks(3, v, sig)
            grid = summaries.position_lattice(x, y)
            est = summaries.lattice_noise(x, y, grid, 0.1)
            total = np.hypot(est, p / np.sqrt(12)) / np.hypot(sig, p / np.sqrt(12))
            assert abs(total - 1) < 0.03 and (sig > 0 or est < 0.00025), (v, sig, est)
    assert summaries.tracking_noise(*_pixel_tracks(3, 0.003, 0.0006)) == 0.0  # the median's reading
    q = summaries.quantize(np.array([0.0007 + 0.00375 * 0.49, 0.0007 - 0.00375 * 0.51, np.nan]), 0.00375, 0.0007)
    np.testing.assert_allclose(q[:2], [0.0007, 0.0007 - 0.00375], atol=1e-15)
    assert np.isnan(q[2])


def test_tracking_noise_that_persists_from_frame_to_frame_is_measured_and_independent_frames_stay_so():
    """The tests' own unicycle (heading diffusion 4e-4 rad^2/s at 1 cm/s, speed noise, 2 mm of
    independent tracking noise; 100 tracks of 60 s at 10 Hz): its frames are independent, and the
    estimate must say so and give :func:`tracking_noise`'s sd unchanged (the heading and speed
    noise bend the spans too, and must not be read as a tracker's). With 3 mm of noise correlated
    over 0.2 s added (Ornstein-Uhlenbeck stepped exactly, test-side), the three parts come back
    within about 4x their scatter over 20 seeds of this generator (2.2 %, 1.3 % and 4.4 %; tau's
    mean 3 % low): 10 %, 6 % and 20 %."""
    R, T, dt = 100, 601, 0.1

    def tracks(seed, tau):
        """The unicycle's tracks, and the same with 3 mm of error correlated over tau added."""
        rng = np.random.default_rng(seed)
        th = unicycle.brownian_headings(rng, R, T, dt, 4e-4)
        x, y = unicycle.tracks(rng, th, 0.01, dt, 0.002, 0.0005)
        return x, y, x + unicycle.ou_noise(rng, R, T, dt, 0.003, tau), y + unicycle.ou_noise(rng, R, T, dt, 0.003, tau)

    x, y, xc, yc = tracks(5, 0.2)
    got = summaries.tracking_noise_correlation(x, y, dt)
    assert got == {"white_m": summaries.tracking_noise(x, y), "correlated_m": 0.0, "tau_s": 0.0}
    # what the frame-to-frame statistic alone makes of the correlated error: far less than there is
    assert summaries.tracking_noise(xc, yc) < 0.75 * np.hypot(0.002, 0.003)
    # Correlated over 0.7 s too (the independent world draws up to 0.8 s): over 20 seeds the parts
    # come back at 0.999 +- 0.006, 0.992 +- 0.010 and 0.995 +- 0.034 of the truth; tolerances about
    # 4x those. With spans to 1 s and tau capped at 0.5 s, the correlated part came back at 0.72 +-
    # 0.05; fitted on both coordinates pooled rather than along and across the chord, 0.983 +- 0.022.
    for seed, tau, tol in ((5, 0.2, (0.10, 0.06, 0.20)), (105, 0.7, (0.03, 0.05, 0.15))):
        _, _, xc, yc = tracks(seed, tau)
        got = summaries.tracking_noise_correlation(xc, yc, dt)
        for (key, truth), t in zip((("white_m", 0.002), ("correlated_m", 0.003), ("tau_s", tau)), tol):
            assert abs(got[key] / truth - 1) < t, (tau, key, got)


def test_a_robots_speed_noise_is_not_read_as_a_trackers_persisting_error():
    """The tests' unicycle with four times the speed noise (2 mm/sqrt(s) along the path) and a
    tracker of 1 mm independent plus 1 mm correlated over 0.6 s: the speed noise's variance grows
    with the span as the correlated error's does on its way to its plateau, and fitted on both
    coordinates pooled it was taken for a larger correlated error (over 20 seeds 1.23 +- 0.13 of
    the truth, every seed above 1.05). Along and across the chord the speed noise is in one
    component and the tracker in both: over 20 seeds 1.027 +- 0.022 and tau 1.006 +- 0.061. Each of
    five seeds within 4 sd plus the mean's offset (0.12 and 0.25)."""
    R, T, dt, tau = 100, 601, 0.1, 0.6
    for seed in range(205, 210):
        rng = np.random.default_rng(seed)
        th = unicycle.brownian_headings(rng, R, T, dt, 4e-4)
        x, y = unicycle.tracks(rng, th, 0.01, dt, 0.001, 0.002)
        x, y = x + unicycle.ou_noise(rng, R, T, dt, 0.001, tau), y + unicycle.ou_noise(rng, R, T, dt, 0.001, tau)
        got = summaries.tracking_noise_correlation(x, y, dt)
        assert abs(got["correlated_m"] / 0.001 - 1) < 0.12, (seed, got)
        assert abs(got["tau_s"] / tau - 1) < 0.25, (seed, got)
        assert abs(got["white_m"] / 0.001 - 1) < 0.03, (seed, got)


def test_light_sweep_gain_is_linear_slope():
    stim = np.linspace(0, 1, 200)[None, None, :]
    reading = np.minimum(5 + 2000 * stim, 1023)
    s = summaries.light_sweep(stim, reading)
    assert abs(s["gain"][0, 0] - 2000) < 1e-6 and abs(s["offset"][0, 0] - 5) < 1e-6


def test_light_sweep_lines_are_numpys_least_squares_lines():
    """Sweeps below the knee throughout, with missing frames and reading noise, some over a
    narrow band of stimuli far from 0 (where a line from uncentred sums loses digits): gain,
    offset and residual sd (n - 2 dof) against ``numpy.polyfit`` on each track's finite samples."""
    rng = np.random.default_rng(4)
    K, N, T = 3, 5, 300
    lo = np.where(rng.uniform(size=(K, N, 1)) < 0.5, 0.05, 0.55)
    stim = lo + (0.1 + 0.3 * (lo < 0.5)) * np.sort(rng.uniform(size=(K, N, T)), axis=-1)
    reading = 20.0 + 800.0 * stim + 3.0 * rng.standard_normal((K, N, T))  # under 600 counts
    reading[rng.uniform(size=reading.shape) < 0.2] = np.nan
    s = summaries.light_sweep(stim, reading)
    for k in range(K):
        for i in range(N):
            ok = np.isfinite(reading[k, i])
            (b, a), res, *_ = np.polyfit(stim[k, i, ok], reading[k, i, ok], 1, full=True)
            assert abs(s["gain"][k, i] - b) < 1e-9 * abs(b) and abs(s["offset"][k, i] - a) < 1e-9 * abs(b)
            assert abs(s["residual_sd"][k, i] - np.sqrt(res[0] / (ok.sum() - 2))) < 1e-9


def test_light_sweep_gain_is_not_flattened_by_reading_noise():
    """Samples are chosen by their stimulus, so a least-squares line through them is unbiased
    whatever the reading noise (theory: the regressor, not the response, is selected). A cut
    on the noisy reading itself keeps the low draws near the knee: at 60 counts of noise over
    a sweep of 2000 counts per unit that read 1544 (23 % flat). 400 sweeps: the mean gain
    within 4 of its standard errors (from the sweeps' own scatter) of the truth; the offset
    within 4 standard errors of 300 less the half count floor() takes off."""
    rng = np.random.default_rng(11)
    R, V = 400, np.linspace(0, 1, 601)
    reading = np.floor(300.0 + 2000.0 * V + 60.0 * rng.standard_normal((R, V.size)))
    s = summaries.light_sweep(np.broadcast_to(V, reading.shape), reading)
    g, o = s["gain"], s["offset"]
    assert np.isfinite(g).all()
    assert abs(g.mean() - 2000.0) < 4 * g.std(ddof=1) / np.sqrt(R), g.mean()
    assert abs(o.mean() - 299.5) < 4 * o.std(ddof=1) / np.sqrt(R), o.mean()


@pytest.mark.parametrize("p", [4.0, 9.0, 20.0, 0.0])
def test_sensor_knee_reads_the_bend_of_sensors_drawn_here(p):
    """Sweeps drawn in numpy (not the twin's sensor): 30 robots x 4 trials, gains 1.4-3.3 x 1024
    counts per unit, offsets 0-15 counts shifted by N(0, 6) per trial, 8 counts of reading
    noise, the soft clip y / (1 + (y / 1023)^p)^(1/p) (p = 0: a hard clip), rounded. Least
    squares over the grid must land on a grid point within one step (12 %) of the truth; a hard
    clip on the hard clip."""
    rng = np.random.default_rng(int(p) + 5)
    K, N, V = 4, 30, np.linspace(0, 1, 601)
    g = 1024.0 * 2.2 * rng.uniform(0.6, 1.5, N)
    o = rng.uniform(0, 15, N)[None, :] + 6.0 * rng.standard_normal((K, N))
    raw = o[..., None] + g[None, :, None] * V + 8.0 * rng.standard_normal((K, N, V.size))
    y = np.maximum(raw, 0.0)
    bent = y / (1 + (y / 1023.0) ** p) ** (1 / p) if p > 0 else y
    reading = np.round(np.minimum(bent, 1023.0))
    stim = np.broadcast_to(V, reading.shape)
    s = summaries.light_sweep(stim, reading)
    got = summaries.sensor_knee(stim, reading, s["gain"], s["offset"])
    if p == 0:
        assert got == 0.0
    else:
        assert got > 0 and abs(np.log(got / p)) <= np.log(2.0) / 6 + 1e-9, got


def test_sensor_knee_needs_readings_above_the_cut():
    V = np.linspace(0, 0.2, 100)[None, None, :]
    reading = np.floor(5 + 2000 * V)  # never above 405 counts
    s = summaries.light_sweep(V, reading)
    assert summaries.sensor_knee(V, reading, s["gain"], s["offset"]) is None


def test_blink_toggle_rate_and_closed_form_leds():
    sc = synth.blink_scenario(30.0, 1 / 30)
    sw = draw_population({"n": 5, "clock_rate": {"dist": "normal", "mean": 1, "sd": 0.02}, "clock_trial_sd": 0.002}, seed=1)
    res = sim.simulate(sc, sw, 3, runs=[0, 5], trials=[0, 2], record_every=1)
    T = res.traj["led"].shape[-1]
    leds = blink_leds(sc, sw, 3, [0, 5], [0, 2], T)
    assert np.array_equal(res.traj["led"], leds)
    rate = summaries.blink(leds.astype(float), 1 / 30)["toggle_rate"]
    st = sim.init_state(sc, sw, 3, runs=[0, 5], trials=[0, 2])
    expected = 31.0 * st.clock / 30  # toggles per second
    assert np.all(np.abs(rate / expected - 1) < 0.01)



def test_a_random_lead_puts_a_robot_anywhere_in_its_led_cycle():
    """With ``frame_lead`` random, the twin's replicates of a trial count toggle rates as robots at
    uniform points of their LED cycle do, written here without the twin: a square wave of 57
    ticks a half at 26.5 Hz (10.75 frames at 5 Hz), read every 0.2 s for 117.6 s. There the
    periods a robot shows span nearly a whole number of frames, and robots placed within one
    frame of each other all count the same rate (independent world blink 3254, where seven
    robots lay 7-10 predictive sds off). The twin's rates must take the same values as the
    uniform phases' with the same frequencies: a chi-square test of the two samples' counts at
    the 0.1 % level, and more than one value."""
    from scipy.stats import chi2_contingency

    from kilobot_twin.gap import effects as E
    from kilobot_twin.gap.model import Conditions, simulate

    n, dt, half, hz, span = 50, 0.2, 57, 26.5, 117.6
    T = int(round(span / dt)) + 1
    cond = Conditions("blink", np.arange(n), 1, span, dt, np.ones((1, n, T), bool), half_period_ticks=half, tick_hz=hz)
    m = E.nominal_model("blink", cond.robot_ids).with_traits(clock_rate=np.ones(n), clock_trial_sd=np.zeros(n),
                                                             frame_lead="random")
    twin = simulate(cond, m, 40, seed=3)["toggle_rate"].ravel()
    u = np.random.default_rng(7).uniform(0.0, 1.0, (2000, 1))  # where in its cycle a robot is at frame 0
    led = np.floor((u * 2 * half + np.arange(T) * dt * hz) / half) % 2
    phases = summaries.blink(led, dt)["toggle_rate"].ravel()
    values = np.unique(np.round(np.concatenate([twin, phases]), 9))
    counts = [[int(np.sum(np.round(x, 9) == v)) for v in values] for x in (twin, phases)]
    assert len(values) > 1 and np.all(np.sum(counts, axis=1) == [twin.size, phases.size]), counts
    assert chi2_contingency(counts)[1] > 1e-3, counts


def test_a_toggle_rate_s_rounding_floor_is_what_frames_do_to_it():
    """``toggle_rate_floor`` against rates counted here: 4,000 clean square waves, 100 s at 10
    Hz, each at a uniform point of its cycle and a half period drawn from 1.5-2.5 s (so no one
    aliasing of periods and frames dominates). Over them the mean squared error of the counted
    rate about the true one is what two uniform roundings of a frame make, var = (rate dt /
    span)^2 / 6 with span from the first to the last toggle; the floor takes the track's whole
    span (a half period or two longer), so it lies below that by up to 2 x 2.5 / 100 and not
    above it. Mean squared error over the mean floor: within 1.0 .. 1.05 + 4 Monte Carlo sds
    (the squared errors' sd / sqrt(4000) over their mean, about 2 %)."""
    rng = np.random.default_rng(11)
    n, dt, T = 4000, 0.1, 1001
    half = rng.uniform(1.5, 2.5, (n, 1))  # s per phase
    u = rng.uniform(0.0, 1.0, (n, 1))
    led = np.floor(u * 2 + np.arange(T) * dt / half) % 2
    s = summaries.blink(led, dt)
    err2 = (s["toggle_rate"] - 1.0 / half[:, 0]) ** 2
    ratio = err2.mean() / s["toggle_rate_floor"].mean()
    se = err2.std() / np.sqrt(n) / err2.mean()
    assert 1.0 - 4 * se < ratio < 1.05 + 4 * se, (ratio, se)


def _square(T=400, first=5, phase=10):
    """LED samples (0/1) toggling every ``phase`` samples from sample ``first``: at dt 0.1 s, 1
    toggle per second exactly."""
    return (((np.arange(T) + phase - first) // phase) % 2).astype(float)


def test_toggle_rate_sees_through_misread_frames_and_lost_phases():
    """Hand-made tracks whose rate is 1 toggle/s exactly (a toggle every 10 samples at 0.1 s):
    clean; three single misread frames inside phases (each two spurious toggles: a plain count
    reads 45 phases in 39 s); a 3.2 s loss hiding three toggles (the count reads 37); misreads on
    the very first and the very last frame; all of these at once. The robust rate is 1.0 in each."""
    clean = _square()
    misread = clean.copy()
    misread[[42, 123, 277]] = 1 - misread[[42, 123, 277]]
    lost = clean.copy()
    lost[100:132] = np.nan  # toggles at 105, 115, 125 unseen; the one at 125 is seen at 132
    ends = clean.copy()
    ends[[0, 399]] = 1 - ends[[0, 399]]
    both = np.where(np.isnan(lost), np.nan, misread)
    both[[0, 399]] = 1 - both[[0, 399]]
    rate = summaries.blink(np.stack([clean, misread, lost, ends, both]), 0.1)["toggle_rate"]
    np.testing.assert_allclose(rate, 1.0, rtol=1e-12)


def test_toggle_rate_on_clean_tracks_is_the_plain_count():
    """Without misreads or lost frames the rate is (toggles - 1) / (last toggle - first toggle), a
    toggle timed at the first sample of a new colour: a second implementation by whole-array
    NumPy, on square waves of non-integer period, random phase, and tracks that start and end at
    random (a short run at either end is the recording's cut, not a misread: its toggle is kept).
    Phases of 1.7-2.4 samples (too short to tell a misread from a phase: the plain count) and of
    3.5-15. (Between, a run one sample short of the rest can fall off the phase grid and the
    robust rate drops an end toggle: rms error 7.7e-4 against the count's 7.6e-4 over 5000 such
    tracks.) Fewer than three toggles: NaN."""
    rng = np.random.default_rng(4)
    R, T = 300, 600
    period = np.where(rng.random(R) < 0.3, rng.uniform(1.7, 2.4, R), rng.uniform(3.5, 15.0, R))[:, None]
    led = np.floor(np.arange(T)[None, :] / period + rng.uniform(0, 2, (R, 1))) % 2
    start, stop = rng.integers(0, 60, R), rng.integers(T - 60, T + 1, R)
    led[np.arange(T)[None, :] < start[:, None]] = np.nan
    led[np.arange(T)[None, :] >= stop[:, None]] = np.nan
    led[:3] = np.nan
    led[:3, :30] = _square(30, 10, 10)  # two toggles only
    seen = np.isfinite(led)
    expected = np.full(R, np.nan)
    for r in range(R):
        c = led[r, seen[r]]
        idx = np.flatnonzero(seen[r])[1:][np.diff(c) != 0]
        if len(idx) >= 3:
            expected[r] = (len(idx) - 1) / ((idx[-1] - idx[0]) * 0.1)
    got = summaries.blink(led, 0.1)["toggle_rate"]
    assert np.isnan(got[:3]).all() and np.isfinite(got[3:]).all()
    np.testing.assert_allclose(got, expected, rtol=1e-12)
    # the compiled pass and the plain Python one (where Numba is not) give the same numbers
    led[3:, ::7] = np.nan
    led[3:, 5::11] = 1 - led[3:, 5::11]
    out = np.empty(R)
    summaries._toggle_rates(np.ascontiguousarray(led), out)
    np.testing.assert_allclose(out / 0.1, summaries.blink(led, 0.1)["toggle_rate"], rtol=1e-15)


def _motion_vectorised(x, y, dt_s, lag_s=2.0, wander_lags_s=(1.0, 10.0), speed_lags_s=(1.0, 5.0)):
    """A second implementation of summaries.motion (the project's former vectorised NumPy one,
    whole-array operations instead of one pass per track): the compiled loop must agree with it."""
    def wrap(a):
        return (a + np.pi) % (2 * np.pi) - np.pi

    def ffill(a):
        ok = np.isfinite(a)
        idx = np.where(ok, np.arange(a.shape[-1]), 0)
        np.maximum.accumulate(idx, axis=-1, out=idx)
        return np.where(np.maximum.accumulate(ok, axis=-1), np.take_along_axis(a, idx, axis=-1), np.nan)

    def wander(z, w):
        """Variance (ddof 1) of the second difference over w frames across its chord, as complex
        positions: the imaginary part of d2 conj(chord) / |chord|; NaN with fewer than 10."""
        d2 = z[..., 2 * w:] - 2 * z[..., w:-w] + z[..., :-2 * w]
        chord = z[..., 2 * w:] - z[..., :-2 * w]
        side = np.imag(d2 * np.conj(chord)) / np.abs(chord)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # tracks with no second difference
            return np.where(np.isfinite(side).sum(-1) >= 10, np.nanvar(side, axis=-1, ddof=1), np.nan)

    def refused(h, L):
        """The refusal rule, one track at a time: a heading that turned by over a quarter turn
        since the last accepted one is dropped, unless L in a row were dropped."""
        out = np.zeros(h.shape, bool)
        for idx in np.ndindex(h.shape[:-1]):
            last, run = None, 0
            for j in np.flatnonzero(np.isfinite(h[idx])):
                if last is not None and abs(wrap(h[idx][j] - last)) > np.pi / 2 and run < L:
                    out[idx][j], run = True, run + 1
                else:
                    last, run = h[idx][j], 0
        return out

    L = max(1, int(round(lag_s / dt_s)))
    dx, dy = x[..., L:] - x[..., :-L], y[..., L:] - y[..., :-L]
    dist, h = np.hypot(dx, dy), np.arctan2(dy, dx)
    h = np.where(refused(h, L), np.nan, h)
    ok = np.isfinite(h)
    step = np.nan_to_num(wrap(np.diff(ffill(h), axis=-1)), nan=0.0)
    first = np.where(ok.any(-1), np.take_along_axis(h, np.argmax(ok, axis=-1)[..., None], -1)[..., 0], 0.0)
    u = np.concatenate([np.zeros(h.shape[:-1] + (1,)), np.cumsum(step, axis=-1)], axis=-1) + first[..., None]
    t = np.arange(h.shape[-1]) * dt_s
    n = ok.sum(-1)
    tm = np.where(ok, t, 0).sum(-1) / np.maximum(n, 1)
    hm = np.where(ok, u, 0).sum(-1) / np.maximum(n, 1)
    dt_ = np.where(ok, t - tm[..., None], 0.0)
    turn = (dt_ * np.where(ok, u - hm[..., None], 0.0)).sum(-1) / np.maximum((dt_**2).sum(-1), 1e-12)
    # A slipped heading: the means of u over lag-long blocks (a quarter of them observed at least)
    # jump by over SLIP_RAD between neighbouring blocks that have a mean.
    nb = -(-u.shape[-1] // L)
    pad = np.zeros(u.shape[:-1] + (nb * L - u.shape[-1],))
    ub = np.concatenate([np.where(ok, u, 0.0), pad], -1).reshape(u.shape[:-1] + (nb, L))
    cb = np.concatenate([ok, pad.astype(bool)], -1).reshape(u.shape[:-1] + (nb, L)).sum(-1)
    with np.errstate(all="ignore"):
        block = np.where(4 * cb >= L, ub.sum(-1) / cb, np.nan)
        jump = np.abs(np.diff(ffill(block), axis=-1)) > summaries.SLIP_RAD
    turn = np.where(jump.any(-1), np.nan, turn)
    speed = np.where(ok, dist, 0.0).sum(-1) / np.maximum(n, 1) / (L * dt_s)
    w1, w2 = (max(1, int(round(s / dt_s))) for s in wander_lags_s)
    z = x + 1j * y
    with np.errstate(all="ignore"):
        diffusion = (wander(z, w2) - wander(z, w1)) / (2 / 3 * speed**2 * dt_s**3 * (w2**3 - w1**3))
    s1, s2 = (max(1, int(round(s / dt_s))) for s in speed_lags_s)
    var_d = []
    for lag in (s1, s2):
        dd = np.hypot(x[..., lag:] - x[..., :-lag], y[..., lag:] - y[..., :-lag])
        okd = np.isfinite(dd)
        nd = np.maximum(okd.sum(-1), 2)
        md = np.where(okd, dd, 0.0).sum(-1) / nd
        var_d.append(np.where(okd, (dd - md[..., None]) ** 2, 0.0).sum(-1) / (nd - 1))
    heading = np.arctan2(np.where(ok, np.sin(h), 0).sum(-1), np.where(ok, np.cos(h), 0).sum(-1))
    out = {"turn_rate": turn, "speed": speed, "diffusion": diffusion, "heading": heading,
           "speed_diffusion": (var_d[1] - var_d[0]) / ((s2 - s1) * dt_s)}
    return {k: np.where(n < 10, np.nan, v) for k, v in out.items()}


def test_compiled_motion_summaries_equal_a_vectorised_second_implementation():
    """Random walks crossing the +-pi cut many times (turning so fast that chords are refused and
    the headings slip: no turn rate) and slower ones,
    with dropped frames, long losses, a track with too few samples, leading gaps and a track that
    never appears: both agree to 1e-9."""
    rng = np.random.default_rng(7)
    K, N, T, dt = 3, 7, 700, 1 / 15
    th = np.cumsum(rng.normal(0, 0.3, (K, N, T)), axis=-1) + rng.uniform(-3, 3, (K, N, 1))
    th[:, 4:] *= 0.05  # and robots that turn slowly, whose headings do not slip
    x = np.cumsum(0.01 * np.cos(th), -1) + 0.002 * rng.standard_normal((K, N, T))
    y = np.cumsum(0.01 * np.sin(th), -1) + 0.002 * rng.standard_normal((K, N, T))
    drop = rng.random((K, N, T)) < 0.1
    drop[0, 1, 200:400] = True
    drop[1, 2, :150] = True
    drop[2, 3, 38:] = True  # fewer than 10 headings (2 s lag = 30 frames)
    drop[2, 4] = True
    x, y = np.where(drop, np.nan, x), np.where(drop, np.nan, y)
    got, want = summaries.motion(x, y, dt, wander_lags_s=(1.0, 10.0)), _motion_vectorised(x, y, dt)
    assert np.isnan(got["turn_rate"][2, 3]) and np.isnan(got["speed"][2, 4])
    # Both branches: fast walkers that slipped (no turn rate) and slow ones that did not.
    assert np.isnan(got["turn_rate"][:, :4]).sum() >= 6 and np.isfinite(got["turn_rate"][:, 4:]).sum() == 8
    for k in want:
        np.testing.assert_allclose(got[k], want[k], rtol=1e-9, atol=1e-12, equal_nan=True, err_msg=k)
    # Shared over threads (enough tracks that three threads get some each): the same.
    got = summaries.motion(np.tile(x, (30, 1, 1)), np.tile(y, (30, 1, 1)), dt, wander_lags_s=(1.0, 10.0), threads=3)
    for k in want:
        np.testing.assert_allclose(got[k], np.tile(want[k], (30, 1)), rtol=1e-9, atol=1e-12, equal_nan=True, err_msg=k)


def _straight(rng, n, T, dt=0.04, v=0.01, noise=0.002):
    """n straight tracks at v (m/s) along x, white noise of sd ``noise`` per coordinate."""
    t = np.arange(T) * dt
    return (v * t + noise * rng.standard_normal((n, T)), 0.3 + noise * rng.standard_normal((n, T)))


def test_a_glitch_among_the_stray_frames_of_a_lost_robot_is_removed():
    """A tracker that loses a robot for 1.6 s (40 frames at 25 Hz) reports two stray frames in
    the gap, one of them a false detection 13 cm off (the third world's seed 3003, where one such
    frame set a track's heading diffusion 100x the others'). Neither has an observed neighbour
    within 6 frames; against the line through the observed samples beyond the gap the glitch is
    ~30 noise sds out and the true frame within noise. By hand: the glitch goes, the true stray
    frame and every frame outside the gap stay."""
    rng = np.random.default_rng(3)
    x, y = _straight(rng, 1, 400)
    x[0, 200:240] = np.nan
    y[0, 200:240] = np.nan
    x[0, 212], y[0, 212] = 0.01 * 212 * 0.04, 0.3  # a true stray frame (on the path)
    x[0, 226], y[0, 226] = 0.01 * 226 * 0.04 - 0.03, 0.3 - 0.127  # a false detection
    xc, yc, removed = summaries.reject_glitches(x, y, 0.002, dt_s=0.04)
    assert np.isnan(xc[0, 226]) and np.isfinite(xc[0, 212])
    assert removed == 1


@pytest.mark.parametrize("where", ["last", "first", "before a gap", "beside the last"])
def test_a_glitch_on_a_track_s_end_goes_and_its_neighbours_stay(where):
    """A glitch of 5-30 cm on a track's end: its last or first observed sample, or the last
    before a gap longer than the span (the third world's tracks end where a robot leaves the
    field, and its glitches are 3-33 cm). Extrapolated from its two neighbours, the end's
    residual is scaled to half for its noise, and the neighbour's line runs to the glitch: both
    read G / 2 (so an end glitch is seen from about 2 x 1.1 cm here; 5 cm is 5.8 residual sds
    beyond that threshold). A glitch beside the end reads G there and G at the end. By hand:
    the glitch goes in every track, and a good sample only as often as Gaussian noise allows
    (4.5 sds in 2-D: exp(-4.5^2 / 2) = 4e-5 of the 120,000 samples, up to 1e-4 near an end:
    5-12 expected; at most 30, beyond which Poisson(12) has 1e-5). Before the end was told from its
    neighbour, the wrong one of the two went in a quarter to three quarters of the tracks, and
    with a glitch on the end the next good samples after it too."""
    rng = np.random.default_rng(5)
    n, T = 2000, 60
    x, y = _straight(rng, n, T, dt=0.2, v=0.017)
    e = {"last": T - 1, "first": 0, "before a gap": 30, "beside the last": T - 2}[where]
    if where == "before a gap":
        x[:, 31:45], y[:, 31:45] = np.nan, np.nan  # 14 frames lost at 5 Hz: beyond the 2 s span
    g = 0.05 + 0.25 * rng.random(n)
    phi = rng.uniform(-np.pi, np.pi, n)
    x[:, e] += g * np.cos(phi)
    y[:, e] += g * np.sin(phi)
    xc, _, removed = summaries.reject_glitches(x, y, 0.002, dt_s=0.2)
    assert np.isnan(xc[:, e]).all()
    lost = np.isnan(xc) & np.isfinite(x)
    lost[:, e] = False
    assert lost.sum() <= 30, (lost.sum(), np.nonzero(lost.any(0))[0])


def test_a_track_s_end_beyond_a_gap_is_removed_no_more_often_than_gaussian_noise_allows():
    """A track's last sample 4 frames after a pair of frames 1 apart, on pure Gaussian noise: the
    extrapolated residual has (1 + 5^2 + 4^2) = 42 noise variances, so scaled to the interior's
    1.5 it exceeds 4.5 sds in 2-D with probability exp(-4.5^2 / 2) = 4e-5 (chi-square, 2 dof).
    Over 20,000 tracks that is 0.8 expected; 10 or more has probability 1e-8. Halving it, as
    for adjacent frames, removed 9 %."""
    rng = np.random.default_rng(4)
    n = 20000
    x, y = _straight(rng, n, 60)
    x[:, 52:56] = np.nan
    y[:, 52:56] = np.nan
    x[:, 57:], y[:, 57:] = np.nan, np.nan  # last sample at 56, its pair at 50, 51
    x[:, 56], y[:, 56] = 0.01 * 56 * 0.04 + 0.002 * rng.standard_normal(n), 0.3 + 0.002 * rng.standard_normal(n)
    xc, _, _ = summaries.reject_glitches(x, y, 0.002)  # within 6 frames: the last sample is an end
    assert np.isnan(xc[:, 56]).sum() < 10


def test_sweep_readings_at_the_twins_ramp_are_the_engines():
    """``model.sweep_readings`` reads the core's sensor directly at given stimuli; at the twin's
    own ramp it must give the batch engine's readings draw for draw (the engine steps the whole
    robot: clocks, behaviour, motion), with reading noise, trial offsets and the knee."""
    from kilobot_twin.batch import engine
    from kilobot_twin.gap.model import sweep_readings

    sw = draw_population({"n": 6, "sensor_gain": {"dist": "normal", "mean": 2.2, "sd": 0.3}, "sensor_offset": 5.0,
                          "sensor_noise": 8.0, "sensor_offset_trial_sd": 4.0}, seed=1)
    sc = synth.light_scenario(30.0, 0.1, 9.0)
    runs = np.arange(6)
    res = engine.simulate(sc, sw, 7, runs=runs, trials=runs % 3, record_every=1, channels=("reading",))
    stim = np.broadcast_to(sc.light.v_value(res.t_s), res.traj["reading"].shape)
    got = sweep_readings(sc, sw, 7, runs, runs % 3, stim)
    assert np.array_equal(got, res.traj["reading"])
    assert got.max() > 900 and np.unique(got[0, 0]).size > 100  # a sweep up to the knee, not a constant


def _lens_world(rng, k, c, e, K=4, N=12, T=600, dt=0.1, v=0.008):
    """Tracks of the tests' own unicycle (Brownian headings at 0.01 rad/sqrt(s), speeds 0.8-1.2
    v) from random starts in a 0.6 m square, seen through a first-order radial lens (k, c) by
    hand, then white tracking noise e."""
    th = unicycle.brownian_headings(rng, K * N, T, dt, 1e-4) + rng.uniform(-np.pi, np.pi, (K * N, 1))
    x, y = unicycle.tracks(rng, th, 1.0, dt, 0.0)
    vv = v * rng.uniform(0.8, 1.2, (K * N, 1))
    x, y = x * vv + rng.uniform(-0.3, 0.3, (K * N, 1)), y * vv + rng.uniform(-0.3, 0.3, (K * N, 1))
    f = 1 + k * ((x - c[0]) ** 2 + (y - c[1]) ** 2)
    x, y = c[0] + (x - c[0]) * f, c[1] + (y - c[1]) * f
    x, y = x + e * rng.standard_normal(x.shape), y + e * rng.standard_normal(y.shape)
    return x.reshape(K, N, T), y.reshape(K, N, T)


def test_a_lens_is_read_off_how_chords_lengthen_across_the_field():
    """A lens of k1 = 0.05 / m^2 about (0.03, -0.02) m with 3 mm of tracking noise, 30 worlds:
    the estimate's error over its own standard error is a standard normal if that error is
    honest (mean within 4 / sqrt(30) of 0, sd within 0.6-1.5: the sd of a sample sd over 30 is
    0.13), and the centre is found to a few cm. Without a lens none is reported (5 sd: a false
    one in 30 worlds has probability 2e-5), and at 8 mm of noise neither, though a direction
    read off the noisy chord itself made 0.28 / m^2 there."""
    rng = np.random.default_rng(12)
    k, c = 0.05, (0.03, -0.02)
    got = [summaries.lens_distortion(*_lens_world(rng, k, c, 0.003), 0.1, z=0.0) for _ in range(30)]
    z = np.array([(g["k1_per_m2"] - k) / g["k1_se"] for g in got])
    assert abs(z.mean()) < 4 / np.sqrt(30) and 0.6 < z.std(ddof=1) < 1.5, (z.mean(), z.std(ddof=1))
    assert all(g["z"] > 5 for g in got)  # reported at its default threshold
    centre = np.array([g["centre_m"] for g in got])
    assert np.all(np.abs(np.median(centre, axis=0) - c) < 0.02), np.median(centre, axis=0)
    for e in (0.003, 0.008):
        assert all(summaries.lens_distortion(*_lens_world(rng, 0.0, c, e), 0.1) is None for _ in range(15))


def test_lens_undistort_by_hand():
    """(0.5, 0) about the origin at k1 = 0.04 / m^2 is seen at 0.5 (1 + 0.04 x 0.25) = 0.505, and
    undistorting returns it; points seen through a lens about an off-origin centre (distorted by
    hand here) come back; no lens leaves positions as they are."""
    lens = {"k1_per_m2": 0.04, "centre_m": (0.0, 0.0)}
    x, y = summaries.lens_undistort(np.array([0.505]), np.array([0.0]), lens)
    assert x[0] == pytest.approx(0.5, abs=1e-12) and y[0] == 0.0
    k, (cx, cy) = -0.06, (0.1, -0.2)
    px, py = np.array([0.4, -0.3, 0.1]), np.array([0.2, 0.5, -0.2])
    f = 1 + k * ((px - cx) ** 2 + (py - cy) ** 2)
    seen = (cx + (px - cx) * f, cy + (py - cy) * f)
    np.testing.assert_allclose(summaries.lens_undistort(*seen, {"k1_per_m2": k, "centre_m": (cx, cy)}), (px, py), atol=1e-12)
    assert summaries.lens_undistort(px, py, None) == (px, py)


def _framed(x, y, half):
    """The positions a camera whose frame spans +-``half`` m reports: outside it, none."""
    out = (np.abs(x) > half) | (np.abs(y) > half)
    return np.where(out, np.nan, x), np.where(out, np.nan, y)


def test_a_lens_s_centre_is_weighed_against_the_middle_of_the_frame():
    """The chords pin a lens's centre to a few cm only. Worlds of the tests' own, framed by a
    camera that sees +-0.45 m (robots beyond it are not seen), each lens's axis drawn about the
    frame's middle with the sd that the weighing assumes (3 % of the 0.9 m frame: 2.7 cm):

    - the data's centre, over its own jackknife se, is a standard normal (sd within 0.75-1.3
      over 80 coordinates: the sample sd's own sd there is 0.08);
    - the weighed centre's squared errors sum to less than the data centre's (paired by world,
      the mean difference is 2.8 of its standard errors above 0 here), and over the posterior
      variance 1 / (1 / se^2 + 1 / prior sd^2) they average 1 (chi-square with 80 degrees of
      freedom: 0.52-1.70 holds it with probability 1 - 2e-4). Taking the data's centre alone
      reads about 2 there (se and prior sd are alike), the prior's middle alone too;
    - where the data pin the centre (40 robots x 6 trials of 3 min: se 0.6 cm), an axis 15 cm
      off the frame's middle (over 5 of the prior's sds) is followed: the weighed centre lies
      within a quarter of the prior's distance of it (the weighing leaves (1 - 0.95) x 15 cm,
      0.7 cm; the margin is 5 se)."""
    rng = np.random.default_rng(41)
    z, gain, post = [], [], []
    for _ in range(40):
        c = rng.normal(0.0, 0.03 * 0.9, 2)
        k = rng.choice([-1.0, 1.0]) * rng.uniform(0.03, 0.08)
        g = summaries.lens_distortion(*_framed(*_lens_world(rng, k, c, 0.003), 0.45), 0.1, z=0.0)
        data, weighed = np.array(g["centre_data_m"]), np.array(g["centre_m"])
        se, tau = np.array(g["centre_se_m"]), np.array(g["centre_prior_sd_m"])
        z.extend((data - c) / se)
        gain.append(np.sum((data - c) ** 2) - np.sum((weighed - c) ** 2))
        post.extend((weighed - c) ** 2 * (1 / se**2 + 1 / tau**2))
    assert 0.75 < np.std(z, ddof=1) < 1.3 and abs(np.mean(z)) < 4 / np.sqrt(80), (np.mean(z), np.std(z, ddof=1))
    assert np.mean(gain) > 0, (np.mean(gain), np.std(gain, ddof=1))
    assert 0.52 < np.mean(post) < 1.70, np.mean(post)
    c = np.array([0.15, -0.0])
    x, y = _lens_world(rng, 0.06, c, 0.003, K=6, N=40, T=1800, v=0.004)
    g = summaries.lens_distortion(*_framed(x, y, 0.45), 0.1)
    prior = np.array(g["centre_prior_m"])
    assert np.hypot(*(np.array(g["centre_m"]) - c)) < 0.25 * np.hypot(*(prior - c)), g


def test_a_camera_axis_the_user_gives_is_the_lens_centre_s_prior(tmp_path):
    """Robots in an arena to one side of the camera's axis (x in 0..0.45 m, the axis near x = 0,
    drawn about (0, 0) with sd 1 cm; 40 worlds): the middle of their span is 22 cm off the
    axis, many of the prior's sds, and the chords pin the centre to 5-50 cm only there. Given
    where the axis meets the floor and how well (``axis_m``, ``axis_sd_m``), the weighed
    centre's squared errors over the posterior variance average 1 (chi-square with 80 degrees of
    freedom: 0.52-1.70 with probability 1 - 2e-4); weighed against the span's middle (10 of
    the worlds) they average far above it. The data's centre over its se stays a standard normal.
    Read from a dataset's meta.yaml (``camera_axis_m``, ``camera_axis_sd_m``), the axis reaches
    the fit."""
    rng = np.random.default_rng(43)
    given, middle, z = [], [], []
    for i in range(40):
        c = rng.normal(0.0, 0.01, 2)
        k = rng.choice([-1.0, 1.0]) * rng.uniform(0.03, 0.08)
        x, y = _lens_world(rng, k, c, 0.003)
        out = (x < 0) | (x > 0.45) | (np.abs(y) > 0.45)
        x, y = np.where(out, np.nan, x), np.where(out, np.nan, y)
        g = summaries.lens_distortion(x, y, 0.1, z=0.0, axis_m=(0.0, 0.0), axis_sd_m=0.01)
        assert g["centre_prior_m"] == (0.0, 0.0) and g["centre_prior_sd_m"] == (0.01, 0.01)
        se = np.array(g["centre_se_m"])

        def posterior_z2(r):
            return (np.array(r["centre_m"]) - c) ** 2 * (1 / se**2 + 1 / np.array(r["centre_prior_sd_m"]) ** 2)

        given.extend(posterior_z2(g))
        if i < 10:
            middle.extend(posterior_z2(summaries.lens_distortion(x, y, 0.1, z=0.0)))
        z.extend((np.array(g["centre_data_m"]) - c) / se)
    assert 0.52 < np.mean(given) < 1.70, np.mean(given)
    assert np.mean(middle) > 10, np.mean(middle)
    assert 0.75 < np.std(z, ddof=1) < 1.3 and abs(np.mean(z)) < 4 / np.sqrt(80), (np.mean(z), np.std(z, ddof=1))

    K, N, T, dt = 4, 12, 600, 0.1
    x, y = _lens_world(rng, 0.06, (0.0, 0.0), 0.003, K=K, N=N, T=T, dt=dt)
    t = np.arange(T) * dt
    tracks = {(i, j): measured.Track(t, {"x_m": x[i, j], "y_m": y[i, j]}) for i in range(K) for j in range(N)}
    meta = {"kind": "motion", "robots": list(range(N)), "trials": K, "dt_s": dt, "duration_s": T * dt,
            "behavior": "straight", "nominal_speed_m_s": 0.008}
    plain, _ = measured_summaries(measured.load(measured.write(tmp_path / "plain", meta, tracks)))
    more = {"camera_axis_m": [0.05, -0.02], "camera_axis_sd_m": 0.004}
    cond, _ = measured_summaries(measured.load(measured.write(tmp_path / "axis", {**meta, **more}, tracks)))
    assert plain.lens["centre_prior_sd_m"][0] > 0.01  # 3 % of the span
    assert cond.lens["centre_prior_m"] == (0.05, -0.02) and cond.lens["centre_prior_sd_m"] == (0.004, 0.004)
    assert cond.lens["centre_data_m"] == plain.lens["centre_data_m"] and cond.lens["centre_m"] != plain.lens["centre_m"]
