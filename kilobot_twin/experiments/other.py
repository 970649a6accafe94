"""Heterogeneity beyond motion: light sensing (Fig. 8), natural frequency and coupling (Fig. 9)."""

from __future__ import annotations

import numpy as np

from ..core import sim
from ..core.traits import draw_population
from .common import Check, Outcome, Settings

# --- Fig. 8: sensing ------------------------------------------------------------------------

# Our population for the 12 robots under the projector (the paper gives curves, not numbers):
# gains spread so that the steepest robot reaches ~1000 at half the luminance of the
# shallowest (Fig. 8b); a few counts of offset; 8 counts of noise per sample; the soft knee.
SENSING_POPULATION = {
    "n": 12,
    "sensor_gain": {"dist": "uniform", "low": 1.5, "high": 3.0},
    "sensor_offset": {"dist": "normal", "mean": 5.0, "sd": 3.0},
    "sensor_noise": 8.0,
}
SWEEP_PERIOD_S = 60.0


def run_sensing(s: Settings) -> Outcome:
    """12 robots under the same saw-tooth sweep of V (4 ramps); readings vs luminance."""
    swarm = draw_population(SENSING_POPULATION, seed=s.seed)
    sc = s.scenario(behavior="still", dt_s=0.1, duration_s=4 * SWEEP_PERIOD_S, tick_hz=31.0,
                    light={"kind": "sweep", "period_s": SWEEP_PERIOD_S, "ramps": 4},
                    sensor={"knee": 6.0}, start={"kind": "grid", "spacing_m": 0.0, "columns": 12})
    # The robots stand still and read the light every step with their own sensors.
    res = sim.simulate(sc, swarm, s.seed, record_every=1)
    readings = res.traj["reading"][0, :, 1:]  # (robots, T): the reading taken at the end of each step
    t_s = res.t_s[1:]
    v = sc.light.v_value(t_s)
    ramp = np.minimum(np.floor(t_s / SWEEP_PERIOD_S + 1e-9).astype(int), 3)
    thresholds = np.arange(0, 1024, 8)
    # Agreement (Fig. 8c): per V bin of the first ramp, how many robots read above a threshold.
    first = ramp == 0
    order = np.argsort(v[first])
    agree = (readings[:, first][:, order][None, :, :] > thresholds[:, None, None]).sum(axis=1)  # (thr, samples)
    data = {"v": v, "readings": readings, "ramp": ramp, "gain": swarm.sensor_gain, "thresholds": thresholds,
            "agree": agree, "agree_v": v[first][order]}
    checks = _sensing_checks(data)
    return Outcome("sensing", data, {"population": SENSING_POPULATION, "seed": s.seed}, checks)


def _v_reaching(v, reading, level):
    """Smallest V at which a (noisy) reading first exceeds ``level`` on a ramp."""
    above = np.flatnonzero(reading >= level)
    return v[above[0]] if above.size else np.nan


def _sensing_checks(d):
    v, r, ramp = d["v"], d["readings"], d["ramp"]
    low = r[:, (v < 0.01)].mean()
    high = r[:, (v > 0.95)].mean(axis=1)
    reach = np.array([[_v_reaching(v[ramp == k], r[i, ramp == k], 900) for k in range(4)] for i in range(r.shape[0])])
    ratio = np.nanmin(reach[:, 0]) / np.nanmax(reach[:, 0])
    from scipy.stats import spearmanr

    rho = spearmanr(reach[:, 0], reach[:, 3]).statistic
    agree = d["agree"]
    mid = agree[(d["thresholds"] >= 300) & (d["thresholds"] <= 700)]
    band = ((mid > 0) & (mid < agree.max())).mean(axis=1)  # fraction of V in disagreement per threshold
    return [
        Check("8b", "readings rise from ~0 and saturate near 1000", "~0 -> ~1000",
              f"{low:.0f} at V=0, {high.min():.0f}-{high.max():.0f} at V=1", low < 30 and 950 <= high.min() <= 1023),
        Check("8b", "the steepest robot reaches 1000 at about half the luminance of the shallowest",
              "ratio ~0.5", f"V(900) ratio = {ratio:.2f}", 0.35 <= ratio <= 0.65),
        Check("8b", "differences are persistent across ramps", "persistent",
              f"Spearman rho(ramp 1, ramp 4) = {rho:.2f}", rho > 0.9),
        Check("8c", "all 12 agree only away from the boundary; the disagreement band is wide",
              "wide band", f"{100 * band.mean():.0f} % of V in disagreement at thresholds 300-700", band.mean() > 0.1),
    ]


def plot_sensing(o: Outcome, out_dir):
    from ..plots import pyplot, save

    plt = pyplot()
    d = o.data
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    t = np.arange(d["readings"].shape[1]) * 0.1
    for i in range(d["readings"].shape[0]):
        axes[0].plot(t, d["readings"][i], lw=0.6)
    axes[0].set_xlabel("time (s)")
    axes[0].set_ylabel("light reading (ADC counts)")
    axes[0].set_title("(a) four saw-tooth sweeps")
    first = d["ramp"] == 0
    cmap = plt.get_cmap("viridis")
    g = d["gain"]
    for i in range(d["readings"].shape[0]):
        axes[1].plot(d["v"][first], d["readings"][i, first], lw=0.8, color=cmap((g[i] - g.min()) / np.ptp(g)),
                     label=f"robot {i}: gain {g[i]:.2f}")
    axes[1].plot(d["v"][first], np.median(d["readings"][:, first], axis=0), color="k", lw=2, label="median")
    axes[1].set_xlabel("projected V-value (luminance, 0-1)")
    axes[1].set_ylabel("light reading (ADC counts)")
    axes[1].set_title("(b) 12 robots, one ramp")
    axes[1].legend(fontsize=6, ncol=2)
    im = axes[2].imshow(d["agree"], origin="lower", aspect="auto", cmap="viridis",
                        extent=(d["agree_v"][0], d["agree_v"][-1], d["thresholds"][0], d["thresholds"][-1]))
    fig.colorbar(im, ax=axes[2], label="# robots reading above threshold")
    axes[2].set_xlabel("projected V-value (luminance, 0-1)")
    axes[2].set_ylabel("threshold (ADC counts)")
    axes[2].set_title("(c) agreement")
    return [save(fig, out_dir / "fig8_sensing.png")]


# --- Fig. 9 a-c: natural frequency ---------------------------------------------------------------

CLOCK_SD = 0.015          # relative spread of natural clock rates (paper: ~1.5 %)
CLOCK_TRIAL_SD = 0.002    # our choice: repetitions of one robot differ by 1-3 switches (Fig. 9b)
# Length of one switch-count experiment: a median robot toggles ~193 times (Fig. 9b):
# 193 toggles x 30 ticks / 31 Hz = 186.8 s.
FREQ_DURATION_S = 193 * 30 / 31


def run_frequency(s: Settings) -> Outcome:
    """49 robots on a 7x7 grid toggle red/blue every 30 ticks, started in sync, no messages."""
    pop = {"n": 49, "clock_rate": {"dist": "normal", "mean": 1.0, "sd": CLOCK_SD}, "clock_trial_sd": CLOCK_TRIAL_SD}
    swarm = draw_population(pop, seed=s.seed)
    sc = s.scenario(behavior="blink", dt_s=1 / 31, duration_s=FREQ_DURATION_S, tick_hz=31.0,
                    start={"kind": "grid", "spacing_m": 0.06, "columns": 7}, light={"kind": "cone"})
    res = sim.simulate(sc, swarm, s.seed, runs=np.arange(4), trials=np.arange(4))
    switches = res.summary["switches"]  # (4 repetitions, 49)
    # Long run for the population ratio (Fig. 9c): ~13k camera samples at 30 fps.
    long_s = 120.0 if s.quick else 440.0
    sc_long = sc.replace(duration_s=long_s, dt_s=1 / 30)
    longres = sim.simulate(sc_long, swarm, s.seed, runs=[10], record_every=1)
    blue = (longres.traj["led"][0] == 1).mean(axis=0)
    data = {"switches": switches, "clock_rate": swarm.clock_rate, "blue_fraction": blue, "t_s": longres.t_s,
            "order": longres.order[0]}
    return Outcome("frequency", data, {"population": pop, "seed": s.seed, "duration_s": FREQ_DURATION_S},
                   _frequency_checks(data))


def _frequency_checks(d):
    sw = d["switches"].astype(float)
    med, lo, hi = np.median(sw), sw.min(), sw.max()
    spread = sw.mean(axis=0).std(ddof=1) / sw.mean()
    # Persistence: between-robot variance dominates (intra-class correlation over repetitions).
    within = sw.var(axis=0, ddof=1).mean()
    between = sw.mean(axis=0).var(ddof=1)
    icc = (between - within / sw.shape[0]) / between
    # Spread of counts vs spread of true clock rates: counts = floor(31 c T / 30) (+ trial jitter).
    rate_sd = d["clock_rate"].std(ddof=1)
    n = len(d["clock_rate"])
    se = spread * np.sqrt(1 / (2 * (n - 1)))  # standard error of an sd estimate
    blue = d["blue_fraction"]
    fps = 30
    early = blue[: fps * 4]
    late = blue[2000:]
    return [
        Check("9b", "switch counts per robot over one experiment", "185-203, median ~193",
              f"{lo:.0f}-{hi:.0f}, median {med:.0f}", abs(med - 193) <= 3 and lo >= 175 and hi <= 212),
        Check("9b", "relative clock-rate spread", "~1.5 % (sd)", f"{100 * spread:.2f} % (true rates {100 * rate_sd:.2f} %)",
              abs(spread - rate_sd) < 4 * se + 0.002),
        Check("9b", "counts are persistent per robot across 4 repetitions", "persistent",
              f"intra-class correlation {icc:.2f}", icc > 0.8),
        Check("9c", "population ratio starts as full 0/1 square waves", "0/1 at start",
              f"min {early.min():.2f}, max {early.max():.2f} in the first 4 s", early.min() == 0 and early.max() == 1),
        Check("9c", "and decays to ~0.5 by ~2000 samples", "~0.5",
              f"mean {late.mean():.2f}, |ratio-0.5| p90 {np.quantile(np.abs(late - 0.5), 0.9):.2f} after sample 2000",
              abs(late.mean() - 0.5) < 0.1 and np.quantile(np.abs(late - 0.5), 0.9) < 0.35),
    ]


def plot_frequency(o: Outcome, out_dir):
    from ..plots import pyplot, save

    plt = pyplot()
    d = o.data
    sw = d["switches"]
    order = np.argsort(sw.mean(axis=0))
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.2), gridspec_kw={"width_ratios": [1, 2]})
    ax = axes[0]
    cmap = plt.get_cmap("flare" if "flare" in plt.colormaps() else "magma_r")
    for rank, i in enumerate(order):
        ax.scatter(np.full(sw.shape[0], rank), sw[:, i], color=cmap(rank / len(order)), s=14)
    ax.set_xlabel("robot (sorted by its mean)")
    ax.set_ylabel("LED switches per experiment (count)")
    ax.set_title("(b) switches per robot, 4 repetitions")
    ax = axes[1]
    samples = np.arange(len(d["blue_fraction"]))
    ax.fill_between(samples, 0, d["blue_fraction"], color="blue", lw=0, step="mid", label="robots showing blue")
    ax.fill_between(samples, d["blue_fraction"], 1, color="red", lw=0, step="mid", label="robots showing red")
    ax.legend(fontsize=7, loc="upper right", framealpha=0.9)
    ax.set_xlim(0, len(samples))
    ax.set_ylim(0, 1)
    ax.set_xlabel("sample (30 per s)")
    ax.set_ylabel("population ratio (fraction of robots)")
    ax.set_title("(c) from synchrony to ~0.5")
    return [save(fig, out_dir / "fig9_frequency.png")]


# --- Fig. 9 d-f: Kuramoto coupling ----------------------------------------------------------------

def run_kuramoto(s: Settings) -> Outcome:
    """Coupling-strength sweep from random phases: order parameter over time per strength.

    Coupling acts between neighbours within 10 cm on the 7x7 grid (6 cm spacing: 8 neighbours),
    once per clock tick (dt = 1/31 s). Because the correction is applied in discrete steps it
    overshoots once k dt exceeds ~1: that is the paper's "too strong" regime.
    """
    ks = np.array([0.0, 0.003, 0.01, 0.03, 0.1, 0.3, 1.0, 3.0, 10.0, 30.0, 60.0, 100.0])
    if s.quick:  # seven of the twelve: 0, 0.003, 0.03, 0.3, 1, 10, 100 /s (the three regimes and their edges)
        ks = ks[[0, 1, 3, 5, 6, 8, 11]]
    pop = {"n": 49, "clock_rate": {"dist": "normal", "mean": 1.0, "sd": CLOCK_SD}}
    swarm = draw_population(pop, seed=s.seed)
    duration = 200.0 if s.quick else 400.0
    runs = 2 if s.quick else 5
    orders = []
    for k in ks:
        sc = s.scenario(behavior="blink", dt_s=1 / 31, duration_s=duration, tick_hz=31.0, coupling_per_s=float(k),
                        neighbour_radius_m=0.1, light={"kind": "cone"},
                        start={"kind": "grid", "spacing_m": 0.06, "columns": 7, "random_phase": True})
        res = sim.simulate(sc, swarm, s.seed, runs=np.arange(runs))
        orders.append(res.order[:, ::31])  # one sample per second
    order = np.stack(orders)  # (K, runs, T)
    final = order[:, :, -order.shape[2] // 4:].mean(axis=(1, 2))
    data = {"k": ks, "order": order, "final_order": final}
    return Outcome("kuramoto", data, {"population": pop, "seed": s.seed, "dt_s": 1 / 31, "duration_s": duration},
                   _kuramoto_checks(data))


def sync_range(ks, final, level=0.9):
    ok = final > level
    return (float(ks[ok].min()), float(ks[ok].max())) if ok.any() else (float("nan"), float("nan"))


def _kuramoto_checks(d):
    ks, final = d["k"], d["final_order"]
    lo, hi = sync_range(ks, final)
    weak = final[ks <= 0.003].max()
    strong = final[ks == ks.max()][0]
    return [
        Check("9d", "weak coupling stays asynchronous", "asynchronous", f"order {weak:.2f} at k <= 0.003 /s", weak < 0.5),
        Check("9e", "medium coupling synchronises", "synchronous",
              f"order > 0.9 for k in [{lo:g}, {hi:g}] /s", np.isfinite(lo)),
        Check("9f", "too strong coupling does not synchronise either", "super-stable, not synchronous",
              f"order {strong:.2f} at k = {ks.max():g} /s", np.isfinite(hi) and hi < ks.max()),
    ]


def plot_kuramoto(o: Outcome, out_dir):
    from ..plots import pyplot, save

    plt = pyplot()
    d = o.data
    fig, axes = plt.subplots(1, 2, figsize=(12, 4))
    cmap = plt.get_cmap("plasma")
    for i, k in enumerate(d["k"]):
        axes[0].plot(d["order"][i].mean(axis=0), color=cmap(i / len(d["k"])), label=f"k = {k:g}")
    axes[0].set_xlabel("time (s)")
    axes[0].set_ylabel("order parameter r (0-1)")
    axes[0].legend(fontsize=7, ncol=2, title="coupling (1/s)", title_fontsize=7)
    axes[0].set_title("(d-f) order parameter over time, mean over runs")
    kk = np.where(d["k"] == 0, d["k"][1] / 3, d["k"])
    axes[1].semilogx(kk, d["final_order"], "o-", label="mean r over the last quarter")
    axes[1].axhline(0.9, color="tab:green", ls="--", lw=1, label="r = 0.9: synchronous")
    axes[1].legend(fontsize=7)
    axes[1].set_xlabel("coupling k (1/s; k = 0 drawn at the left)")
    axes[1].set_ylabel("final order parameter r (0-1)")
    axes[1].set_title("weak: asynchronous, medium: synchronous, strong: fails")
    return [save(fig, out_dir / "fig9_kuramoto.png")]
