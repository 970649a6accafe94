"""The independent world (benchmarks/indep_world.py) writes datasets the project's reader accepts,
and its physics agrees with the project's summaries (two code bases, one answer)."""

import json

import inspect

import numpy as np
import pytest

from kilobot_twin.recording import measured
from kilobot_twin.gap.model import measured_summaries
from kilobot_twin.gap.summaries import light_sweep
from . import benchmark

iw = benchmark.load("indep_world")


@pytest.mark.parametrize("kind, hidden", [("motion", "heading_bias,floor_tilt"), ("motion", "motion_noise"),
                                          ("light_sweep", "sensor_gain"), ("blink", "clock_drift")])
@pytest.mark.parametrize("seed", [1, 2])
def test_reader_accepts_randomised_datasets(tmp_path, kind, hidden, seed):
    truth = iw.generate(kind, hidden, tmp_path, seed=seed)
    ds = measured.load(tmp_path)  # raises on anything the format does not allow
    sh = truth["shape"]
    assert ds.kind == kind and ds.trials == sh["trials"] and ds.robots == list(range(sh["robots"]))
    assert ds.dt_s == pytest.approx(1 / sh["frame_hz"])
    missing = {tuple(m) for m in sh["missing"]}
    assert set(ds.tracks) == {(k, i) for k in range(sh["trials"]) for i in range(sh["robots"])} - missing
    # Uneven trials: each track ends within a frame of its trial's length.
    for (k, i), tr in ds.tracks.items():
        assert tr.t_s[-1] <= sh["lengths_s"][k] + 0.01
    assert json.loads((tmp_path / "truth.json").read_text())["hidden"] == hidden.split(",")


def test_noiseless_world_matches_the_projects_summaries(tmp_path):
    """Without nuisances the world's robots turn at their true rate and drive at their true speed
    (the twin's summaries, a second implementation, measure them), and the true heading bias in
    the twin's units is b = -omega L / v."""
    truth = iw.generate("motion", "heading_bias,speed_heterogeneity", tmp_path, seed=4, nuisance_scale=0.0)
    _, s = measured_summaries(measured.load(tmp_path))
    w = np.array([truth["robots"][str(i)]["turn_rate_rad_s"] for i in range(truth["shape"]["robots"])])
    v = np.array([truth["robots"][str(i)]["speed_m_s"] for i in range(truth["shape"]["robots"])])
    # Summaries use 2 s chords: on a circle of radius v/w the chord is 2 (v/w) sin(w 1 s), shorter
    # than v 2 s by a relative (w 1 s)^2 / 6 < 1e-3 here; headings of chords turn at exactly w.
    seen = _seen(truth)
    assert np.isfinite(s["turn_rate"]).sum() == seen.sum()
    np.testing.assert_allclose(s["turn_rate"][seen], np.broadcast_to(w, seen.shape)[seen], atol=2e-5)
    np.testing.assert_allclose(s["speed"][seen], np.broadcast_to(v, seen.shape)[seen], rtol=2e-3)
    b = np.array([truth["robots"][str(i)]["heading_bias"] for i in range(len(w))])
    np.testing.assert_allclose(b, -w * 0.025 / v)


def test_noiseless_sensor_and_clock(tmp_path):
    t = iw.generate("light_sweep", "sensor_gain", tmp_path / "l", seed=5, nuisance_scale=0.0)
    _, s = measured_summaries(measured.load(tmp_path / "l"))
    g = np.array([t["robots"][str(i)]["sensor_gain"] for i in range(t["shape"]["robots"])])
    o = np.array([t["robots"][str(i)]["sensor_offset"] for i in range(t["shape"]["robots"])])
    # Expected: a least-squares line (numpy's polyfit) through the world's noiseless response
    # on a fine grid of V, below the knee the summary uses; rounding to counts moves it by far
    # less than the tolerance.
    knee = inspect.signature(light_sweep).parameters["knee_counts"].default
    V = np.linspace(0.02, 1, 20001)
    exp_g, exp_o = np.empty(len(g)), np.empty(len(g))
    for i in range(len(g)):
        raw = o[i] + g[i] * 1024 * V
        r = raw / (1 + (raw / 1023) ** 9) ** (1 / 9)
        exp_g[i], exp_o[i] = np.polyfit(V[r < knee], r[r < knee], 1)
    seen = _seen(t)
    np.testing.assert_allclose(s["gain"][seen], np.broadcast_to(exp_g, seen.shape)[seen], rtol=2e-3)
    np.testing.assert_allclose(s["offset"][seen], np.broadcast_to(exp_o, seen.shape)[seen], atol=1.5)
    t = iw.generate("blink", "clock_drift", tmp_path / "b", seed=5, nuisance_scale=0.0)
    _, s = measured_summaries(measured.load(tmp_path / "b"))
    c = np.array([t["robots"][str(i)]["clock_rate"] for i in range(t["shape"]["robots"])])
    # 31 Hz x rate / 30 ticks per toggle; toggles timed to a frame (1/30 s) over ~120 s.
    seen = _seen(t)
    np.testing.assert_allclose(s["toggle_rate"][seen], np.broadcast_to(31 * c / 30, seen.shape)[seen], rtol=1e-3)


def _seen(truth):
    """(trials, robots) True where the robot took part in the trial."""
    sh = truth["shape"]
    seen = np.ones((sh["trials"], sh["robots"]), bool)
    for k, i in sh["missing"]:
        seen[k, i] = False
    return seen


def test_bad_effect_name_is_one_line_and_exit_2(tmp_path, capsys):
    assert iw.main(["--kind", "blink", "--hidden", "heading_bias", "--out", str(tmp_path / "x")]) == 2
    assert "heading_bias is not an effect of blink" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_a_forced_correlation_time_replaces_only_that_level(tmp_path):
    """``nuisance`` (``--heading-noise-tau``) sets the turn-rate noise's correlation time and leaves
    every other drawn level, the shape and the program as the seed draws them; an unknown level
    is refused before anything is written."""
    a = iw.generate("motion", "none", tmp_path / "a", seed=4)
    b = iw.generate("motion", "none", tmp_path / "b", seed=4, nuisance={"heading_noise_tau_s": 5.0})
    assert b["nuisance"]["heading_noise_tau_s"] == 5.0 != a["nuisance"]["heading_noise_tau_s"]
    assert {k: v for k, v in a["nuisance"].items() if k != "heading_noise_tau_s"} == \
        {k: v for k, v in b["nuisance"].items() if k != "heading_noise_tau_s"}
    assert a["shape"] == b["shape"]
    assert iw.main(["--out", str(tmp_path / "c"), "--heading-noise-tau", "2"]) == 0
    assert json.loads((tmp_path / "c" / "truth.json").read_text())["nuisance"]["heading_noise_tau_s"] == 2.0
    with pytest.raises(ValueError, match="heading_tau is not a nuisance level"):
        iw.generate("motion", "none", tmp_path / "d", seed=4, nuisance={"heading_tau": 1.0})
    assert not (tmp_path / "d").exists()


def test_the_worlds_persistent_tracking_error_is_an_exact_ornstein_uhlenbeck_process():
    """``_ou_at`` samples OU noise exactly at uneven times: its sd is the stationary one from the
    first frame on, and frames |dt| apart correlate as exp(-|dt| / tau) (theory, not a fit)."""
    rng = np.random.default_rng(11)
    t = np.cumsum(rng.uniform(0.02, 0.18, (4000, 60)), axis=1)  # uneven, as jittered frames are
    sd, tau = 0.003, 0.25
    e = iw._ou_at(rng, t, sd, tau)
    # 4000 samples per column: an sd's relative standard error is 1/sqrt(2 x 4000) = 1.1 %.
    np.testing.assert_allclose(e.std(axis=0)[[0, 30, 59]], sd, rtol=0.045)
    for j in (1, 10):  # correlation of frame j with frame j+1, whose gap differs per row
        gap = t[:, j + 1] - t[:, j]
        short, long_ = gap < 0.06, gap > 0.14
        for m in (short, long_):
            r = np.mean(e[m, j] * e[m, j + 1]) / sd**2
            expect = np.mean(np.exp(-gap[m] / tau))
            assert abs(r - expect) < 4 / np.sqrt(m.sum()), (j, r, expect)


def test_persistent_tracking_error_is_added_on_its_own_stream_and_the_twin_reads_it(tmp_path):
    """Turned off, the world writes what it wrote before the tracker error was added (nothing else
    draws from its stream); turned on, the positions differ by the error alone; and the project's
    estimator (a second implementation) reads its size and correlation time from the data."""
    base = {"tracking_noise_m": 0.001, "glitch_p": 0.0, "heading_noise": 0.01, "speed_noise": 0.0005}
    off = iw.generate("motion", "none", tmp_path / "off", seed=6, nuisance={**base, "tracking_correlated_m": 0.0})
    on = iw.generate("motion", "none", tmp_path / "on", seed=6,
                     nuisance={**base, "tracking_correlated_m": 0.003, "tracking_tau_s": 0.25})
    a = np.loadtxt(tmp_path / "off" / "observations.csv", delimiter=",", skiprows=1)
    b = np.loadtxt(tmp_path / "on" / "observations.csv", delimiter=",", skiprows=1)
    assert off["shape"] == on["shape"] and a.shape == b.shape
    np.testing.assert_array_equal(a[:, :3], b[:, :3])
    d = b[:, 3:] - a[:, 3:]
    assert 0.0027 < d.std() < 0.0033 and abs(np.corrcoef(d[:-1, 0], d[1:, 0])[0, 1]) > 0.2
    # Tolerances: 4x the sd over 12 seeds of this world at these levels (1.4 %, 2.9 %, 4.6 %).
    cond, _ = measured_summaries(measured.load(tmp_path / "on"))
    assert cond.tracking_correlated_m == pytest.approx(0.003, rel=0.06)
    assert cond.tracking_tau_s == pytest.approx(0.25, rel=0.12)
    assert cond.tracking_noise_m == pytest.approx(0.001, rel=0.2)
    cond, _ = measured_summaries(measured.load(tmp_path / "off"))
    assert cond.tracking_correlated_m == 0.0 and cond.tracking_noise_m == pytest.approx(0.001, rel=0.1)


@pytest.mark.parametrize("seed, spread", [(11, 12.0), (12, 0.0)])
def test_the_base_reads_the_sensors_two_noises_of_another_world(tmp_path, seed, spread):
    """The base fits the light sensor's reading noise and its offset's trial-to-trial spread
    (``effects.fit_sensor_noise``) to a world that shares no code with the twin: another sensor
    curve, its own noise, offsets shifted per trial from their own stream. The tolerances are
    the estimates' sampling errors, from theory: a variance read from the within-robot scatter
    of ``dof`` sweep-to-sweep deviations has a relative standard error sqrt(2 / dof), so its
    sd half that. A spread of 0 must come out 0 within 4 standard errors of the offsets'
    within-robot variance. (With the spread's column taken out of the fit, seed 11 reads a
    spread of 0 for the world's 12 counts and fails.)"""
    from kilobot_twin.gap import effects as E
    from kilobot_twin.gap import workflow as W

    truth = iw.generate("light_sweep", "none", tmp_path / "d", seed=seed,
                        nuisance={"sensor_noise": 8.0, "sensor_offset_trial_sd": spread})
    cond, meas = measured_summaries(measured.load(tmp_path / "d"))
    meas = E.Summaries(meas, np.arange(cond.trials))
    offsets = np.asarray(meas["offset"])  # (K, N), NaN where a robot missed a trial
    dof = int(np.sum(np.sum(np.isfinite(offsets), axis=0) - 1))
    fitter = W._Fitter(cond, meas, E.nominal_model("light_sweep", cond.robot_ids), W.GapSettings(seed=seed), True)
    base = fitter.fit((), np.arange(cond.trials))
    got = float(base.swarm.sensor_offset_trial_sd.mean())
    reading_sd = float(base.swarm.sensor_noise.mean()) / np.sqrt(10)  # the twin averages 10 samples a reading
    rel = 1.0 / np.sqrt(2 * dof)
    if spread > 0:
        assert abs(got / spread - 1) < 4 * rel, (got, dof)
    else:
        assert got**2 <= 4 * np.sqrt(2.0 / dof) * E.within_var(offsets), (got, dof)
    assert abs(reading_sd / truth["nuisance"]["sensor_noise"] - 1) < 4 * rel, (reading_sd, dof)
    # The report states the noise a reading carries, the one a user measures, beside the per-sample one.
    assert W._nuisances(base, cond)["reading_noise_counts"] == pytest.approx(reading_sd, rel=1e-12)


@pytest.mark.parametrize("seed, spread", [(13, 6.0), (49, 1.4)])
def test_the_base_rounds_as_another_worlds_noiseless_sensor(tmp_path, seed, spread):
    """A sensor without reading noise (the independent world: its own soft clip, p = 9, offsets
    that shift by 6 or 1.4 counts from trial to trial, rounding): the base reads its bend (within
    a grid step of 9), fits no reading noise, and its gains vary from sweep to sweep as the data's
    do: the log of the ratio of within-robot variances within 4 standard errors (the data's
    variance from ``dof`` deviations, relative se sqrt(2 / dof); the model's from its
    replicates, sqrt(2 / (M dof))). The rounding floor's dither (sqrt(1/12) counts a sample)
    or the twin's own knee (p = 6) made the model's 4.5-5x the data's on seed 3060 of the
    evaluation. Seed 49 (10 robots x 7 trials) took the dither where the kinds of sensor were
    judged by the linear maps' misses (``effects.fit_sensor_noise``): its gains then varied 2.1x
    the data's; judged by simulating each kind, 0.94x."""
    from kilobot_twin.gap import effects as E
    from kilobot_twin.gap import workflow as W
    from kilobot_twin.gap.model import simulate

    iw.generate("light_sweep", "none", tmp_path / "d", seed=seed, nuisance={"sensor_noise": 0.0, "sensor_offset_trial_sd": spread})
    cond, meas = measured_summaries(measured.load(tmp_path / "d"))
    assert abs(np.log(cond.sensor_knee / 9.0)) <= np.log(2.0) / 6, cond.sensor_knee
    meas = E.Summaries(meas, np.arange(cond.trials))
    gs = W.GapSettings(seed=seed)
    base = W._Fitter(cond, meas, E.nominal_model("light_sweep", cond.robot_ids), gs, True).fit((), np.arange(cond.trials))
    assert np.all(base.swarm.sensor_noise == 0.0)
    gains = np.asarray(meas["gain"])
    dof = int(np.sum(np.sum(np.isfinite(gains), axis=0) - 1))
    sim = simulate(cond, base, gs.m_ref, 5)
    ratio = float(np.mean(E.within_var(sim["gain"]))) / E.within_var(gains)
    se = np.sqrt(2.0 / dof * (1 + 1 / gs.m_ref))
    assert abs(np.log(ratio)) < 4 * se, (ratio, dof)


def test_a_noiseless_sensor_s_held_out_gains_are_predicted_as_widely_as_they_vary(tmp_path):
    """Another world's sensor without reading noise, its offsets shifting by 2 counts from trial to
    trial (seed 22: 21 robots x 5 trials), varies in gain from sweep to sweep by less than a part
    in 10^4 of the gain, the variance floor of the held-out predictions elsewhere. The base's
    replicates vary as the world's rounding does there, and a calibrated prediction of null data
    has a mean z^2 of 1 over the held-out tracks: within 4 of its standard errors, sqrt(2 / n) for
    n tracks (theory). Floored at a part in 10^4 (as before ``workflow._predictive_floor``) it was
    0.40, and so was every candidate's, which divided what a right sensor gain gains by 2.5."""
    from kilobot_twin.gap import effects as E
    from kilobot_twin.gap import workflow as W

    iw.generate("light_sweep", "none", tmp_path / "d", seed=22, nuisance={"sensor_noise": 0.0, "sensor_offset_trial_sd": 2.0})
    cond, meas = measured_summaries(measured.load(tmp_path / "d"))
    gains = np.asarray(meas["gain"])
    # the premise, by hand: the robots' gains vary within themselves by less than 1e-4 of the gain
    dev = gains - np.nanmean(gains, axis=0)
    dof = int(np.sum(np.sum(np.isfinite(gains), axis=0) - 1))
    assert np.sqrt(np.nansum(dev**2) / dof) < 1e-4 * np.nanmean(gains)
    meas = E.Summaries(meas, np.arange(cond.trials))
    fitter = W._Fitter(cond, meas, E.nominal_model("light_sweep", cond.robot_ids), W.GapSettings(seed=22), True)
    pred = W._heldout(fitter, (), "light_sweep")["gain"]
    z2 = ((gains - pred["mean"]) / pred["sd"]) ** 2
    n = int(np.isfinite(z2).sum())
    assert abs(np.nanmean(z2) - 1.0) < 4 * np.sqrt(2.0 / n), (np.nanmean(z2), n)


def test_robots_that_read_alike_do_not_leave_a_level_gap_on_null_data(tmp_path):
    """Another world's noiseless sensor on identical robots (no reading noise, no offset spread):
    every robot rounds the same sweep to the same integers, so a trial's gain and offset are off
    by one rounding, shared by the swarm, not by one robot's over n. The data show no reading
    noise beyond the rounding (below 0.1 counts: the world has none), too little to dither it. On
    null data a right model's per trial level is then z^2 of K trials, its excess over 1 within
    4 sds (sqrt(2 / K)) of 0, and the report names the shared part. Broken (the level's spread
    left at 1 / n of a robot's, as before ``workflow.shared_deviation``): 17.0 and 17.7 on this
    seed (independent light null 3296 of the evaluation read 7.2 and 11.0)."""
    from kilobot_twin.gap.workflow import GapSettings, data_reading_noise, run_gap

    iw.generate("light_sweep", "none", tmp_path / "d", seed=1, nuisance={"sensor_noise": 0.0, "sensor_offset_trial_sd": 0.0})
    assert data_reading_noise(measured_summaries(measured.load(tmp_path / "d"))[1]) < 0.1
    s = run_gap([str(tmp_path / "d")], tmp_path / "r", gs=GapSettings(seed=1), log=lambda *a: None)["datasets"][0]
    assert s["named_effects"] == []
    for c, parts in s["gap_by_part"].items():
        assert parts["level"][0] < 4 * np.sqrt(2.0 / s["trials"]), (c, parts, s["trials"])
        assert s["shared_deviation"][c] > 0.5, s["shared_deviation"]
        assert s["shared_rounding_sd"][c] > 0, s["shared_rounding_sd"]
    assert "share part of their deviation" in (tmp_path / "r" / "report.md").read_text()


def test_a_swarm_wide_shift_from_trial_to_trial_stays_in_the_level_gap(tmp_path):
    """The light's level shifting every robot's readings alike from trial to trial (+8 counts,
    -8, ..., written into another world's noisy null sweeps here) is a disagreement the library
    has no effect for. The robots share that deviation too, but their reading noise (the world's
    8 counts, read off the data within 10 %) dithers the ADC's rounding, so none of it is shared
    rounding, and the per trial level of the offset must show it (above 4 sds, sqrt(2 / K), of
    a right model's), as before the shared rounding was let into the level's spread. On the
    world's fixed shape (12 robots x 4 trials at 10 Hz: 7 s alone; the seed's own 29 x 8 at 20 Hz
    took 25-27 s in the suite). Broken (the shared part taken whatever the noise): the level
    reads 0.32 against 2.83 and this fails (0.18 on the larger shape)."""
    import csv

    from kilobot_twin.gap.workflow import GapSettings, data_reading_noise, run_gap

    d = tmp_path / "d"
    iw.generate("light_sweep", "none", d, seed=7, fixed_shape=True, nuisance={"sensor_noise": 8.0, "sensor_offset_trial_sd": 4.0})
    with open(d / "observations.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        shifted = float(r["reading"]) + (8.0 if int(r["trial"]) % 2 == 0 else -8.0)
        r["reading"] = str(int(np.clip(shifted, 0, 1023)))
    with open(d / "observations.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    assert abs(data_reading_noise(measured_summaries(measured.load(d))[1]) / 8.0 - 1) < 0.1
    s = run_gap([str(d)], tmp_path / "r", gs=GapSettings(seed=7), log=lambda *a: None)["datasets"][0]
    assert s["named_effects"] == []
    assert s["gap_by_part"]["offset"]["level"][0] > 4 * np.sqrt(2.0 / s["trials"]), s["gap_by_part"]
