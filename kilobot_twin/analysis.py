"""Summaries of experiment arrays (pure NumPy): acceptable ranges, minima, comparisons."""

from __future__ import annotations

import numpy as np

from .core.constants import WHEEL_SEPARATION_M
from .core.kinematics import heading_bias_from_turn_rate


def mean_cost_by_robot(cost):
    """(G, R, N) -> (G, N) mean over Monte Carlo runs."""
    return np.asarray(cost).mean(axis=-2)


def acceptable_range(bias, mean_cost, delta_acc):
    """R_acc: the bias interval [lo, hi] around the best robot where the mean cost stays below
    ``delta_acc`` (the contiguous run of acceptable robots containing the minimum), and its width.

    Returns (lo, hi, width); (nan, nan, 0) if no robot is acceptable.
    """
    order = np.argsort(bias)
    b, c = np.asarray(bias)[order], np.asarray(mean_cost)[order]
    ok = c < delta_acc
    if not ok.any():
        return float("nan"), float("nan"), 0.0
    best = int(np.argmin(c))
    lo = best
    while lo > 0 and ok[lo - 1]:
        lo -= 1
    hi = best
    while hi < len(b) - 1 and ok[hi + 1]:
        hi += 1
    return float(b[lo]), float(b[hi]), float(b[hi] - b[lo])


def n_acceptable(cost, delta_acc):
    """N_acc: number of (run, robot) experiments with cost below ``delta_acc``; cost (..., R, N)."""
    return int((np.asarray(cost) < delta_acc).sum())


def phototaxis_summary(bias, cost, p_rights, delta_acc=0.75) -> dict:
    """Headline numbers of a phototaxis campaign, per P_R."""
    bias = np.asarray(bias)
    mc = mean_cost_by_robot(cost)
    zero = int(np.argmin(np.abs(bias)))
    out = {}
    for g, p in enumerate(p_rights):
        m = mc[g]
        left, right = bias < 0, bias > 0
        lo, hi, width = acceptable_range(bias, m, delta_acc)
        best = int(np.argmin(m))
        out[f"P_R={p}"] = {
            "cost_at_zero_bias_m": round(float(m[zero]), 4),
            "best_bias": round(float(bias[best]), 4),
            "best_cost_m": round(float(m[best]), 4),
            "mean_cost_left_biased_m": round(float(m[left].mean()), 4) if left.any() else None,
            "mean_cost_right_biased_m": round(float(m[right].mean()), 4) if right.any() else None,
            "R_acc": [round(lo, 4), round(hi, 4)],
            "N_acc": n_acceptable(cost[g], delta_acc),
        }
    return out


def turn_rate_from_track(t_s, x, y, min_step_m: float = 1e-4):
    """Turn rate (rad/s, counter-clockwise positive) and speed (m/s) of tracked positions.

    The heading of each displacement between samples is unwrapped and a line is fitted to it
    against time (least squares). Works on the last axis; NaN positions (tracking gaps) and
    displacements shorter than ``min_step_m`` (standing still, tracker jitter) are skipped.
    It takes each track's own (possibly irregular) sample times; for tracks on a common grid
    the gap workflow uses the vectorised :func:`kilobot_twin.gap.summaries.motion` instead.

    Parameters
    ----------
    t_s : (T,) or (..., T) sample times
    x, y : (..., T) positions in m

    Returns
    -------
    omega_rad_s, speed_m_s : arrays of shape (...)
    """
    t = np.broadcast_to(np.asarray(t_s, dtype=np.float64), np.shape(x))
    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    flat_t, flat_x, flat_y = (a.reshape(-1, a.shape[-1]) for a in (t, x, y))
    omega = np.full(flat_x.shape[0], np.nan)
    speed = np.full(flat_x.shape[0], np.nan)
    for i in range(flat_x.shape[0]):
        ok = np.isfinite(flat_x[i]) & np.isfinite(flat_y[i])
        tt, xx, yy = flat_t[i, ok], flat_x[i, ok], flat_y[i, ok]
        if len(tt) < 3:
            continue
        dx, dy, dt = np.diff(xx), np.diff(yy), np.diff(tt)
        step = np.hypot(dx, dy)
        moving = step > min_step_m
        if moving.sum() < 2:
            continue
        heading = np.unwrap(np.arctan2(dy[moving], dx[moving]))
        tm = 0.5 * (tt[1:] + tt[:-1])[moving]
        omega[i] = np.polyfit(tm, heading, 1)[0]
        speed[i] = step.sum() / dt.sum()
    return omega.reshape(np.shape(x)[:-1]), speed.reshape(np.shape(x)[:-1])


def heading_bias_from_track(t_s, x, y, wheel_separation_m: float = WHEEL_SEPARATION_M):
    """Dimensionless heading bias (+ = clockwise) from tracked positions: ``b = -omega L / v``."""
    omega, speed = turn_rate_from_track(t_s, x, y)
    return heading_bias_from_turn_rate(omega, speed, wheel_separation_m)
