"""A user's own effect through the command line (``kilobot-twin gap --effects FILE.py``): the
example of the docs, a tilted floor, on a world the twin was not built from; and what a file that
is not a working effect gets (one line, exit 2, nothing written)."""

import functools
import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from kilobot_twin.cli import main
from . import benchmark

EXAMPLE = Path(__file__).resolve().parents[2] / "docs" / "examples" / "floor_tilt.py"
iw = benchmark.load("indep_world")


@pytest.fixture(scope="module")
def tilted(tmp_path_factory):
    """The independent world on a tilted floor (seed 1: 32 robots x 4 trials), and its truth."""
    ds = tmp_path_factory.mktemp("tilted") / "ds"
    truth = iw.generate("motion", "floor_tilt", ds, seed=1)
    return ds, truth


def _tilt_and_se(ds):
    """The tilt by least squares in this test (another implementation than the example's): each
    track's mean speed over its robot's mean, against (cos, sin) of its mean heading (robots'
    means taken out), with the standard errors of the two coefficients."""
    import csv

    rows = list(csv.DictReader(open(ds / "observations.csv")))
    tracks = {}
    for r in rows:
        tracks.setdefault((int(r["trial"]), int(r["robot_id"])), []).append((float(r["t_s"]), float(r["x_m"]), float(r["y_m"])))
    speed, head, robot = [], [], []
    for (k, i), obs in tracks.items():
        t, x, y = np.array(sorted(obs)).T
        dx, dy = x[-1] - x[0], y[-1] - y[0]
        speed.append(np.hypot(dx, dy) / (t[-1] - t[0]))
        head.append(np.arctan2(dy, dx))
        robot.append(i)
    speed, head, robot = map(np.asarray, (speed, head, robot))
    cols = [speed / np.array([speed[robot == i].mean() for i in robot]), np.cos(head), np.sin(head)]
    y, c, s = (a - np.array([a[robot == i].mean() for i in robot]) for a in cols)
    X = np.column_stack([c, s])
    coef, res, *_ = np.linalg.lstsq(X, y, rcond=None)
    dof = len(y) - 2 - len(set(robot))
    cov = res[0] / dof * np.linalg.inv(X.T @ X)
    return coef, np.sqrt(np.diag(cov))


def test_a_users_tilted_floor_is_named_and_the_gap_shrinks(tilted, tmp_path):
    """The library has no floor tilt; the example file adds one. Named alone, nothing left
    unexplained, the gap removed clearly above 0 and the shrink >= 80 % (the issue's target), and
    the fitted floor is the world's: amplitude and direction within 4 standard errors of a
    regression of the data's own end-to-end speeds (the twin's tilt is the same law, speed x
    (1 + A cos(heading - phi)); the world's is relative to the population's speed)."""
    ds, truth = tilted
    out = tmp_path / "out"
    assert main(["gap", str(ds), "--out", str(out), "--effects", str(EXAMPLE), "--quiet"]) == 0
    rep = json.loads((out / "report.json").read_text())
    sec = rep["datasets"][0]
    assert rep["named_effects"] == ["floor_tilt"] and not rep["unexplained"]
    assert sec["gap_shrink"]["value"] >= 0.8 and sec["gap_shrink"]["removed_ci95"][0] > 0
    true_a, true_phi = truth["floor_tilt"]["amplitude"], truth["floor_tilt"]["downhill_rad"]
    (a, b), se = _tilt_and_se(ds)
    assert np.hypot(a, b) == pytest.approx(true_a, abs=4 * se.max())  # the regression itself reads the world
    fit_a, fit_phi = sec["scenario"]["floor_tilt"], sec["scenario"]["floor_tilt_direction_rad"]
    assert abs(fit_a - true_a) < 4 * se.max(), (fit_a, true_a, se)
    assert abs(np.angle(np.exp(1j * (fit_phi - true_phi)))) < 4 * se.max() / true_a, (fit_phi, true_phi)
    md = (out / "report.md").read_text()
    assert "`floor_tilt`" in md and f"floor_tilt (`{EXAMPLE}`)" in md  # the fitted floor, and where the effect came from
    assert rep["library"]["floor_tilt"] == {"class": "FloorTilt", "source": str(EXAMPLE)}
    assert rep["library"]["heading_bias"]["source"] == "kilobot_twin"


@pytest.fixture(scope="module")
def tilted_small(tmp_path_factory):
    """The independent world's fixed shape (12 robots x 4 trials at 10 Hz) on the tilted floor of
    seed 1: enough to flag the speed's heading dependence, so that a user's effect is fitted."""
    ds = tmp_path_factory.mktemp("tilted_small") / "ds"
    iw.generate("motion", "floor_tilt", ds, seed=1, fixed_shape=True)
    return ds


@pytest.fixture(scope="module")
def level(tmp_path_factory):
    """The same world on a level floor (seed 1)."""
    ds = tmp_path_factory.mktemp("level") / "ds"
    iw.generate("motion", "", ds, seed=1)
    return ds


def test_a_users_effect_is_not_scored_on_null_data_and_its_detectable_size_is_stated(level, tmp_path):
    """The same world without a tilt: nothing named, and the tilt not even scored (no flagged
    signal is one it explains). The example gives ``at_size``, so the report states the smallest
    tilt these data would flag (what that size is worth: the next test)."""
    out = tmp_path / "out"
    assert main(["gap", str(level), "--out", str(out), "--effects", str(EXAMPLE), "--quiet"]) == 0
    rep = json.loads((out / "report.json").read_text())
    assert rep["named_effects"] == [] and rep["datasets"][0]["scenario"] == {}
    assert all("floor_tilt" not in st.get("scores", {}) for st in rep["steps"])
    mde = rep["datasets"][0]["minimum_detectable"]["floor_tilt"]
    assert mde["by"] == "simulation" and mde["size"] is None and 0.005 < mde["detection_size"] < 0.5
    shares = [w for _, w in mde["power_by_size"]]
    assert shares[0] < 0.8 <= shares[-1]
    assert "- floor_tilt (yours): detected %.3g (floor slope A" % mde["detection_size"] in (out / "report.md").read_text()


@functools.lru_cache(maxsize=None)
def _example_and_base(level):
    """The example module, and the level dataset's conditions, summaries and fitted base, as the
    workflow's round 0 has them. Fitted once per test process (seconds; nothing here changes them)."""
    from kilobot_twin.gap import effects as E
    from kilobot_twin.gap import workflow as W
    from kilobot_twin.gap.model import measured_summaries
    from kilobot_twin.recording import measured

    spec = importlib.util.spec_from_file_location("floor_tilt_example", EXAMPLE)
    ex = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(ex)
    cond, meas = measured_summaries(measured.load(level))
    meas = E.Summaries(meas, np.arange(cond.trials))
    base = W._Fitter(cond, meas, E.nominal_model("motion", cond.robot_ids, cond.forward_speed_m_s), W.GapSettings(),
                     True).fit((), list(range(cond.trials)))
    return ex, cond, meas, base


@functools.lru_cache(maxsize=None)
def _simulated(level, m, seed):
    """The level dataset's base simulated m times (the pool of 960 takes 7 s; shared by the cases below)."""
    from kilobot_twin.gap.model import simulate

    _, cond, _, base = _example_and_base(level)
    sims = simulate(cond, base, m, seed)
    for v in sims.values():  # shared between cases: a function that wrote into them would raise
        v.setflags(write=False)
    return sims


@pytest.mark.parametrize("m, lowest", [pytest.param(120, 0.005, marks=pytest.mark.slow), (12, 0.005), (120, 0.05)])
def test_the_tilt_stated_is_where_the_non_central_f_test_has_80_percent_power(level, m, lowest, monkeypatch):
    """``simulated_detection`` against theory. The statistic is the log F of a regression of each
    track's relative speed on (cos, sin) of its heading, robots' means taken out; a floor of
    slope A in direction phi makes it non-central F(2, dof) with lambda = A^2 u' M u / sigma^2
    (M: the design's cross-products, u = (cos phi, sin phi), sigma^2: a track's residual
    variance). Computed here from the data's headings and from the null the function is handed
    (its residual variance), and from nulls of as many replicates drawn from the pool of the
    model's replicates the function is handed (the mean and sd of their F's normal scores, the
    standard normal quantile of F(2, dof)'s upper tail by scipy, set the threshold: mean + z sd at
    the family's level, as the workflow's calibrated p does), the power averaged over those nulls
    and over directions (the example draws the direction), the slope where it is 80 %.
    The function's size must lie within 4 Monte Carlo errors of it: the share flagged at 80 % has
    sd sqrt(0.16 / 100), which the theory's power curve turns into an error of the size. With a
    null of 12 replicates (the workflow simulates 120) the threshold scatters so much from null to
    null that the size read at the one null's threshold alone lies more than 4 of those errors
    away, so the test tells the two apart there (with 400 replicates per size). With a ``size_range`` whose smallest size
    (0.05) is flagged already, the search goes on below it (halving) and finds the same; with one
    (0.2) too high for the steps allowed (one, here), the size is the smallest tried, marked
    ``at_most``. The null of 120 searched from 0.005 is slow (20 s); by default the null of 120
    is checked against the same theory when searched from 0.05, after halving."""
    from scipy import optimize, stats

    from kilobot_twin.gap import workflow as W

    ex, cond, meas, base = _example_and_base(level)
    gs = W.GapSettings()
    null = {k: v[:m] for k, v in _simulated(level, gs.m_null, 11).items()}
    pool = _simulated(level, 960, 12)
    reps = W.POWER_REPS if m > 20 else 4 * W.POWER_REPS  # a finer reading where the two thresholds are compared
    tilt = type("Tilt", (ex.FloorTilt,), {"size_range": (lowest, 0.5)})()
    found = W.simulated_detection("motion", cond, base, null, gs.alpha, tilt, seed=5, reps=reps, pool=pool)
    got = found["detection_size"]
    assert not found["at_most"] and (lowest == 0.005 or found["power_by_size"][0][0] < lowest)

    def regression(v, h):  # (..., K, N) -> log F, residual variance, design cross-products
        ok = np.isfinite(v) & np.isfinite(h)
        with np.errstate(all="ignore"):
            cols = [np.where(ok, a, np.nan) for a in (v / np.nanmean(np.where(ok, v, np.nan), -2, keepdims=True),
                                                      np.cos(h), np.sin(h))]
            y, c, s = (np.nan_to_num(a - np.nanmean(a, -2, keepdims=True)) for a in cols)
        X = np.stack([c, s], -1).reshape(*c.shape[:-2], -1, 2)
        y = y.reshape(*y.shape[:-2], -1)
        M = np.einsum("...ti,...tj->...ij", X, X)
        b = np.linalg.solve(M, np.einsum("...ti,...t->...i", X, y)[..., None])[..., 0]
        ss_reg = np.einsum("...i,...i->...", b, np.einsum("...ij,...j->...i", M, b))
        dof = ok.sum((-2, -1)) - (ok.sum(-2) > 0).sum(-1) - 2
        res = ((y**2).sum(-1) - ss_reg) / dof
        return stats.norm.isf(stats.f.sf(ss_reg / 2 / res, 2, dof)), res, M, dof

    def threshold(scores):  # mean + z sd of normal scores -> the F that the data's dof needs
        return stats.f.isf(stats.norm.sf(scores.mean(-1) + z * scores.std(-1, ddof=1)), 2, dof)

    _, _, M, dof = regression(meas["speed"], meas["heading"])
    lf, res, _, _ = regression(null["speed"], null["heading"])
    z = stats.norm.isf(gs.alpha / len(W.statistics("motion", null, cond.trials)))
    lp, _, _, _ = regression(pool["speed"], pool["heading"])
    drawn = lp[np.argsort(np.random.default_rng(0).random((400, lp.size)), axis=1)[:, :m]]  # nulls of m, from the pool
    thr, sigma2 = threshold(drawn), float(np.median(res))
    u = [np.array([np.cos(p), np.sin(p)]) for p in np.linspace(0, np.pi, 24, endpoint=False)]

    def power(A):
        return np.mean([stats.ncf.sf(thr, 2, dof, A**2 * (e @ M @ e) / sigma2).mean() for e in u])

    want = optimize.brentq(lambda A: power(A) - 0.8, 1e-5, 2.0)
    slope = (power(want * 1.02) - power(want / 1.02)) / (2 * np.log(1.02))  # d power / d ln A
    se = np.sqrt(0.16 / reps) / slope
    one = threshold(lf)  # the handed null's threshold alone
    alone = optimize.brentq(lambda A: np.mean([stats.ncf.sf(one, 2, dof, A**2 * (e @ M @ e) / sigma2) for e in u]) - 0.8,
                            1e-5, 2.0)
    print(f"stated {got:.4f}, theory {want:.4f}, ln ratio {np.log(got / want):+.3f}, se {se:.3f}; "
          f"at the one threshold {alone:.4f}")
    assert abs(np.log(got / want)) < 4 * se
    if m < 20:  # here the test tells the two apart: a size read at the one threshold would fail it
        assert abs(np.log(want / alone)) > 4 * se
    if lowest > 0.01:  # a range that starts too high for the steps below it: the smallest size tried, "at most"
        high = type("Tilt", (ex.FloorTilt,), {"size_range": (0.2, 0.5)})()
        monkeypatch.setattr(W, "BELOW_RANGE_STEPS", 1)
        far = W.simulated_detection("motion", cond, base, null, gs.alpha, high, seed=5, reps=reps, pool=pool)
        assert far["at_most"] and far["detection_size"] == far["power_by_size"][0][0] == 0.1


def test_the_size_stated_does_not_depend_on_the_threads_it_is_simulated_on(level):
    """The workflow simulates the sizes' groups and the pool's parts ``GapSettings.threads`` at a
    time; each has its own seed, so one thread and two give the same curve to the last bit (a
    machine's core count must not change a report)."""
    from kilobot_twin.gap import workflow as W
    from kilobot_twin.gap.model import simulate

    ex, cond, _, base = _example_and_base(level)
    gs = W.GapSettings()
    null = simulate(cond, base, 12, 11)
    tilt = type("Tilt", (ex.FloorTilt,), {"size_range": (0.005, 0.1)})()
    one, two = (W.simulated_detection("motion", cond, base, null, gs.alpha, tilt, seed=5, reps=20, sizes=4, threads=t)
                for t in (1, 2))
    assert one == two and len(one["power_by_size"]) >= 2


def test_the_screen_finds_the_size_that_every_replicate_at_every_size_would(level, monkeypatch):
    """Each size is screened on a fifth of its replicates, and the rest are simulated only where
    the screen might come from a share of 80 %. The size is then the one the whole search would
    find: the same replicates (each group's screen and its rest have their own seeds) and, at the
    size below the crossing, all of them. Here an effect whose share steps from about 20 % to
    100 % between two sizes (a weak tilt below 0.03, a strong one above) puts a screened size
    right below the crossing; the search without a screen (``SCREEN_LEVEL`` 0) is the reference."""
    from kilobot_twin.gap import workflow as W
    from kilobot_twin.gap.model import simulate

    ex, cond, _, base = _example_and_base(level)
    gs = W.GapSettings()
    null, pool = simulate(cond, base, 24, 11), simulate(cond, base, 96, 12)

    class Step(ex.FloorTilt):
        def at_size(self, model, size, rng):
            return super().at_size(model, 0.006 if size < 0.03 else 0.05, rng)

    def search():
        return W.simulated_detection("motion", cond, base, null, gs.alpha, Step(), seed=5, pool=pool, threads=2)

    screened = search()
    monkeypatch.setattr(W, "SCREEN_LEVEL", 0.0)
    whole = search()
    sizes = [s for s, _ in whole["power_by_size"]]
    assert sizes == [s for s, _ in screened["power_by_size"]]
    below = max(i for i, s in enumerate(sizes) if s < 0.03)
    assert whole["power_by_size"][below + 1][1] == 1.0 and 0.05 < whole["power_by_size"][below][1] < 0.45
    assert screened["replicates_by_size"][below - 1] == 20 and screened["replicates_by_size"][below] == 100
    assert screened["detection_size"] == whole["detection_size"]
    full = [i for i, n in enumerate(screened["replicates_by_size"]) if n == 100]
    assert [screened["power_by_size"][i] for i in full] == [whole["power_by_size"][i] for i in full]
    assert set(whole["replicates_by_size"]) == {100} and sum(screened["replicates_by_size"]) < 0.6 * 100 * len(sizes)


_HEAD = "from kilobot_twin.gap.effects import Effect\n"
_TILT = ("class T(Effect):\n    name, kind = 'tilt2', 'motion'\n    predicts = {'speed': 'pop'}\n"
         "    def explains(self, signal):\n        return signal == 'speed:heading_dependence'\n")


@pytest.mark.parametrize("text, says", [
    (None, "mine.py does not exist"),
    ("x = 1\n", "is not a Python file (.py)"),  # written as mine.txt
    (_HEAD + "x = (\n", "failed to load at line 2: SyntaxError"),
    (_HEAD + "y = undefined_name\n", "failed to load at line 2: NameError"),
    ("import numpy\n", "defines no Effect subclass"),
    (_HEAD + "class T(Effect):\n    name, kind = 't', 'motion'\n", "T does not define fit"),
    (_HEAD + "class T(Effect):\n    name, kind = 't', 'wheels'\n    def fit(self, *a):\n        pass\n", "kind 'wheels'"),
    (_HEAD + "class T(Effect):\n    name, kind = 'heading_bias', 'motion'\n    predicts = {'speed': 'pop'}\n"
     "    def fit(self, *a):\n        pass\n", "the name 'heading_bias' is taken"),
    (_HEAD + "class T(Effect):\n    name, kind = 't', 'motion'\n    def fit(self, *a):\n        pass\n", "predicts no summary"),
    # the two below load, and fail when the workflow fits them on the tilted data
    (_HEAD + _TILT + "    def fit(self, model, meas, ref, resim=None):\n        return 1 / 0\n",
     "line 8 (fit) raised ZeroDivisionError"),
    (_HEAD + _TILT + "    def fit(self, model, meas, ref, resim=None):\n"
     "        return model.with_traits(scenario={'floor_tiltt': 0.1})\n", "floor_tiltt: unknown scenario key"),
    (_HEAD + _TILT + "    size_range, size_unit = (0.5, 0.1), 'slope'\n    def at_size(self, model, size, rng):\n"
     "        return model\n    def fit(self, *a):\n        pass\n", "size_range (0.5, 0.1) is not (smallest, largest)"),
    (_HEAD + _TILT + "    size_range = (0.01, 0.5)\n    def at_size(self, model, size, rng):\n"
     "        return model\n    def fit(self, *a):\n        pass\n", "gives at_size but no size_unit"),
    (_HEAD + _TILT + "    size_range, size_unit = (0.01, 0.5), 'slope'\n    def at_size(self, model, size, rng):\n"
     "        return 1 / 0\n    def fit(self, *a):\n        pass\n", "line 9 (at_size) raised ZeroDivisionError"),
])
def test_a_file_that_is_not_a_working_effect_gets_one_line_and_exit_2(tilted_small, tmp_path, capsys, text, says):
    ds = tilted_small
    f = tmp_path / ("mine.txt" if says.startswith("is not a Python") else "mine.py")
    if text is not None:
        f.write_text(text)
    out = tmp_path / "out"
    assert main(["gap", str(ds), "--out", str(out), "--effects", str(f), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    print(err)
    assert len(err.splitlines()) == 1 and says in err, err
    assert "--effects" in err or "TwinModel.scenario" in err  # the field to fix
    assert not out.exists()  # nothing written
