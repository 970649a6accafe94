"""Per-(trial, robot) summaries of observed runs: the signals the gap workflow compares.

All functions take arrays on the nominal sample grid, shaped (trials, robots, T), with NaN
where a sample is missing, and return arrays shaped (trials, robots). Measured and simulated
runs go through the same functions.
"""

from __future__ import annotations

import numpy as np

from ..core.constants import WHEEL_SEPARATION_M

#: Lag over which headings and speeds are measured: long enough that tracking noise (mm)
#: is small against the displacement (1.13 cm/s x 2 s), short enough to follow curvature.
MOTION_LAG_S = 2.0


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def _ffill(a):
    """Forward-fill NaNs along the last axis (leading NaNs stay NaN)."""
    ok = np.isfinite(a)
    idx = np.where(ok, np.arange(a.shape[-1]), 0)
    np.maximum.accumulate(idx, axis=-1, out=idx)
    out = np.take_along_axis(a, idx, axis=-1)
    first = np.maximum.accumulate(ok, axis=-1)
    return np.where(first, out, np.nan)


def _lagged_msd(r, ok, lag):
    """Mean squared change of r over ``lag`` samples where both ends are observed; (...,)."""
    d = r[..., lag:] - r[..., :-lag]
    m = ok[..., lag:] & ok[..., :-lag]
    return np.where(m, d * d, 0.0).sum(-1) / np.maximum(m.sum(-1), 1)


def motion(x, y, dt_s: float, lag_s: float = MOTION_LAG_S, msd_lags_s=(5.0, 20.0)) -> dict:
    """Turn rate, speed, heading diffusion and mean heading of every track.

    Headings are those of displacements over ``lag_s`` (long against tracking noise). They
    are unwrapped across tracking gaps by differencing consecutive *observed* headings, and
    ``turn_rate`` is the least-squares slope of the unwrapped heading against time (rad/s,
    counter-clockwise positive). ``speed`` is the mean lagged displacement over the lag (m/s).
    ``diffusion`` (rad^2/s) is the growth rate of the detrended heading's mean squared change
    between the two ``msd_lags_s``: tracking noise adds the same constant at both lags and
    cancels, the robot's heading noise (sigma_omega^2 per second) does not.
    ``heading`` is the circular mean heading. (For single tracks with irregular sample times,
    :func:`kilobot_twin.analysis.turn_rate_from_track` does the turn rate and speed.)
    """
    L = max(1, int(round(lag_s / dt_s)))
    dx = x[..., L:] - x[..., :-L]
    dy = y[..., L:] - y[..., :-L]
    dist = np.hypot(dx, dy)
    h = np.arctan2(dy, dx)
    ok = np.isfinite(h)
    hf = _ffill(h)
    step = np.nan_to_num(_wrap(np.diff(hf, axis=-1)), nan=0.0)
    first = np.where(ok.any(-1), np.take_along_axis(h, np.argmax(ok, axis=-1)[..., None], -1)[..., 0], 0.0)
    unwrapped = np.concatenate([np.zeros(h.shape[:-1] + (1,)), np.cumsum(step, axis=-1)], axis=-1) + first[..., None]
    t = np.arange(h.shape[-1]) * dt_s
    w = ok.astype(float)
    n = w.sum(-1)
    tm = (w * t).sum(-1) / np.maximum(n, 1)
    hm = (w * np.nan_to_num(unwrapped)).sum(-1) / np.maximum(n, 1)
    dt_ = np.where(ok, t - tm[..., None], 0.0)
    turn = (dt_ * np.where(ok, unwrapped - hm[..., None], 0.0)).sum(-1) / np.maximum((dt_**2).sum(-1), 1e-12)
    resid = np.where(ok, unwrapped - hm[..., None] - turn[..., None] * (t - tm[..., None]), 0.0)
    l1, l2 = (max(1, int(round(s / dt_s))) for s in msd_lags_s)
    diffusion = (_lagged_msd(resid, ok, l2) - _lagged_msd(resid, ok, l1)) / ((l2 - l1) * dt_s)
    okd = np.isfinite(dist)
    speed = np.where(okd, dist, 0.0).sum(axis=-1) / np.maximum(okd.sum(axis=-1), 1) / (L * dt_s)
    heading = np.arctan2(np.where(ok, np.sin(h), 0).sum(-1), np.where(ok, np.cos(h), 0).sum(-1))
    bad = n < 10
    out = {"turn_rate": turn, "speed": speed, "diffusion": diffusion, "heading": heading}
    return {k: np.where(bad, np.nan, v) for k, v in out.items()}


def bias_from_turn_rate(turn_rate, speed):
    """Heading bias (+ = clockwise) from turn rate and speed: ``b = -omega L / v``."""
    return -turn_rate * WHEEL_SEPARATION_M / speed


def light_sweep(stimulus, reading, knee_counts: float = 900.0, min_stimulus: float = 0.02) -> dict:
    """Gain (counts per unit stimulus), offset (counts) and residual sd of each track's
    linear response below the saturation knee."""
    use = np.isfinite(reading) & np.isfinite(stimulus) & (reading < knee_counts) & (stimulus > min_stimulus)
    w = use.astype(float)
    n = w.sum(-1)
    s = np.where(use, stimulus, 0.0)
    r = np.where(use, reading, 0.0)
    ms, mr = s.sum(-1) / np.maximum(n, 1), r.sum(-1) / np.maximum(n, 1)
    cov = (w * (s - ms[..., None]) * (r - mr[..., None])).sum(-1)
    var = (w * (s - ms[..., None]) ** 2).sum(-1)
    gain = cov / np.maximum(var, 1e-12)
    offset = mr - gain * ms
    resid = np.where(use, r - (offset[..., None] + gain[..., None] * s), 0.0)
    sd = np.sqrt((resid**2).sum(-1) / np.maximum(n - 2, 1))
    bad = n < 5
    return {k: np.where(bad, np.nan, v) for k, v in {"gain": gain, "offset": offset, "residual_sd": sd}.items()}


def blink(led, dt_s: float) -> dict:
    """Toggle rate (toggles per second) of each track from its LED samples (0/1, NaN = missing).

    A toggle is timed at the first observed sample after a colour change (missing frames are
    bridged by the last seen colour); the rate is (toggles - 1) / (last toggle - first toggle).
    Vectorised over all leading axes.
    """
    filled = _ffill(led)
    ok = np.isfinite(led[..., 1:]) & np.isfinite(filled[..., :-1])
    change = ok & (filled[..., 1:] != filled[..., :-1])
    n = change.sum(-1)
    T = change.shape[-1]
    first = np.argmax(change, axis=-1)
    last = T - 1 - np.argmax(change[..., ::-1], axis=-1)
    with np.errstate(all="ignore"):
        rate = (n - 1) / ((last - first) * dt_s)
    return {"toggle_rate": np.where(n >= 3, rate, np.nan)}
