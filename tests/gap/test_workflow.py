"""The gap workflow on synthetic data with known hidden effects (reduced simulation counts).

`benchmarks/eval_gap.py` measures the rates over many seeds; here each case runs once with a
fixed seed, and the slow variant repeats over seeds.
"""

import json

import numpy as np
import pytest

from kilobot_twin.core import sim
from kilobot_twin.core.traits import load_swarm
from kilobot_twin.gap.synth import motion_scenario, synth
from kilobot_twin.gap.workflow import GapSettings, run_gap
from . import benchmark

FAST = GapSettings(seed=1, m_null=80, m_ref=12, m_score=20, boot=300)


def run(tmp_path, kind, hidden, seed=5, robots=None, gs=FAST):
    ds = tmp_path / f"{kind}_{hidden or 'none'}"
    truth = synth(kind, hidden, ds, seed=seed, robots=robots)
    rep = run_gap([str(ds)], tmp_path / "out", gs=gs, log=lambda *a: None)
    return truth, rep


def test_heading_bias_named_recovered_and_gap_shrinks(tmp_path):
    truth, rep = run(tmp_path, "motion", "heading_bias")
    assert rep["named_effects"] == ["heading_bias"] and not rep["unexplained"]
    fitted = load_swarm(rep["model"])
    true = np.array([truth["robots"][str(i)]["heading_bias"] for i in fitted.ids])
    assert np.corrcoef(true, fitted.heading_bias)[0, 1] >= 0.95
    # Slope and intercept, not only correlation: each robot within 4 standard errors of its
    # turn rate's mean (b = -omega L / v), and the fitted-vs-true line's slope within 10 % of 1.
    tol = _per_robot_tolerance(tmp_path / "motion_heading_bias", "turn_rate", 4) * 0.025 / (0.06 * 48 / 255)
    assert np.all(np.abs(fitted.heading_bias - true) <= tol), (fitted.heading_bias - true, tol)
    assert abs(np.polyfit(true, fitted.heading_bias, 1)[0] - 1) <= 0.1
    # The updated model loads into the batch engine and runs there (the same gap run: each run costs seconds).
    res = sim.simulate(motion_scenario(10.0, 0.1), fitted, 0)
    assert res.summary["x"].shape == (1, len(fitted))
    assert rep["gap_shrink"]["value"] >= 0.8 and rep["gap_shrink"]["ci95"][0] > 0
    sh = rep["gap_shrink"]  # the gap removed, as the report's own numbers before and after make it
    assert sh["removed"] == pytest.approx(sh["before"] - sh["after"]) and 0 < sh["removed_ci95"][0] < sh["removed"]
    assert rep["disagreements"][0]["signal"] == "turn_rate:between_robots"
    # The report has every field the issue names.
    doc = json.loads((tmp_path / "out" / "report.json").read_text())
    for k in ("named_effects", "unexplained", "unexplained_signals", "gap_before", "gap_after", "steps",
              "disagreements", "model"):
        assert k in doc
    assert set(doc["gap_before"]) == {"metric", "value", "ci95"}
    step = doc["steps"][0]
    # No rival explanation of turn rates besides bias_drift, which contains heading_bias: the
    # report says so instead of showing a runner-up (and writes no Infinity into the JSON).
    assert step["name"] == "heading_bias" and step["runner_up"]["name"] is None and "gap_after" in step
    assert "bias_drift skipped: it extends heading_bias" in step["runner_up"]["why_this_one"]
    assert "Infinity" not in (tmp_path / "out" / "report.json").read_text()
    # The report states how closely the per-robot values can follow the truth; here they do (r >= 0.95 above).
    assert doc["datasets"][0]["estimates"]["heading_bias"]["expected_r"] >= 0.95
    assert "heading_bias: expected r" in (tmp_path / "out" / "report.md").read_text()
    # What sigma_omega is: white noise that wanders as much between the wander's lags, which the
    # report gives (docs/gap_methods.md: 1 s and 10 s x sqrt(e / 2 mm) within 4..20 s, e the whole tracking error).
    nz = doc["datasets"][0]["nuisances"]
    e = np.hypot(nz["tracking_noise_m"], nz.get("tracking_correlated_m", 0.0))
    assert nz["wander_lags_s"] == pytest.approx([1.0, float(np.clip(10 * np.sqrt(e / 0.002), 4, 20))])
    assert ("white heading noise that makes the tracks wander as much as measured between 1 and %.2g s"
            % nz["wander_lags_s"][1]) in (tmp_path / "out" / "report.md").read_text()
    # The base's noise levels with their 90 % intervals (tests/gap/test_nuisance_ci.py checks
    # their coverage), named as the levels are, in report.json and report.md.
    ci = doc["datasets"][0]["nuisance_ci90"]
    assert set(ci) == {"sigma_omega_rad_sqrt_s", "sigma_v_m_sqrt_s", "speed_trial_sd", "bias_trial_sd"}
    assert all(0 <= lo <= hi for lo, hi in ci.values())
    assert "sigma_omega_rad_sqrt_s %.3g (90 %% CI %.3g .. %.3g)" % (nz["sigma_omega_rad_sqrt_s"], *ci["sigma_omega_rad_sqrt_s"]) \
        in (tmp_path / "out" / "report.md").read_text()
    # What it can see: naming needs the flag, so no size it names is below the one it detects.
    md = (tmp_path / "out" / "report.md").read_text()
    for eff, v in doc["datasets"][0]["minimum_detectable"].items():
        assert v["size"] is None or v["detection_size"] <= v["size"], (eff, v)
        # and report.md says so, "none up to" the largest spread searched where no size has the power
        named, detected = ("none up to %.3g" % v["searched_to"] if x is None else "%.3g" % x for x in (v["size"], v["detection_size"]))
        if v["size"] is None:  # and how near the search came
            assert v["best_power"] < 0.8 and 0 < v["best_at"] <= v["searched_to"]
            named += (" (at most %.0f %% power, at %.3g)" % (100 * v["best_power"], v["best_at"]) if v["best_power"] > 0
                      else " (named at none of the sizes searched)")
        assert f"- {eff}: named {named}, detected {detected} (" in md
        # and with more robots or trials (tests/gap/test_designs.py checks the scale): smaller, and said
        if eff != "motion_noise" and v["detection_size"] is not None:
            more = v["at_other_designs"]
            assert [x["robots"] for x in more] == [len(fitted)] * 3 + [2 * len(fitted)]
            assert all(x["detection_size"] < v["detection_size"] for x in more)
            assert "%d robots x %d trials %.3g" % (more[0]["robots"], more[0]["trials"], more[0]["detection_size"]) in md
        else:
            assert "at_other_designs" not in v
    assert (tmp_path / "out" / "report.md").is_file() and (tmp_path / "out" / "gap_0.png").is_file()
    # Where the gap is: the turn rates' per-track part, and the report's table row says so.
    by = doc["datasets"][0]["gap_by_part"]
    assert set(by) == {"turn_rate", "speed", "diffusion"}
    before, after = by["turn_rate"]["track"]
    assert before > 1 and after < 0.2 * before and before == max(v[0] for parts in by.values() for v in parts.values())
    row = next(r for r in (tmp_path / "out" / "report.md").read_text().splitlines() if r.startswith("| turn_rate |"))
    assert f"{before:.2f} -> {after:.2f}" in row


def test_no_hidden_effect_names_nothing(tmp_path):
    _, rep = run(tmp_path, "motion", "")
    assert rep["named_effects"] == [] and not rep["unexplained"]
    # report.md says that no test flagged anything, and which ran, rather than showing empty tables
    md = (tmp_path / "out" / "report.md").read_text()
    sec = rep["datasets"][0]
    assert sec["disagreements"] == [] and sec["steps"] == [] and "turn_rate:between_robots" in sec["tests"]
    assert f"No test flagged a disagreement ({', '.join(sec['tests'])})." in md
    assert "| round | signal |" not in md and "| step | named |" not in md


def test_pair_is_named_in_full(tmp_path):
    truth, rep = run(tmp_path, "motion", "heading_bias,speed_heterogeneity")
    assert sorted(rep["named_effects"]) == ["heading_bias", "speed_heterogeneity"]
    fitted = load_swarm(rep["model"])
    true = np.array([truth["robots"][str(i)]["speed_factor"] for i in fitted.ids])
    assert np.corrcoef(true, fitted.speed_factor)[0, 1] >= 0.95
    # A speed spread of sd 0.12 is not a tracked point off the rotation centre: robots alike in
    # speed would have to be tracked spread * v / rms(omega) to its side, here (from the truth's
    # own speed factors and turn rates) nine times a Kilobot's body radius, and the report says so.
    from kilobot_twin.core.constants import BODY_RADIUS_M, WHEEL_SEPARATION_M
    tp = rep["datasets"][0]["tracked_point"]
    v = tp["speed_m_s"]
    omega = -np.array([truth["robots"][str(i)]["heading_bias"] for i in fitted.ids]) * v / WHEEL_SEPARATION_M
    want = np.std(true, ddof=1) / np.mean(true) * v / np.sqrt(np.mean(omega**2))
    assert want > 5 * BODY_RADIUS_M and 0.5 < tp["offset_m"] / want < 2, (tp, want)
    assert tp["within_body"] is False
    md = (tmp_path / "out" / "report.md").read_text()
    assert "beyond a Kilobot's body (radius 16.5 mm)" in md and "the spread may be the tracker's" not in md


def test_effect_outside_the_library_is_unexplained(tmp_path):
    _, rep = run(tmp_path, "motion", "floor_tilt")
    assert rep["named_effects"] == []
    assert rep["unexplained"] and "speed:heading_dependence" in rep["unexplained_signals"]
    # The report says why: no effect of the library accounts for a speed that depends on heading.
    nn = rep["datasets"][0]["not_named"]
    assert nn["signals"] == rep["unexplained_signals"] and nn["best"] is None and nn["scores"] == {}
    assert set(nn["set_aside"]) == {"heading_bias", "bias_drift", "speed_heterogeneity", "motion_noise"}
    assert "Round 0 named nothing" in (tmp_path / "out" / "report.md").read_text()


def _per_robot_tolerance(ds_dir, component, trials):
    """4 standard errors of each robot's mean summary over its trials, the tolerance of a
    per-robot parameter fitted from that mean. The trial-to-trial sd is pooled over robots (they
    share the noise; one robot's 4 trials give an sd with 3 degrees of freedom, often half the
    true one)."""
    from kilobot_twin.recording import measured
    from kilobot_twin.gap.model import measured_summaries

    _, s = measured_summaries(measured.load(ds_dir))
    x = s[component]
    n = np.isfinite(x).sum(0)
    pooled = np.sqrt(np.nansum((x - np.nanmean(x, axis=0)) ** 2) / (n - 1).sum())
    return 4 * pooled / np.sqrt(n)


def test_recovered_sensor_gain_and_offset_match_the_truth_in_slope_and_intercept(tmp_path):
    """Not only correlated: each robot's fitted gain and offset lie within 4 standard errors of
    the truth (gain in counts per unit V is 1024 x sensor_gain), and the line fitted vs true has
    slope within 10 % of 1."""
    truth, rep = run(tmp_path, "light_sweep", "sensor_gain")
    assert rep["named_effects"] == ["sensor_gain"] and rep["gap_shrink"]["ci95"][0] > 0
    fitted = load_swarm(rep["model"])
    ds = tmp_path / "light_sweep_sensor_gain"
    for trait, comp, scale in (("sensor_gain", "gain", 1024.0), ("sensor_offset", "offset", 1.0)):
        true = np.array([truth["robots"][str(i)][trait] for i in fitted.ids])
        got = fitted.values[trait]
        tol = _per_robot_tolerance(ds, comp, 4) / scale
        assert np.all(np.abs(got - true) <= tol), (trait, got - true, tol)
        slope, intercept = np.polyfit(true, got, 1)
        assert abs(slope - 1) <= 0.1, (trait, slope)
    # The sensor's two noises with 90 % intervals; the noise a reading carries is the per-sample
    # one over the root of the samples a reading averages, as for the levels themselves.
    sec = json.loads((tmp_path / "out" / "report.json").read_text())["datasets"][0]
    ci, nz = sec["nuisance_ci90"], sec["nuisances"]
    assert set(ci) == {"sensor_noise_per_sample_counts", "reading_noise_counts", "sensor_offset_trial_sd_counts"}
    assert np.allclose(ci["reading_noise_counts"], np.asarray(ci["sensor_noise_per_sample_counts"]) / np.sqrt(nz["samples_per_reading"]))


@pytest.mark.parametrize("kind, hidden, trait", [("blink", "clock_drift", "clock_rate")])
def test_sensor_and_clock_effects(tmp_path, kind, hidden, trait):
    truth, rep = run(tmp_path, kind, hidden)
    assert rep["named_effects"] == [hidden]
    fitted = load_swarm(rep["model"])
    true = np.array([truth["robots"][str(i)][trait] for i in fitted.ids])
    assert np.corrcoef(true, fitted.values[trait])[0, 1] >= 0.95
    assert rep["gap_shrink"]["ci95"][0] > 0
    # the clocks' trial-to-trial jitter with its 90 % interval
    sec = json.loads((tmp_path / "out" / "report.json").read_text())["datasets"][0]
    lo, hi = sec["nuisance_ci90"]["clock_trial_sd"]
    assert 0 <= lo <= hi and "clock_trial_sd %.3g (90 %% CI %.3g .. %.3g)" % (sec["nuisances"]["clock_trial_sd"], lo, hi) \
        in (tmp_path / "out" / "report.md").read_text()


@pytest.mark.slow
@pytest.mark.parametrize("hidden", ["heading_bias", "bias_drift", "motion_noise", ""])
def test_named_exactly_over_seeds(tmp_path, hidden):
    """The workflow as shipped (default settings): named exactly in at least 4 of 5 seeds (synth's
    effects are well above the reports' minimum detectable effects on 12 robots x 4 trials; robots
    differing in noise intensity, sigma_omega x exp(N(0, 0.8)), too, since the heading noise is
    read from the sideways wander: before, from 2 s chord headings, it was below)."""
    hits = 0
    for seed in range(5):
        truth, rep = run(tmp_path / str(seed), "motion", hidden, seed=100 + seed, gs=GapSettings(seed=seed))
        want = sorted(filter(None, hidden.split(",")))
        assert rep["datasets"][0]["minimum_detectable"]  # every report says what it can see
        hits += sorted(rep["named_effects"]) == want
    assert hits >= 4


def test_gap_reads_an_imported_bag_like_its_dataset(tmp_path):
    from kilobot_twin.gap.bags import dataset_from_bag
    from kilobot_twin.recording.importer import import_dataset
    from kilobot_twin.recording import measured

    ds_dir = tmp_path / "ds"
    synth("motion", "heading_bias", ds_dir, seed=5, robots=6, trials=3)
    import_dataset(str(ds_dir), str(tmp_path / "bag"))
    ds, back = measured.load(ds_dir), dataset_from_bag(tmp_path / "bag")
    assert back.kind == "motion" and back.trials == 3 and sorted(back.tracks) == sorted(ds.tracks)
    _, x0 = ds.grid("x_m")
    _, x1 = back.grid("x_m")
    both = np.isfinite(x0) & np.isfinite(x1)
    np.testing.assert_allclose(x1[both], x0[both], atol=1e-6)
    # The viewer's reader puts samples on its time grid; jittered neighbours may share a slot.
    assert both.sum() >= 0.99 * np.isfinite(x0).sum()
    rep = run_gap([str(tmp_path / "bag")], tmp_path / "out", gs=FAST, log=lambda *a: None)
    assert rep["named_effects"] == ["heading_bias"]


def test_gap_refuses_a_single_run_bag_with_one_line(tmp_path):
    from kilobot_twin.errors import ConfigError
    from kilobot_twin.gap.bags import dataset_from_bag
    from kilobot_twin.recording.twin_bag import TwinBagWriter

    w = TwinBagWriter(str(tmp_path / "b"))
    w.close()
    with pytest.raises(ConfigError, match="trial structure"):
        dataset_from_bag(tmp_path / "b")


def test_a_users_own_effect_is_scored_and_named_without_touching_the_workflow(tmp_path):
    """A per-robot turn written here (not the library's heading_bias, which is left out of the
    settings' library) is found on heading-bias data: the workflow takes its candidates from
    the settings."""
    from dataclasses import replace

    from kilobot_twin.gap import effects as E

    class MyTurn(E.Effect):
        name, kind = "my_turn", "motion"
        predicts = {"turn_rate": "mean"}

        def fit(self, model, meas, ref, resim=None):
            v = 0.06 * 48 / 255 * model.swarm.speed_factor
            b = -np.nanmean(meas["turn_rate"], axis=0) * 0.025 / v  # b = -omega L / v
            return model.with_traits(heading_bias=b, bias_trial_sd=np.zeros(len(b)))

    with pytest.raises(TypeError):
        E.Effect()  # abstract: an effect must say how it is fitted
    lib = {k: v for k, v in E.LIBRARY.items() if k not in ("heading_bias", "bias_drift")}
    lib["my_turn"] = MyTurn()
    truth, rep = run(tmp_path, "motion", "heading_bias", gs=replace(FAST, library=lib))
    assert rep["named_effects"] == ["my_turn"]
    assert "heading_bias" not in rep["steps"][0]["scores"]
    # It gives no at_size: the report lists it, with why it states no size for it.
    mine = rep["datasets"][0]["minimum_detectable"]["my_turn"]
    assert mine["size"] is None and "no at_size" in mine["why_none"]
    assert "- my_turn: none stated: the effect gives no at_size" in (tmp_path / "out" / "report.md").read_text()


def test_a_report_lists_every_effect_and_why_it_states_no_size_for_some(tmp_path):
    """What a report cannot see includes what it gives no size for: 6 robots x 2 trials with no
    heading noise (a nuisance that is zero in the data). A trend over trials needs 3 of them, and
    robots that differ in noise differ by factors of an intensity the base fits at 0: every
    motion effect of the library is listed, those two with the reason, in the JSON and in
    report.md (before, they were left out, and "nothing named" read as nothing to see). The
    heading bias and speed are detected at a size, but the size named is not emulated on 2
    trials (each held out against the other alone): before, the report said they would be named
    at no size up to 20x the detection size ("at most 0 % power"), while on 6 robots x 2 trials
    the workflow named a heading bias in 3 of 3 datasets."""
    from kilobot_twin.gap import effects as E

    ds = tmp_path / "ds"
    synth("motion", "none", ds, robots=6, trials=2, seed=3, nuisance={"sigma_omega": 0.0})
    rep = run_gap([str(ds)], tmp_path / "out", gs=FAST, log=lambda *a: None)
    sec = rep["datasets"][0]
    mde = sec["minimum_detectable"]
    assert set(mde) == {n for n, e in E.LIBRARY.items() if e.kind == "motion"}
    assert mde["bias_drift"]["size"] is None and mde["bias_drift"]["detection_size"] is None
    assert mde["bias_drift"]["why_none"] == "a trend over trials needs 3 trials or more; these data have 2"
    assert sec["nuisances"]["sigma_omega_rad_sqrt_s"] == 0.0
    assert mde["motion_noise"]["size"] is None and "fits no heading noise" in mde["motion_noise"]["why_none"]
    md = (tmp_path / "out" / "report.md").read_text()
    for n in ("bias_drift", "motion_noise"):
        assert f"- {n}: none stated: {mde[n]['why_none']}" in md
    for n in ("heading_bias", "speed_heterogeneity"):
        v = mde[n]
        assert v["size"] is None and v["detection_size"] > 0 and "best_power" not in v
        assert v["why_none"].startswith("with 2 trials each is held out against one other")
        assert f"- {n}: none stated: {v['why_none']}; detected {v['detection_size']:.3g} ({v['unit']})" in md


@pytest.mark.parametrize("hidden, named", [("", []), ("sensor_gain", ["sensor_gain"])])
def test_a_sensor_without_noise_breaks_neither_the_tests_nor_the_likelihood(tmp_path, hidden, named):
    """Readings without any noise (a nuisance that is zero in the data): nothing named on null
    data, the gain named when robots differ."""
    ds = tmp_path / "ds"
    synth("light_sweep", hidden, ds, seed=1000, nuisance={"sensor_noise": 0.0})
    rep = run_gap([str(ds)], tmp_path / "out", gs=FAST, log=lambda *a: None)
    assert rep["named_effects"] == named and not rep["unexplained"]


def test_blink_frame_lead_follows_the_recording(tmp_path):
    """Toggles are timed to frames. The independent world of seed 1019 starts its robots up to
    2.9 s late, at any point within a frame (a free-running camera): the base fits a random lead
    and names clock_drift (the twin with clocks aligned to frame 0 left it unexplained, eval
    2026-11-23). The twin's own generator starts every clock at frame 0: without clock jitter
    (which would outweigh the timing error, and either choice is then right) the base sees it
    aligned, and names clock_drift too."""

    iw = benchmark.load("indep_world")
    indep = tmp_path / "indep"
    iw.generate("blink", "clock_drift", indep, seed=1019)
    rep = run_gap([str(indep)], tmp_path / "out_i", gs=GapSettings(seed=1019), log=lambda *a: None)
    assert rep["datasets"][0]["nuisances"]["frame_lead"] == "random"
    assert rep["named_effects"] == ["clock_drift"] and not rep["unexplained"]
    ds = tmp_path / "synth"
    synth("blink", "clock_drift", ds, seed=5, nuisance={"clock_trial_sd": 0.0})
    rep = run_gap([str(ds)], tmp_path / "out_s", gs=FAST, log=lambda *a: None)
    assert rep["datasets"][0]["nuisances"]["frame_lead"] == "aligned"
    assert rep["named_effects"] == ["clock_drift"]


@pytest.mark.parametrize("hidden, named", [("clock_drift", ["clock_drift"]), ("", [])])
def test_blink_in_a_world_without_noise(tmp_path, hidden, named):
    """Clocks started with the frames and never jittering (synth's randomised seed 3012 draws no
    clock jitter): every simulated replicate blinks alike and the null's statistics have no
    spread. A right clock_drift is named (it had resolved nothing: its pooled rates' F was
    0.005 off a null of spread 0), and the null dataset states a size it can detect (none had been
    stated): robots without noise are told apart far below the earlier issue's 0.015."""
    ds = tmp_path / "ds"
    synth("blink", hidden, ds, seed=3012, nuisance={"clock_trial_sd": 0.0})
    rep = run_gap([str(ds)], tmp_path / "out", gs=GapSettings(seed=3012), log=lambda *a: None)
    sec = rep["datasets"][0]
    assert sec["nuisances"]["frame_lead"] == "aligned"
    assert rep["named_effects"] == named and not rep["unexplained"]
    assert 0 < sec["minimum_detectable"]["clock_drift"]["size"] < 1e-3


@pytest.mark.parametrize("kind, hidden, trait, program", [
    ("blink", "clock_drift", "clock_rate", {"half_period_ticks": 14, "tick_hz": 26.0}),
    ("motion", "speed_heterogeneity", "speed_factor", {"commanded_speed_m_s": 0.017}),
])
def test_the_dataset_s_program_sets_what_the_twin_simulates(tmp_path, kind, hidden, trait, program):
    """Robots programmed otherwise than the twin's defaults (another LED program, another
    commanded speed; measured-v1 states them in meta.yaml), in the independent world: the
    recovered clock rates and speed factors are relative to that program, as the truth is, not
    to the twin's 30 ticks at 31 Hz or its 1.13 cm/s (which would scale them by 1.7 and 1.5)."""

    iw = benchmark.load("indep_world")
    truth = iw.generate(kind, hidden, tmp_path / "d", seed=3, nuisance_scale=1.0, fixed_shape=True, program=program)
    rep = run_gap([str(tmp_path / "d")], tmp_path / "out", gs=FAST, log=lambda *a: None)
    assert rep["named_effects"] == [hidden]
    fitted = load_swarm(rep["model"])
    true = np.array([truth["robots"][str(i)][trait] for i in fitted.ids])
    got = fitted.values[trait]
    # Slope of fitted on true within 10 % of 1, and the fitted mean within 1 % of the true mean
    # (the population level is fitted from all robots' trials; the scales the twin's defaults
    # would give are 50-70 % off).
    assert abs(np.polyfit(true, got, 1)[0] - 1) <= 0.1, np.polyfit(true, got, 1)
    assert abs(got.mean() / true.mean() - 1) <= 0.01, (got.mean(), true.mean())


@pytest.mark.parametrize("predicts, named", [("pop", True), ("mean", False)])
def test_a_name_must_resolve_a_disagreement_of_its_own_kind(tmp_path, predicts, named):
    """A user's base model whose heading noise is 3x the data's: the diffusion's level is flagged.
    An effect that refits the population's heading noise removes that flag. Declared as fitting a
    population level ("pop") it accounts for a level and is named; declared as per-robot means
    ("mean") the same fit has explained no disagreement of its kind (robots that differ), so it is
    not named and the level stays unexplained (as on a tilted floor, where robots differing in
    noise once took the credit for the diffusion level the tilt moved)."""
    from dataclasses import replace

    import yaml

    from kilobot_twin.gap import effects as E

    class NoiseLevel(E.Effect):
        name, kind = "noise_level", "motion"

        def fit(self, model, meas, ref, resim=None):
            ratio = np.nanmean(meas["diffusion"]) / np.nanmean(ref["diffusion"])
            return model.with_traits(sigma_omega=model.swarm.sigma_omega * np.sqrt(max(ratio, 0.0)))

    effect = NoiseLevel()
    effect.predicts = {"diffusion": predicts}
    ds = tmp_path / "ds"
    synth("motion", "", ds, seed=7)
    ids = yaml.safe_load((ds / "meta.yaml").read_text())["robots"]
    base = {"format": "kilobot-twin/traits-v1",
            "robots": {int(i): {"sigma_omega": 0.03, "sigma_v": 0.0005} for i in ids}}
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(base))
    rep = run_gap([str(ds)], tmp_path / "out", model_path=str(tmp_path / "base.yaml"),
                  gs=replace(FAST, library={"noise_level": effect}), log=lambda *a: None)
    assert "diffusion:level" in [d["signal"] for d in rep["disagreements"] if d["round"] == 0]
    assert (rep["named_effects"] == ["noise_level"]) == named
    assert ("diffusion:level" in rep["unexplained_signals"]) != named


@pytest.mark.parametrize("hidden, named", [("", []), ("heading_bias", ["heading_bias"]),
                                           ("speed_heterogeneity", ["speed_heterogeneity"])])
def test_motion_without_speed_or_tracking_noise(tmp_path, hidden, named):
    """Tracks with no speed noise and no tracking noise (nuisances that are zero in the data; the
    randomised synth evaluation's seed 1005, 2026-11-23): each robot's speed is the same in every
    trial to a part in 10^7. Robots that turn have a shorter chord per second, so per-robot
    speeds fit far better than the base's, yet nothing about speed was flagged: that candidate
    must not stand in the way of the heading bias that was (it did, and the heading bias ended
    unexplained). With speed factors hidden, the F ratio over a within-robot scatter of numerical
    residue must still be calibrated, so that naming them resolves the flag."""
    from kilobot_twin.gap.observe import Observation

    ds = tmp_path / "ds"
    synth("motion", hidden, ds, seed=1005, obs=Observation(tracking_noise_m=0.0),
          nuisance={"sigma_v": 0.0, "sigma_omega": 2.8})
    rep = run_gap([str(ds)], tmp_path / "out", gs=FAST, log=lambda *a: None)
    assert rep["named_effects"] == named and not rep["unexplained"]
    if hidden == "heading_bias":
        assert "speed_heterogeneity" in rep["steps"][0]["set_aside"]
    assert rep["datasets"][0]["not_named"] is None


def test_one_slipped_trial_does_not_outweigh_the_swarm(tmp_path):
    """Speed factors (sd 0.12) under 8 mm tracking noise on 2.6 cm chords and 3.2x nominal
    heading noise: the randomised synth evaluation's seed 1014 (2026-11-23), settings and seed
    as there. One robot's heading slips in one trial (its turn rate -0.17 rad/s against a
    spread of 0.02); with a Gaussian held-out density its z^2 of 1,500 set the naming bounds to
    -663 .. 263, and speed factors 2.6x their detectable size ended unexplained."""
    from kilobot_twin.gap.observe import Observation

    ds = tmp_path / "ds"
    synth("motion", "speed_heterogeneity", ds, seed=1014, obs=Observation(tracking_noise_m=0.0079),
          nuisance={"sigma_omega": 3.23, "sigma_v": 2.31, "sensor_noise": 1.90, "clock_trial_sd": 3.35})
    rep = run_gap([str(ds)], tmp_path / "out", gs=GapSettings(seed=1014), log=lambda *a: None)
    assert rep["named_effects"] == ["speed_heterogeneity"] and not rep["unexplained"]
    assert rep["gap_shrink"]["value"] >= 0.8 and rep["gap_shrink"]["ci95"][0] > 0


def test_synth_gives_its_robots_coloured_heading_noise(tmp_path):
    """``heading_noise_tau_s`` reaches every robot of the written world (its truth) and its tracks:
    the same seed with white noise drives the same robots along other paths."""
    white = synth("motion", "none", tmp_path / "w", robots=4, trials=2, seed=9, duration_s=20.0)
    col = synth("motion", "none", tmp_path / "c", robots=4, trials=2, seed=9, duration_s=20.0, heading_noise_tau_s=2.0)
    assert all(r["heading_noise_tau"] == 2.0 for r in col["robots"].values())
    assert all(r["heading_noise_tau"] == 0.0 for r in white["robots"].values())
    assert (tmp_path / "w" / "observations.csv").read_text() != (tmp_path / "c" / "observations.csv").read_text()


@pytest.mark.parametrize("kind, hidden, traits", [
    ("motion", "heading_bias,speed_heterogeneity,bias_drift,motion_noise",
     {"heading_bias": 0.0, "speed_factor": 1.0, "bias_drift": 0.0, "sigma_omega": None}),
    ("light_sweep", "sensor_gain", {"sensor_gain": 2.25, "sensor_offset": 5.0}),
    ("blink", "clock_drift", {"clock_rate": 1.0}),
])
def test_synths_effect_scale_multiplies_each_effects_spread(tmp_path, kind, hidden, traits):
    """``effect_scale=s`` draws the same robots with every hidden effect's deviation from its
    centre (``HIDDEN``: the normals' means, the gains' middle; sigma_omega on a log scale about the
    nominal) x s, and leaves the other traits as they were; at 1 it writes what no scale writes."""
    kw = dict(robots=8, trials=2, seed=5, duration_s=10.0)
    one = synth(kind, hidden, tmp_path / "one", **kw)
    synth(kind, hidden, tmp_path / "default", effect_scale=1.0, **kw)
    assert (tmp_path / "one" / "observations.csv").read_bytes() == (tmp_path / "default" / "observations.csv").read_bytes()
    half = synth(kind, hidden, tmp_path / "half", effect_scale=0.5, **kw)
    assert half["effect_scale"] == 0.5 and one["effect_scale"] == 1.0
    nominal = 0.01  # synth's nominal sigma_omega
    for i, r1 in one["robots"].items():
        rh = half["robots"][i]
        for k, centre in traits.items():
            if k == "sigma_omega":
                assert np.log(rh[k] / nominal) == pytest.approx(0.5 * np.log(r1[k] / nominal), abs=1e-12)
            elif k != "speed_factor" or 0.75 < r1[k] < 1.25:  # unclipped
                assert rh[k] - centre == pytest.approx(0.5 * (r1[k] - centre), abs=1e-12)
        assert {k: v for k, v in rh.items() if k not in traits} == {k: v for k, v in r1.items() if k not in traits}
    assert (tmp_path / "one" / "observations.csv").read_bytes() != (tmp_path / "half" / "observations.csv").read_bytes()


def test_synths_effect_scale_multiplies_the_floors_slope(tmp_path):
    """A tilted floor is no spread over robots: ``effect_scale`` multiplies its slope (0.15 at 1),
    in the same direction, and the robots stay as they were."""
    kw = dict(robots=6, trials=2, seed=5, duration_s=10.0)
    one = synth("motion", "floor_tilt", tmp_path / "one", **kw)
    half = synth("motion", "floor_tilt", tmp_path / "half", effect_scale=0.5, **kw)
    assert one["floor_tilt"]["amplitude"] == 0.15 and half["floor_tilt"]["amplitude"] == pytest.approx(0.075, abs=1e-15)
    assert half["floor_tilt"]["direction_rad"] == one["floor_tilt"]["direction_rad"] and half["robots"] == one["robots"]
    assert (tmp_path / "one" / "observations.csv").read_bytes() != (tmp_path / "half" / "observations.csv").read_bytes()


def test_synths_tracker_can_repeat_its_errors_from_frame_to_frame(tmp_path):
    """``Observation(tracking_correlated_m=, tracking_tau_s=)``: the same seed writes the same
    frames at the same times, and the positions differ by Ornstein-Uhlenbeck noise of that sd whose
    neighbouring frames correlate as exp(-dt / tau) (theory; ~40,000 samples per axis give a
    standard error near 0.005 for both)."""
    from kilobot_twin.gap.observe import Observation
    from kilobot_twin.recording import measured

    kw = dict(robots=10, trials=2, seed=9, duration_s=200.0)
    synth("motion", "none", tmp_path / "a", **kw)
    synth("motion", "none", tmp_path / "b", obs=Observation(tracking_correlated_m=0.003, tracking_tau_s=0.3), **kw)
    a, b = measured.load(tmp_path / "a"), measured.load(tmp_path / "b")
    assert set(a.tracks) == set(b.tracks)
    d, r = [], []
    for key, ta in a.tracks.items():
        tb = b.tracks[key]
        np.testing.assert_array_equal(ta.t_s, tb.t_s)
        for c in ("x_m", "y_m"):
            e = tb.values[c] - ta.values[c]
            step = np.diff(np.round(ta.t_s / a.dt_s)) == 1  # neighbouring frames (drops leave gaps)
            d.append(e)
            r.append(np.column_stack([e[:-1][step], e[1:][step]]))
    d, r = np.concatenate(d), np.concatenate(r)
    assert abs(d.std() / 0.003 - 1) < 0.03
    assert abs(np.mean(r[:, 0] * r[:, 1]) / np.mean(r * r) - np.exp(-a.dt_s / 0.3)) < 0.02


def test_a_tracker_whose_errors_persist_over_frames_is_not_read_as_heading_noise(tmp_path):
    """A null motion world whose tracker smooths: 6 mm of error correlated over 0.5 s added to
    every track, test-side (Ornstein-Uhlenbeck stepped exactly). The frame-to-frame statistic
    sees a third of that noise; over the diffusion summary's lags the rest bends the tracks as
    heading noise would. Read as such, the base fitted twice the robots' heading noise (0.022
    against 0.010 rad/sqrt(s)), and on the independent world's slow robots under 5 mm of tracking
    noise the turn rates' bound then left ``diffusion:level`` unexplained in 4 of 6 null datasets.
    Fitted and simulated, the tracker's part is measured (0.3 of its tolerance is 2x the scatter
    seen over seeds) and the heading noise comes out within 25 % of the truth (the base's
    estimate scatters by about 10 % on 12 robots x 4 trials); nothing is named or unexplained."""
    from kilobot_twin.recording import measured

    from .unicycle import ou_noise

    ds = tmp_path / "ds"
    synth("motion", "none", ds, seed=7)
    truth = json.loads((ds / "truth.json").read_text())
    sigma = np.mean([r["sigma_omega"] for r in truth["robots"].values()])
    data = measured.load(ds)
    rng = np.random.default_rng(7)
    for tr in data.tracks.values():
        for c in ("x_m", "y_m"):
            tr.values[c] = tr.values[c] + ou_noise(rng, 1, len(tr), data.dt_s, 0.006, 0.5)[0]
    measured.write(ds, {k: v for k, v in data.meta.items() if k != "format"}, data.tracks)
    rep = run_gap([str(ds)], tmp_path / "out", gs=FAST, log=lambda *a: None)
    assert rep["named_effects"] == [] and not rep["unexplained"], rep["unexplained_signals"]
    nz = rep["datasets"][0]["nuisances"]
    assert abs(nz["sigma_omega_rad_sqrt_s"] / sigma - 1) < 0.25, (nz, sigma)
    assert abs(nz.get("tracking_tau_s", 0) / 0.5 - 1) < 0.3 and abs(nz.get("tracking_correlated_m", 0) / 0.006 - 1) < 0.15, nz


@pytest.mark.parametrize("world, kind, seed, comps", [
    ("indep_world", "motion", 3000, ("speed",)),  # 5 mm of tracking noise at 10 Hz
    ("indep_world", "blink", 3004, ("toggle_rate",)),  # 14 robots x 8 trials
    ("stress_world", "light_sweep", 3008, ("gain", "offset")),  # wandering ambient light
])
def test_the_base_reproduces_the_level_of_null_data_from_other_worlds(tmp_path, world, kind, seed, comps):
    """Null data of the two other worlds (their own integrators and noise; the evaluation's
    datasets of these seeds), the base model fitted on all but one trial predicting the held-out
    trial's level (the mean over robots): each level z (:func:`workflow._level_z`) is N(0, 1)
    for a model that reproduces the data, so their mean over the K trials is within
    4 / sqrt(K). Levels matched once against the start model's simulation, before the noise was
    fitted, missed by 2.4 % (speed: mean z +11), 0.05 % (toggle rate: -2.1) and through the
    clipped reading noise (gain: +6; offset)."""
    from kilobot_twin.gap import effects as E
    from kilobot_twin.gap import workflow as W

    benchmark.load(world).generate(kind, "", tmp_path / "d", seed=seed, program="random")
    cond, meas = W.measured_summaries(W._load_data(str(tmp_path / "d")))
    meas = E.Summaries(meas, np.arange(cond.trials))
    start = E.nominal_model(kind, cond.robot_ids, cond.forward_speed_m_s)
    fitter = W._Fitter(cond, meas, start, W.GapSettings(seed=seed), True)
    pred = W._heldout(fitter, (), kind)
    for c in comps:
        z = W._level_z(meas[c], pred[c]["mean"], pred[c]["sd_level"])
        assert abs(np.mean(z)) <= 4 / np.sqrt(cond.trials), (c, z)


def test_robots_whose_noise_differs_by_factors_are_named_and_kept_apart(tmp_path):
    """The independent world, 12 robots x 4 trials, heading-noise intensities a factor e^1.7
    apart per sd (sd of ln sigma_omega 1.7 over the robots; its effect scale 2.5): pooled on the
    summary's own scale, towards the robots' arithmetic mean, the quiet robots came out several
    times too noisy, the between-robot flag stayed after the fit and the noise ended
    `unexplained`; pooled on a log scale (effects.pool_intensities) it is named, the gap shrinks,
    and the robots' estimates follow their truth on the log scale."""

    iw = benchmark.load("indep_world")
    truth = iw.generate("motion", "motion_noise", tmp_path / "d", seed=2, effect_scale=2.5, fixed_shape=True)
    rep = run_gap([str(tmp_path / "d")], tmp_path / "out", gs=GapSettings(seed=2), log=lambda *a: None)
    assert rep["named_effects"] == ["motion_noise"] and not rep["unexplained"]
    sec = rep["datasets"][0]
    assert sec["gap_shrink"]["value"] >= 0.8 and sec["gap_shrink"]["ci95"][0] > 0
    true = np.log([truth["robots"][str(r)]["sigma_omega"] for r in sec["robots"]])
    got = np.log(sec["estimates"]["sigma_omega"]["individual"])
    # On the log scale the estimates spread as the robots do: slope of fitted on true ln sigma
    # 0.79, r 0.92 here (linear pooling: slope 0.20, r 0.76, the quiet robots lifted towards the
    # noisy ones). 12 robots give the slope an se of about 0.1: within 0.35 of 1 is 3 se.
    slope = np.polyfit(true, got, 1)[0]
    assert abs(slope - 1) < 0.35 and np.corrcoef(true, got)[0, 1] > 0.8


def test_a_clock_drift_with_robots_missing_from_trials_is_named(tmp_path):
    """The independent world's blink 3058 as `eval_gap.py --random-program` draws it: 7 robots x
    3 trials at 5 Hz, clock rates 2 % apart, robot 6 absent from trial 1 and robots 1 and 2 from
    trial 2. Robots compared on values centred by the trials' plain means (which move with who
    was in a trial) had their noise taken 11-72x too large and the drift, 2.1x its stated
    minimum detectable size, unnamed (`unexplained`); with the two-way fit it is named and
    the gap shrinks."""

    iw = benchmark.load("indep_world")
    ds = tmp_path / "blink"
    truth = iw.generate("blink", "clock_drift", ds, seed=3058, program="random")
    assert [tuple(m) for m in truth["shape"]["missing"]] == [(2, 1), (2, 2), (1, 6)]
    rep = run_gap([str(ds)], tmp_path / "out", gs=GapSettings(seed=3058), log=lambda *a: None)
    assert rep["named_effects"] == ["clock_drift"] and not rep["unexplained"]
    assert rep["gap_shrink"]["value"] >= 0.8 and rep["gap_shrink"]["ci95"][0] > 0


def test_data_too_short_to_summarise_is_refused_before_any_folder_is_made(tmp_path):
    """Tracks of one sample each give no turn rate: one line naming the summary, and no report
    folder, also when the workflow is called from Python (the command line's own clean-up aside)."""
    from kilobot_twin.errors import ConfigError

    ds = tmp_path / "short"
    synth("motion", "none", ds, robots=2, trials=2, seed=1, duration_s=10.0)
    (ds / "observations.csv").write_text("trial,robot_id,t_s,x_m,y_m\n0,0,0.0,0,0\n1,0,0.0,0,0\n")
    with pytest.raises(ConfigError, match="turn_rate"):
        run_gap([str(ds)], tmp_path / "out", gs=GapSettings(seed=1), log=lambda *a: None)
    assert not (tmp_path / "out").exists()
