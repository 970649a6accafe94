"""Random walk area coverage vs heading bias (Fig. 7).

Why the two presets differ here. The authors' walk (random_walk.c: each decision forward 2 s
with p = 0.5, else a 1 s turn left or right) reorients the robot every few seconds: its
rotational diffusion is about D_r = 0.09 rad^2/s, a persistence time tau ~ 11 s. A heading bias
b turns the robot at omega_b = b v / L while it drives; a chiral random walk's diffusion shrinks
by 1 / (1 + (omega_b tau)^2), so the bias only matters once omega_b tau ~ 1. At the labelled
|b| <= 0.04, omega_b tau ~ 0.14 and coverage changes by a few per cent, not the ~25 % of
Fig. 7c. At |b| <= 0.2 (the range whose circles Fig. 1c draws: r = 0.025 m / 0.2 = 0.125 m)
omega_b tau ~ 0.7 and the ideal robot covers clearly more, as in the paper. So:

- ``argos-code``: the authors' setup as shipped (1 m walled arena, 2000 s, bias +-0.04).
- ``paper``: the same walk with the bias axis read as +-0.2, in a 4 m arena where the walls
  rarely matter (in a 1 m box, robots pinned against walls dominate coverage instead).
"""

from __future__ import annotations

import numpy as np

from ..batch import Campaign, run_campaign
from ..core.traits import draw_population
from .common import Check, Outcome, Settings

SETUPS = {
    "argos-code": {"bias": 0.04, "arena_m": 1.0, "duration_s": 2000.0},
    "paper": {"bias": 0.2, "arena_m": 4.0, "duration_s": 2000.0},
}


def run_random_walk(s: Settings) -> Outcome:
    setup = SETUPS[s.preset]
    n, runs = (41, 20) if s.quick else (200, 100)
    sc = s.scenario(behavior={"kind": "random_walk"}, duration_s=setup["duration_s"],
                    arena={"width_m": setup["arena_m"], "height_m": setup["arena_m"], "walls": True,
                           "coverage_cell_m": 0.033},
                    start={"kind": "uniform", "half_width_m": 0.3, "heading_rad": None, "shared": False})
    # The authors' simulator's per-tick wheel noise applies to every behaviour.
    swarm = draw_population({"n": n, "heading_bias": {"dist": "linspace", "low": -setup["bias"], "high": setup["bias"]},
                             "wheel_noise": 0.5}, seed=s.seed)
    res = run_campaign(Campaign(sc, swarm, s.seed, runs), workers=s.workers, progress=s.progress, desc="random walk")
    cov = res["summary"]["coverage_m2"][0]  # (runs, robots)
    data = {"bias": swarm.heading_bias, "coverage_m2": cov}
    meta = {**setup, "robots": n, "runs": runs, "cell_m": 0.033, "seed": s.seed}
    return Outcome("random_walk", data, meta, _checks(data, setup["bias"]))


def coverage_peak_stats(bias, cov, inner=0.25, outer=0.75):
    """Mean coverage of robots with |b| <= inner*max vs |b| >= outer*max, their ratio and its SE."""
    lim = np.abs(bias).max()
    mid = np.abs(bias) <= inner * lim
    ext = np.abs(bias) >= outer * lim
    a, b = cov[:, mid].mean(axis=1), cov[:, ext].mean(axis=1)  # per-run means (independent runs)
    ratio = b.mean() / a.mean()
    # Delta-method SE of a ratio of means over independent runs.
    se = ratio * np.sqrt(b.var(ddof=1) / (len(b) * b.mean() ** 2) + a.var(ddof=1) / (len(a) * a.mean() ** 2))
    return a.mean(), b.mean(), ratio, se


def _checks(d, bias_range):
    mean_cov = d["coverage_m2"].mean(axis=0)
    best = d["bias"][np.argmax(mean_cov)]
    mid, ext, ratio, se = coverage_peak_stats(d["bias"], d["coverage_m2"])
    return [
        Check("7c", "coverage is highest near bias 0", "peak at 0",
              f"extremes / centre = {ratio:.3f} +- {se:.3f} (best robot b = {best:+.3f}, axis +-{bias_range:g})",
              ratio + 3 * se < 1.0),
        Check("7c", "extremes keep ~75 % of the ideal robot's coverage", "~0.75 (4.8k vs 3.6k px^2)",
              f"{ratio:.2f}", abs(ratio - 0.75) <= 0.1),
        Check("7c", "wide scatter per robot", "wide", f"per-robot CV {np.median(d['coverage_m2'].std(axis=0) / mean_cov):.2f}",
              np.median(d["coverage_m2"].std(axis=0) / mean_cov) > 0.05),
    ]


def plot_random_walk(o: Outcome, out_dir):
    from ..plots import _plt, bias_cmap

    plt = _plt()
    d = o.data
    fig, ax = plt.subplots(figsize=(6, 4.5))
    b = np.tile(d["bias"], d["coverage_m2"].shape[0])
    lim = np.abs(d["bias"]).max()
    ax.scatter(b, d["coverage_m2"].ravel(), c=b, cmap=bias_cmap(), vmin=-lim, vmax=lim, s=6, alpha=0.4, lw=0)
    ax.plot(d["bias"], d["coverage_m2"].mean(axis=0), color="k", lw=2, label="mean")
    ax.set_xlabel("heading bias (+ = right)")
    ax.set_ylabel("covered area [m^2] (3.3 cm cells)")
    ax.set_title(f"Random walk coverage ({o.meta['arena_m']:g} m arena, {o.meta['duration_s']:g} s)")
    ax.legend()
    fig.tight_layout()
    path = out_dir / "fig7_random_walk.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return [path]
