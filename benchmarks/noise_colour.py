"""What coloured turn noise does to the two readings of a robot's heading noise, and how much data
would tell it from white noise.

The base model's heading noise is white; a real robot's turn noise is correlated over some time
tau. Its long-run intensity sigma_omega is the same whatever tau (the twin's ``heading_noise_tau``
and the independent world keep Var(heading) = sigma_omega^2 t at long times), but over lags short
against tau the heading wanders less. Two readings of sigma_omega^2, on twin tracks (60 s at
10 Hz, 1.1 cm/s, 2 mm of white tracking noise by default, no trial-to-trial bias spread):

- **wander**: the motion summary's ``diffusion`` (the tracks' sideways wander between 1 s and
  ``summaries.wander_lags``' long lag, 10 s at 2 mm), the base's reading of the level. Shown
  relative to its value on white noise of the same intensity.
- **halves**: half a track's turn rate (the summary's least-squares slope of its chord headings)
  minus the other half's. A trial's own heading bias, fixed within the trial, cancels; so the
  difference reads the heading noise alone, none of the trial-to-trial bias spread, and over
  halves of 30 s it sees the long-run intensity. Shown relative to its exact value for white
  noise, computed here from the sample times (the slope's weights on chord headings that average
  the heading over each 2 s chord, under a Brownian heading), not from a simulation.

For each tau: both readings' means over all tracks (with standard errors), their relative sds over
datasets of 12 robots x 4 trials, and how many robot-trials it would take to see a dataset's
wander over its halves fall short of white noise's by 2 sds of that ratio, which is what fitting
tau from these summaries would need (the ratio's sd scales as 1 / sqrt(robot-trials)).

    python benchmarks/noise_colour.py [--datasets 1000] [--tracking-mm 2]
    python benchmarks/noise_colour.py --bias-spread
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from kilobot_twin.batch import engine
from kilobot_twin.gap import effects, summaries, synth

DT, DURATION, SIGMA, LAG_S = 0.1, 60.0, 0.01, 2.0
PER_DATASET = 48  # 12 robots x 4 trials
TAUS = (0.0, 0.5, 1.0, 2.0)


def tracks(tau: float, n: int, seed: int, tracking_m: float, robots: int = 1, trials: int = 1, bias: float = 0.0,
           noise_seed: int | None = None):
    """Twin tracks (runs, robots, T): n runs of trial 0, 1, ..., trials - 1 in turn, heading noise
    correlated over tau (white at 0), a trial-to-trial bias spread ``bias`` (in b), and white
    tracking noise (its own stream, ``noise_seed``, default seed + 1)."""
    sw = effects.nominal_model("motion", np.arange(robots)).swarm.with_values(
        sigma_omega=np.full(robots, SIGMA), heading_noise_tau=np.full(robots, tau), bias_trial_sd=np.full(robots, bias))
    res = engine.simulate(synth.motion_scenario(DURATION, DT), sw, seed, runs=np.arange(n),
                          trials=np.tile(np.arange(trials), n // trials), record_every=1)
    rng = np.random.default_rng(seed + 1 if noise_seed is None else noise_seed)
    return tuple(res.traj[c] + tracking_m * rng.standard_normal(res.traj[c].shape) for c in ("x", "y"))


def white_half_difference(samples: int) -> float:
    """Var(slope of half 1 - slope of half 2) for a Brownian heading of unit intensity, exactly:
    each half's chord headings are the heading averaged over the chord (``LAG_S``), their slope a
    least-squares line over the half's samples; the halves' increments are independent."""
    L = int(round(LAG_S / DT))
    m = samples - L  # chord headings in a half
    t = np.arange(samples) * DT
    cov = np.minimum.outer(t, t)  # Brownian heading at the samples, unit intensity
    avg = np.zeros((m, samples))
    for j in range(m):  # chord j's heading: the heading's mean over [t_j, t_j + LAG_S]
        avg[j, j:j + L + 1] = 1.0
        avg[j, [j, j + L]] = 0.5
        avg[j] /= L
    tc = np.arange(m) * DT
    w = (tc - tc.mean()) / ((tc - tc.mean()) ** 2).sum()  # least-squares slope weights
    v = w @ avg
    return 2.0 * float(v @ cov @ v)  # two independent halves


def bias_spread(datasets: int) -> None:
    """The halves' reading of Eq. 6's trial-to-trial bias spread (``--bias-spread``): per dataset of
    12 robots x 4 trials, the trial turn rates' pooled within-robot variance less a quarter of the
    halves' mean squared difference (the noise's part of a whole trial's turn rate, for a Brownian
    heading), against the truth's spread in turn rate, b v / 0.025 m."""
    n, k = 12, 4
    v = synth.FORWARD_SPEED_M_S
    print(f"bias spread from the halves, {datasets} datasets of {n} x {k} per row (squared spread in rad^2/s^2)")
    print("tracking_mm  tau_s  spread_b  truth_rad_s  read: mean of b^2 (truth b^2)  sd per dataset  median spread")
    for j, (trk, tau, b) in enumerate((t, u, b) for t in (2.0, 6.0) for u in (0.0, 2.0) for b in (0.0, 0.002, 0.004)):
        x, y = tracks(tau, datasets * k, 500 + j, trk / 1e3, robots=n, trials=k, bias=b, noise_seed=600 + j)
        h = x.shape[-1] // 2
        whole, first, second = (summaries.motion(x[..., a:z], y[..., a:z], DT)["turn_rate"].reshape(datasets, k, n)
                                for a, z in ((0, None), (0, h), (h, 2 * h)))
        b2 = np.nanvar(whole, axis=1, ddof=1).mean(-1) - np.nanmean((first - second) ** 2, axis=(1, 2)) / 4
        truth = b * v / 0.025
        print(f"{trk:11.0f}  {tau:5.1f}  {b:8.3f}  {truth:11.4f}  {b2.mean():20.2e} ({truth**2:.1e})  {b2.std(ddof=1):14.1e}"
              f"  {np.median(np.sqrt(np.maximum(b2, 0))):13.4f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--datasets", type=int, default=1000, help="datasets of 12 x 4 per tau (default 1000)")
    ap.add_argument("--tracking-mm", type=float, default=2.0, help="white tracking noise, mm (default 2; at 0.5 the wander lags are 1-5 s)")
    ap.add_argument("--bias-spread", action="store_true",
                    help="instead: the halves' reading of the trial-to-trial bias spread (40 datasets per row)")
    a = ap.parse_args()
    if a.bias_spread:
        bias_spread(40)
        return
    n = a.datasets * PER_DATASET
    T = int(round(DURATION / DT)) + 1
    h = T // 2
    theory = white_half_difference(h) * SIGMA**2
    tracking_m = a.tracking_mm / 1e3
    lags = summaries.wander_lags(tracking_m)
    t0 = time.perf_counter()
    rows, white_wander = [], None
    for k, tau in enumerate(TAUS):
        x, y = (c[:, 0] for c in tracks(tau, n, 9400 + k, tracking_m))
        wander = summaries.motion(x, y, DT, wander_lags_s=lags)["diffusion"]
        a_ = summaries.motion(x[:, :h], y[:, :h], DT)["turn_rate"]
        b_ = summaries.motion(x[:, h:2 * h], y[:, h:2 * h], DT)["turn_rate"]
        halves = (a_ - b_) ** 2
        per = lambda v: np.nanmean(v.reshape(a.datasets, PER_DATASET), axis=1)  # noqa: E731
        wd, hd = per(wander), per(halves)
        if white_wander is None:
            white_wander = float(np.nanmean(wander))
        rw, rh = wd / white_wander, hd / theory
        rows.append((tau, rw, rh))
    print(f"twin tracks {DURATION:.0f} s at {1 / DT:.0f} Hz, sigma_omega {SIGMA} rad/sqrt(s), {a.tracking_mm:g} mm "
          f"tracking noise, wander lags {lags[0]:.0f}-{lags[1]:.0f} s, halves of {h * DT:.0f} s; "
          f"{a.datasets} datasets of 12 x 4 per tau ({time.perf_counter() - t0:.0f} s)")
    # What a 12 x 4 dataset would read colour by: its wander over its halves, relative to white
    # noise's; the halves' reading is near its white value at every tau (the check of the column).
    sd_ratio = float(np.std(rows[0][1] / rows[0][2], ddof=1) / np.mean(rows[0][1] / rows[0][2]))
    print(f"per 12 x 4 dataset (white): wander's relative sd {np.std(rows[0][1], ddof=1):.3f}, halves' "
          f"{np.std(rows[0][2], ddof=1) / np.mean(rows[0][2]):.3f}, their ratio's {sd_ratio:.3f}")
    print("tau_s  wander/white (+- se)  halves/theory (+- se)  wander/halves short of white's  robot-trials to see it at 2 sd")
    w0, r0 = rows[0][1], rows[0][1] / rows[0][2]
    for tau, rw, rh in rows:
        D = len(rw)
        rr = rw / rh  # each dataset's colour reading: its wander over its halves
        se_w = float(np.sqrt(np.var(rw, ddof=1) / D + np.var(w0, ddof=1) / D)) if tau > 0 else 0.0
        short = 1.0 - float(np.mean(rr) / np.mean(r0))
        se = float(np.sqrt(np.var(rr, ddof=1) / D + np.var(r0, ddof=1) / D) / np.mean(r0))
        if tau == 0:
            need = "-"
        elif short > 2 * se:  # resolved here: scaled to the datasets whose ratio's sd it is 2 sds of
            need = f"{PER_DATASET * (2 * sd_ratio / short) ** 2:,.0f}"
        else:
            need = f"> {PER_DATASET * (2 * sd_ratio / (short + 2 * se)) ** 2:,.0f} (not resolved here)"
        print(f"{tau:5.1f}  {np.mean(rw) / np.mean(w0):8.3f} +- {se_w:.3f}  {np.mean(rh):10.3f} +- {np.std(rh, ddof=1) / np.sqrt(D):.3f}"
              f"  {short:18.3f} +- {se:.3f}  {need:>26}")


if __name__ == "__main__":
    main()
