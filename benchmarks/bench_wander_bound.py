"""How close the motion ``diffusion`` summary comes to the best any estimator can do from one track.

The Cramer-Rao bound for the heading-noise intensity sigma_omega^2 from one straight track: the
track's sideways position is v times the integral of a heading that diffuses (covariance
v^2 sigma^2 min(t,u)^2 (3 max(t,u) - min(t,u)) / 6) plus white tracking noise e^2 per frame; the
start, heading and turn rate are unknown (a quadratic in time, projected out: restricted
likelihood), and so is e^2 (a nuisance). The bound is the relative sd sqrt(I^-1)[0, 0] / sigma^2
of the 2 x 2 Fisher information for (sigma^2, e^2). Tracks are drawn here in numpy (unicycle at
100 Hz, sampled at 10 Hz; none of the twin's code) and summarised by the shipped ``summaries.motion``.
Prints, per tracking noise, the summary's relative sd over tracks and the bound's, at sigma_omega
0.01 and 0.02 rad/sqrt(s).

    python benchmarks/bench_wander_bound.py
"""

from __future__ import annotations

import time

import numpy as np

from kilobot_twin.gap import summaries

HZ, DURATION, SPEED, TRACKS, SUB = 10.0, 60.0, 0.0113, 400, 10


def tracks(sigma: float, e: float, seed: int):
    """Straight runs with heading diffusion sigma (rad/sqrt(s)) and a turn rate of sd 0.008 rad/s,
    positions with white noise e (m) per axis and frame."""
    rng = np.random.default_rng(seed)
    h = 1.0 / (HZ * SUB)
    steps = int(DURATION * HZ) * SUB + 1
    turn = 0.008 * rng.standard_normal((TRACKS, 1))
    walk = np.cumsum(sigma * np.sqrt(h) * rng.standard_normal((TRACKS, steps)), axis=1)
    th = rng.uniform(-np.pi, np.pi, (TRACKS, 1)) + turn * h * np.arange(steps) + walk
    x = np.cumsum(SPEED * np.cos(th) * h, axis=1)[:, ::SUB]
    y = np.cumsum(SPEED * np.sin(th) * h, axis=1)[:, ::SUB]
    return x + e * rng.standard_normal(x.shape), y + e * rng.standard_normal(y.shape)


def bound(sigma: float, e: float) -> float:
    """Relative sd of the best unbiased estimate of sigma^2 from one track (restricted likelihood)."""
    t = np.arange(int(DURATION * HZ) + 1) / HZ
    lo, hi = np.minimum.outer(t, t), np.maximum.outer(t, t)
    A = SPEED**2 * lo**2 * (3 * hi - lo) / 6  # sideways position per unit sigma^2
    q = np.linalg.qr(np.vander(t / t[-1], 3))[0]
    U = np.linalg.svd(np.eye(len(t)) - q @ q.T)[0][:, : len(t) - 3]  # the quadratic projected out
    A = U.T @ A @ U
    B = np.eye(len(A))
    Si = np.linalg.inv(sigma**2 * A + e**2 * B)
    SA, SB = Si @ A, Si @ B
    F = 0.5 * np.array([[np.sum(SA * SA.T), np.sum(SA * SB.T)], [np.sum(SB * SA.T), np.sum(SB * SB.T)]])
    return float(np.sqrt(np.linalg.inv(F)[0, 0]) / sigma**2)


def main():
    t0 = time.perf_counter()
    print(f"relative sd of sigma_omega^2 from one track ({DURATION:.0f} s at {HZ:.0f} Hz, {SPEED * 100:.2f} cm/s, "
          f"{TRACKS} tracks): the shipped diffusion summary against the Cramer-Rao bound")
    for e in (0.0005, 0.002, 0.008):
        cells = []
        for sigma in (0.01, 0.02):
            x, y = tracks(sigma, e, seed=int(1e6 * e) + int(100 * sigma))
            d = summaries.motion(x, y, 1.0 / HZ, wander_lags_s=summaries.wander_lags(e))["diffusion"]
            d = d[np.isfinite(d)]
            rel, lim = float(np.std(d, ddof=1) / np.mean(d)), bound(sigma, e)
            cells.append(f"sigma {sigma:.2f}: summary {rel:4.2f}, bound {lim:4.2f} (variance {(rel / lim) ** 2:3.1f}x)")
        print(f"  tracking noise {e * 1e3:3.1f} mm: " + "; ".join(cells))
    print(f"({time.perf_counter() - t0:.1f} s)")


if __name__ == "__main__":
    main()
