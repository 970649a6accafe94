"""Per-(trial, robot) summaries of observed runs: the signals the gap workflow compares.

All functions take arrays on the nominal sample grid, shaped (trials, robots, T), with NaN
where a sample is missing, and return arrays shaped (trials, robots). Measured and simulated
runs go through the same functions.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from ..batch import engine, kernel
from ..core.constants import LIGHT_READING_MAX


#: Lag over which headings and speeds are measured: long enough that tracking noise (mm)
#: is small against the displacement (1.13 cm/s x 2 s), short enough to follow curvature.
MOTION_LAG_S = 2.0

#: A track's mean heading over one lag-long block differs from the next block's by this much
#: only where the unwrapped heading slipped by a whole turn (:func:`motion`): a slip of 2 pi
#: spreads over at most two block boundaries, so one of them jumps by at least pi.
SLIP_RAD = 0.75 * math.pi


def _ffill(a):
    """Forward-fill NaNs along the last axis (leading NaNs stay NaN)."""
    ok = np.isfinite(a)
    idx = np.where(ok, np.arange(a.shape[-1]), 0)
    np.maximum.accumulate(idx, axis=-1, out=idx)
    out = np.take_along_axis(a, idx, axis=-1)
    first = np.maximum.accumulate(ok, axis=-1)
    return np.where(first, out, np.nan)


def motion(x, y, dt_s: float, lag_s: float = MOTION_LAG_S, wander_lags_s=None, speed_lags_s=(1.0, 5.0),
           threads: int = 1) -> dict:
    """Turn rate, speed, heading diffusion and mean heading of every track.

    Headings are those of displacements over ``lag_s`` (long against tracking noise). They
    are unwrapped across tracking gaps by differencing consecutive *observed* headings, and
    ``turn_rate`` is the least-squares slope of the unwrapped heading against time (rad/s,
    counter-clockwise positive), NaN where the heading slipped by a whole turn (:data:`SLIP_RAD`).
    ``speed`` is the mean lagged displacement over the lag (m/s).
    ``diffusion`` (rad^2/s) measures the heading noise by the track's sideways wander
    (:func:`wander_lags`): the second difference of position over s seconds,
    ``p(t + s) - 2 p(t) + p(t - s)``, across the chord ``p(t + s) - p(t - s)``, centred on the
    track's mean (a steady turn bends every stretch alike), has variance
    ``2/3 v^2 sigma_omega^2 s^3 + 6 e^2`` for a heading that diffuses with intensity
    sigma_omega^2 at speed v under white tracking noise of sd e per coordinate. The difference
    of that variance at the two ``wander_lags_s`` over ``2/3 v^2 (s2^3 - s1^3)`` (v: the track's
    ``speed``) estimates sigma_omega^2 (less 1.5 s2 / track length: centring takes out the
    variance of the track's mean): tracking noise cancels, and speed noise, which moves a robot
    along its path, does not count. It reads positions over seconds rather than 2 s
    chord headings, whose error (2 mm of tracking noise over a 2.3 cm chord: 0.13 rad) swamped
    the heading's own change: per track it separates robots whose sigma_omega differ by a factor
    2 by 3.3 sd at 2 mm of tracking noise, the chord headings by 0.67 (``benchmarks/bench_wander.py``).
    ``heading`` is the circular mean heading. ``speed_diffusion`` (m^2/s) is the growth rate of the
    variance of the distance covered over ``speed_lags_s``: the speed noise's sigma_v^2. Tracks
    with fewer than 10 observed headings give NaN. (For single tracks with irregular sample times,
    :func:`kilobot_twin.analysis.turn_rate_from_track` does the turn rate and speed.)

    One pass per track (:func:`_motion_tracks`, compiled with Numba where available): the
    workflow summarises thousands of simulated tracks per fit. ``threads`` share the tracks (the
    result does not depend on it).
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    lead = x.shape[:-1]
    L = max(1, int(round(lag_s / dt_s)))
    T = x.shape[-1]
    w1, w2 = (max(1, int(round(s / dt_s))) for s in (wander_lags_s or wander_lags(0.002)))
    w2 = max(min(w2, (T - 1) // 3), w1 + 1)  # at least three stretches of the longer lag per track
    s1, s2 = (max(1, int(round(s / dt_s))) for s in speed_lags_s)
    R = int(np.prod(lead))
    out = np.empty((R, 5))
    xr = np.ascontiguousarray(x.reshape(-1, x.shape[-1]))
    yr = np.ascontiguousarray(y.reshape(-1, y.shape[-1]))
    tracks = kernel.compiled(_motion_tracks)

    def rows(r0, r1):
        tracks(xr[r0:r1], yr[r0:r1], L, w1, w2, s1, s2, float(dt_s), out[r0:r1])

    # Tracks are independent and the compiled pass releases the GIL: threads share the rows.
    engine.share(rows, R, threads)
    out = out.reshape(lead + (5,))
    return {k: out[..., j] for j, k in enumerate(_MOTION_KEYS)}


_MOTION_KEYS = ("turn_rate", "speed", "diffusion", "heading", "speed_diffusion")


def wander_lags(tracking_noise_m: float) -> tuple:
    """The two lags (s) of the ``diffusion`` summary's sideways wander (:func:`motion`), for a
    tracker of this noise: 1 s (tracking noise alone, nearly) and the lag where the wander of a
    Kilobot (1.1 cm/s) with the nominal heading noise (0.01 rad/sqrt(s)) has grown to about the
    tracking noise's share, 10 s x sqrt(e / 2 mm) within 4 .. 20 s. Longer lags see more wander
    but fewer independent stretches per track; this one gave the most separation between robots
    whose noise differs, per track, from 0.5 to 8 mm (``benchmarks/bench_wander.py``). Measured and
    simulated tracks of a dataset are summarised with the same lags (the data's fitted noise)."""
    e = max(float(tracking_noise_m), 0.0)
    return 1.0, float(np.clip(10.0 * np.sqrt(e / 0.002), 4.0, 20.0))


def _motion_tracks(x, y, L, w1, w2, s1, s2, dt, out):  # pragma: no cover - compiled
    """:func:`motion` for tracks ``x``, ``y`` (R, T) into ``out`` (R, 5), in the order of ``_MOTION_KEYS``."""
    R, T = x.shape
    Th = max(T - L, 0)
    u = np.empty(Th)
    ok = np.empty(Th, np.bool_)
    dist = np.empty(T)
    for r in range(R):
        n = 0
        dist_sum, s_sum, c_sum, t_sum, u_sum = 0.0, 0.0, 0.0, 0.0, 0.0
        last, acc, first = 0.0, 0.0, 0.0
        seen = False
        refused = 0
        h = 0.0
        for j in range(Th):
            dx = x[r, j + L] - x[r, j]
            dy = y[r, j + L] - y[r, j]
            ok[j] = math.isfinite(dx) and math.isfinite(dy)
            if ok[j]:
                h = math.atan2(dy, dx)
                if seen:  # unwrap: the wrapped change since the last observed heading
                    step = h - last  # within (-2 pi, 2 pi): wrapped into [-pi, pi) without a modulo
                    if step >= math.pi:
                        step -= 2 * math.pi
                    elif step < -math.pi:
                        step += 2 * math.pi
                    # A chord that turned by over a quarter turn since the last one is a
                    # tracking error (a point centimetres off reverses a 2 cm chord), not the
                    # robot: refused, else the unwrapping slips by 2 pi. A new heading that
                    # persists for a whole lag is accepted.
                    if abs(step) > 0.5 * math.pi and refused < L:
                        ok[j] = False
                        refused += 1
                    else:
                        acc += step
                        refused = 0
                else:
                    first, seen = h, True
            if ok[j]:
                last = h
                n += 1
                # |d| and the heading's sine and cosine from the chord itself (d > 0 where atan2 is
                # defined by it); fewer transcendental calls than hypot, sin and cos.
                d = math.sqrt(dx * dx + dy * dy)
                dist_sum += d
                if d > 0.0:
                    s_sum += dy / d
                    c_sum += dx / d
                else:
                    c_sum += 1.0  # atan2(0, 0) = 0
            u[j] = first + acc
            if ok[j]:
                t_sum += j * dt
                u_sum += u[j]
        if n < 10:
            for q in range(5):
                out[r, q] = np.nan
            continue
        tm, hm = t_sum / n, u_sum / n
        sxy, sxx = 0.0, 0.0
        for j in range(Th):
            if ok[j]:
                dtj = j * dt - tm
                sxy += dtj * (u[j] - hm)
                sxx += dtj * dtj
        turn = sxy / max(sxx, 1e-12)
        # A heading that slipped by a whole turn (a run of chords turned round by tracking error,
        # each within a quarter turn of the last) leaves the track without a turn rate: the mean
        # headings of consecutive lag-long blocks then jump by over SLIP_RAD.
        prev, have = 0.0, False
        for b0 in range(0, Th, L):
            sm, cnt = 0.0, 0
            for j in range(b0, min(b0 + L, Th)):
                if ok[j]:
                    sm += u[j]
                    cnt += 1
            if cnt * 4 >= L:
                if have and abs(sm / cnt - prev) > SLIP_RAD:
                    turn = np.nan
                prev, have = sm / cnt, True
        wander = np.zeros(2)
        for q, w in enumerate((w1, w2)):
            m, ls, ss = 0, 0.0, 0.0
            for j in range(w, T - w):
                cx = x[r, j + w] - x[r, j - w]
                cy = y[r, j + w] - y[r, j - w]
                c2 = cx * cx + cy * cy
                d2x = cx - 2.0 * (x[r, j] - x[r, j - w])
                d2y = cy - 2.0 * (y[r, j] - y[r, j - w])
                if c2 > 0.0 and math.isfinite(c2) and math.isfinite(d2x) and math.isfinite(d2y):
                    side = (d2y * cx - d2x * cy) / math.sqrt(c2)  # the second difference across the chord
                    ls += side
                    ss += side * side
                    m += 1
            wander[q] = (ss - ls * ls / m) / (m - 1) if m >= 10 else np.nan
        var = np.zeros(2)
        for q, lag in enumerate((s1, s2)):
            m, ss = 0, 0.0
            for j in range(T - lag):
                ex = x[r, j + lag] - x[r, j]
                ey = y[r, j + lag] - y[r, j]
                d = math.sqrt(ex * ex + ey * ey)
                if math.isfinite(d):
                    dist[m] = d  # kept for the second pass
                    ss += d
                    m += 1
            nd = max(m, 2)
            md, sq = ss / nd, 0.0
            for j in range(m):
                sq += (dist[j] - md) ** 2
            var[q] = sq / (nd - 1)
        out[r, 0] = turn
        out[r, 1] = dist_sum / n / (L * dt)
        v = out[r, 1]
        out[r, 2] = (wander[1] - wander[0]) / (2.0 / 3.0 * v * v * dt**3 * (w2**3 - w1**3)) if v > 0.0 else np.nan
        out[r, 3] = math.atan2(s_sum, c_sum)
        out[r, 4] = (var[1] - var[0]) / ((s2 - s1) * dt)


def robust_sd(x, axis=None):
    """1.4826 x the median absolute deviation from the median, NaNs left out: the sd of a normal
    sample that a share of gross errors (glitches, slipped headings) does not move."""
    x = np.asarray(x, dtype=float)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a slice with nothing seen has no sd: NaN
        med = np.nanmedian(x, axis=axis, keepdims=True)
        return 1.4826 * np.nanmedian(np.abs(x - med), axis=axis)


def tracking_noise(x, y) -> float:
    """Position noise sd (m) of the tracker, from within-track statistics only.

    Over one frame a robot's path is straight to well below a millimetre, so the second
    difference ``p[j] - (p[j-1] + p[j+1]) / 2`` of an observed triple is tracking noise with
    variance 1.5 sd^2 per coordinate. Median absolute deviation (x 1.4826), so that glitches
    (heavy-tailed, centimetres) do not count.
    """
    d = np.concatenate([_span_difference(x, 1, centred=False).ravel(), _span_difference(y, 1, centred=False).ravel()])
    d = d[np.isfinite(d)]
    if d.size < 10:
        return 0.0
    return float(robust_sd(d) / np.sqrt(1.5))


#: Positions count as lying on a lattice (:func:`position_lattice`) when 99 % of the distinct values
#: of each coordinate lie within 5 % of a step of its grid, and the step is at least 10 um: finer
#: grids are the CSV's decimal places, far below any tracker's noise. A grid whose own error,
#: step / sqrt(12), is below ``relevant`` x the tracker's (median-based) noise adds under 1/16 of
#: its variance, spread like noise: it is left to the noise, whose frame-to-frame correlation is
#: then fitted as without a grid (the third world's files hold 5 decimals: a 10 um grid under
#: millimetres of noise).
LATTICE = {"share": 0.99, "tolerance": 0.05, "min_step_m": 1e-5, "relevant": 0.25}


def position_lattice(x, y, noise_m: float = 0.0) -> tuple | None:
    """The pixel grid that positions lie on, if they do and it matters beside the tracker's noise
    ``noise_m`` (:data:`LATTICE`): ((step_x, origin_x), (step_y, origin_y)) in metres (origin
    within one step of 0), else None.

    A camera reports positions in whole pixels where its tracker does not interpolate between
    them. A Kilobot moves 0.3-1 mm per frame, so on a millimetre pixel its position stays put for
    frames and then jumps by a pixel: one-frame second differences are mostly exactly 0, the
    median-based noise (:func:`tracking_noise`) reads 0, and the pixel's error, a sawtooth along
    the path of sd step / sqrt(12), is missing from a twin observed without it (the third world's
    3.75 mm pixel with a slow robot: tracking noise fitted 0, the diffusion's held-out deviance 107
    on null data). Each coordinate's distinct values, sorted, are mostly one step apart; the step
    is their median spacing (or a half or third of it, where the grid is visited sparsely), kept
    where :data:`LATTICE` holds, and refined with the origin by least squares on the values' grid
    indices."""
    out = []
    for a in (x, y):
        u = np.unique(np.asarray(a, dtype=float)[np.isfinite(a)])
        if u.size < 10:
            return None
        du = np.diff(u)
        p0 = float(np.median(du))
        if p0 < LATTICE["min_step_m"]:
            return None
        for k in (1, 2, 3):
            # the step as the mean of the spacings one step long (a file's decimal places round
            # each value: their median is off by up to a rounding, which a few hundred steps add
            # up to a whole step), then with the origin by least squares on the grid indices
            one = np.abs(du - p0 / k) < 0.25 * p0 / k
            if not one.any():
                continue
            n = np.rint((u - u[0]) / float(np.mean(du[one])))
            step, origin = np.polyfit(n, u, 1)
            r = (u - origin) / step
            if step > 0 and np.mean(np.abs(r - np.rint(r)) < LATTICE["tolerance"]) >= LATTICE["share"]:
                out.append((float(step), float(np.mod(origin, step))))
                break
        else:
            return None
    if lattice_sd(out) < LATTICE["relevant"] * noise_m:
        return None
    return tuple(out)


def lattice_sd(lattice) -> float:
    """The sd a pixel grid (:func:`position_lattice`) adds to a position, step / sqrt(12) (rms over
    the two coordinates); 0 without one."""
    return 0.0 if lattice is None else float(np.sqrt(np.mean([g[0] ** 2 for g in lattice]) / 12.0))


def quantize(a, step: float, origin: float, out=None):
    """Positions ``a`` reported on a pixel grid: origin + step x round((a - origin) / step)
    (NaN stays NaN). ``out``: in place, e.g. ``out=a``."""
    out = np.subtract(a, origin, out=out)
    out /= step
    np.rint(out, out=out)
    out *= step
    out += origin
    return out


def lattice_noise(x, y, lattice, dt_s: float, window_s: float = 2.0, seed: int = 0) -> float:
    """The tracker's own position noise sd (m, per coordinate, independent frames) behind
    positions reported on a pixel grid (:func:`position_lattice`), by simulation.

    On a grid, neither the median-based estimate (0, or one grid value, whatever the noise) nor
    the plain variance of one-frame second differences (of sd step / sqrt(12) per sample only where
    the noise or the frame's motion spans a pixel: a slow robot crosses pixels rarely) tells the
    noise. The tracks are smoothed (a moving mean over ``window_s``, several pixel crossings of a
    slow robot: over 1 s its path stayed wavy, and at 0.3 mm per frame on a 3.75 mm pixel the
    noise read 0.13 mm where there was none, 0.75 mm for 0.6 mm), the smooth path is observed
    through the grid with noise sigma added (the same normal draws for every sigma, so the
    statistic grows smoothly with it), and sigma is the one whose mean square of one-frame second
    differences (the largest 0.2 % left out in both, as outliers) equals the data's: 0 where the
    data vary less than the grid alone makes them. Beyond 8 steps the grid no longer matters and
    the variance is read as without one."""
    W = max(3, int(round(window_s / dt_s)))
    rng = np.random.default_rng(seed)

    def mean_square(xs, ys):
        d = np.concatenate([_span_difference(a, 1, centred=False).ravel() for a in (xs, ys)])
        d = np.sort(d[np.isfinite(d)] ** 2)
        return float(np.mean(d[: max(1, int(np.ceil(0.998 * d.size)))])) if d.size else 0.0

    def smooth(a):  # NaN-aware centred moving mean over W frames, where a is observed
        ok = np.isfinite(a)
        pad = [(0, 0)] * (a.ndim - 1) + [(1, 0)]
        c = np.pad(np.cumsum(np.where(ok, a, 0.0), -1), pad)
        n = np.pad(np.cumsum(ok, -1), pad)
        T = a.shape[-1]
        lo, hi = np.clip(np.arange(T) - W // 2, 0, T), np.clip(np.arange(T) + W // 2 + 1, 0, T)
        with np.errstate(all="ignore"):
            m = (c[..., hi] - c[..., lo]) / (n[..., hi] - n[..., lo])
        return np.where(ok, m, np.nan)

    target = mean_square(x, y)
    paths = [(smooth(a), rng.standard_normal(a.shape), g) for a, g in zip((x, y), lattice)]
    step = max(g[0] for g in lattice)
    sigmas = np.concatenate([[0.0], step * np.geomspace(0.01, 8.0, 40)])
    ms = np.array([mean_square(*(quantize(m + s * z, *g) for m, z, g in paths)) for s in sigmas])
    if target <= ms[0]:
        return 0.0
    if target >= ms[-1]:
        return float(np.sqrt(target / 1.5))
    j = int(np.argmax(ms >= target))
    t = (target - ms[j - 1]) / max(ms[j] - ms[j - 1], 1e-300)
    return float(sigmas[j - 1] + t * (sigmas[j] - sigmas[j - 1]))


def _span_difference(a, m: int, centred: bool = True):
    """a[j] - (a[j-m] + a[j+m]) / 2 where all three samples are observed, else NaN; (..., T).
    ``centred``: less the track's median of it (a steady turn bends every span alike)."""
    d = np.full(a.shape, np.nan)
    if a.shape[-1] > 2 * m:
        d[..., m:-m] = a[..., m:-m] - 0.5 * (a[..., :-2 * m] + a[..., 2 * m:])
    return _less_track_median(d) if centred else d


def _less_track_median(d):
    """``d`` less each track's median of it (NaN for tracks with none observed); (..., T)."""
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # tracks with no observed span
        return d - np.nanmedian(d, axis=-1, keepdims=True)


def _chord_parts(x, y, m: int):
    """The span-m second difference (:func:`_span_difference`) of a 2-D track split into its
    components along and across the chord ``p[j+m] - p[j-m]``, each less the track's median;
    ((..., T), (..., T)). A straight robot's speed noise moves it along the chord, its heading
    noise across; an isotropic tracker's noise is the same in both, and, by symmetry, uncorrelated
    with the chord it is projected on."""
    dx, dy = _span_difference(x, m, centred=False), _span_difference(y, m, centred=False)
    cx, cy = np.full(x.shape, np.nan), np.full(y.shape, np.nan)
    if x.shape[-1] > 2 * m:
        cx[..., m:-m] = x[..., 2 * m:] - x[..., :-2 * m]
        cy[..., m:-m] = y[..., 2 * m:] - y[..., :-2 * m]
    with np.errstate(all="ignore"):  # zero chords
        length = np.hypot(cx, cy)
        ux, uy = cx / length, cy / length
    return _less_track_median(dx * ux + dy * uy), _less_track_median(dy * ux - dx * uy)


#: What the tracking noise must show to count as correlated from frame to frame
#: (:func:`tracking_noise_correlation`): a correlated part of at least ``share`` of the noise
#: variance and at least ``sd_m``, with a frame-to-frame correlation of at least ``rho`` (at 10 Hz,
#: a correlation time of 0.062 s; below it the one-frame statistic sees 3/4 of such an error or
#: more). Below any of them frames are taken as independent: the fit's four terms do not describe a
#: path exactly (coloured heading noise, jittered sample times), and on 400 datasets with
#: independent frames (both evaluation generators, heading noise correlated up to 5 s) smaller
#: correlated parts were fitted where there were none: a frame-to-frame correlation of up to 0.14
#: with the share met (one dataset: at ``rho`` 0.1 it was read as correlated), a share of up to
#: 0.08 with ``rho`` met, of any size (up to 1.1 mm). ``sd_m`` only keeps parts too small to
#: matter out of the model; at 0.5 mm, which the fit on pooled coordinates needed, the independent
#: world's 0.42 mm over 0.48 s beside 0.76 mm independent (seed 3007, fitted 0.44-0.46 mm) was
#: read as independent frames.
CORRELATED_TRACKING_MIN = {"share": 0.2, "sd_m": 0.0002, "rho": 0.2}


def tracking_noise_correlation(x, y, dt_s: float, max_span_s: float = 2.0, max_tau_s: float = 1.0,
                               noise_m: float | None = None) -> dict:
    """The tracker's position noise when its errors persist from frame to frame (a tracker that
    smooths, a blob that changes shape slowly): independent noise of sd ``white_m`` plus noise of
    sd ``correlated_m`` whose frames correlate as rho^m at m frames (Ornstein-Uhlenbeck sampled
    every ``dt_s``: rho = exp(-dt_s / ``tau_s``)). For independent frames ``correlated_m`` and
    ``tau_s`` are 0 and ``white_m`` is :func:`tracking_noise`'s, unchanged.

    The span-m second difference ``p[j] - (p[j-m] + p[j+m]) / 2``, split into its components
    along and across the chord ``p[j+m] - p[j-m]`` (:func:`_chord_parts`), then has in each the
    variance 3/2 white^2 + correlated^2 (3/2 - 2 rho^m + rho^(2m) / 2): the same at every span
    for independent frames, rising to a plateau within a few tau for correlated ones. The robot's
    own path adds a variance that grows without a plateau, each in one component: along the chord
    as s = m dt_s for speed noise (the position along the path is a random walk), across it as s^3
    for heading noise (a steady turn adds nothing: each track's median is taken off). The robust
    variances (median-based, as :func:`tracking_noise`) of both components at spans up to
    ``max_span_s`` are fitted together with those four terms by non-negative least squares in
    relative terms, for each tau of a grid up to ``max_tau_s`` (beyond about half the longest span
    a correlated error is not told from speed noise), and the best tau kept. The tracker's noise
    is the one term both components share; fitted on the two coordinates pooled, speed noise and a
    correlated error traded off (both rise over the spans), and the correlated part came back at
    1.01 (10-90 %: 0.92-1.50) of the truth, against 1.00 (0.96-1.19) split, over the 304 evaluation
    datasets with a correlated tracker (motion, seeds 3000-3019, both generators). Spans to 2 s and
    tau to 1 s: with spans to 1 s, the independent world's tracker at 0.7 s (capped at 0.5 s) had
    left 1/4 of its variance to be read as heading noise, fitted at 8x the truth; none of 400
    evaluation datasets with independent frames (64 of them with heading noise correlated over 5 s)
    is read as correlated. Frames count as independent unless the correlated part is as large and
    as persistent as :data:`CORRELATED_TRACKING_MIN` asks. ``noise_m``: :func:`tracking_noise` of
    these tracks, where the caller has it already."""
    from scipy.optimize import nnls

    white = {"white_m": tracking_noise(x, y) if noise_m is None else float(noise_m), "correlated_m": 0.0, "tau_s": 0.0}
    spans = np.unique(np.round(np.geomspace(1, max(max_span_s / dt_s, 6.0), 10)).astype(int))
    v = []  # (along, across) per span
    for m in spans:
        parts = [d[np.isfinite(d)] for d in _chord_parts(x, y, m)]
        if min(d.size for d in parts) < 10:
            break
        v.append([robust_sd(d) ** 2 for d in parts])
    v = np.array(v)
    if len(v) < 5 or not (v[0] > 0).all():
        return white
    spans = np.repeat(spans[: len(v)], 2)
    along = np.tile([1.0, 0.0], len(v))
    v = v.ravel()
    s = spans / spans[-1]  # span lengths relative to the longest
    best = (np.inf, 0.0, 0.0, 0.0)
    for tau in np.geomspace(dt_s / 10, max_tau_s, 120):
        rho = np.exp(-dt_s / tau)
        g = 1.5 - 2.0 * rho**spans + 0.5 * rho ** (2 * spans)
        A = np.column_stack([np.full(len(v), 1.5), g, s * along, s**3 * (1 - along)]) / v[:, None]
        coef, res = nnls(A, np.ones(len(v)))
        if res < best[0]:
            best = (res, float(coef[0]), float(coef[1]), float(tau))
    _, w2, c2, tau = best
    lim = CORRELATED_TRACKING_MIN
    if not (c2 >= lim["share"] * (w2 + c2) and c2 >= lim["sd_m"] ** 2 and np.exp(-dt_s / tau) >= lim["rho"]):
        return white
    return {"white_m": float(np.sqrt(w2)), "correlated_m": float(np.sqrt(c2)), "tau_s": tau}


#: The longest stretch over which a sample is checked against the line through its observed
#: neighbours for a glitch (:func:`reject_glitches`): a robot at 1 cm/s departs from a straight
#: line over 2 s by a fraction of a millimetre.
GLITCH_SPAN_S = 2.0


def _observed_neighbours(ok):
    """Index of the previous and of the next observed sample of each frame, strictly before and
    after it (-1 and T where there is none); ok: (..., T) -> two (..., T) int arrays."""
    T = ok.shape[-1]
    idx = np.arange(T)
    prev_i = np.maximum.accumulate(np.where(ok, idx, -1), axis=-1)
    prev_i = np.concatenate([np.full(ok.shape[:-1] + (1,), -1), prev_i[..., :-1]], axis=-1)
    next_i = np.minimum.accumulate(np.where(ok, idx, T)[..., ::-1], axis=-1)[..., ::-1]
    next_i = np.concatenate([next_i[..., 1:], np.full(ok.shape[:-1] + (1,), T)], axis=-1)
    return prev_i, next_i


def _on_a_line(ok, prev_i, next_i, max_span: int):
    """The observed samples with an observed neighbour on each side at most ``max_span`` frames
    apart, read against the line between them (the rest are ends, extrapolated)."""
    T = ok.shape[-1]
    return ok & (prev_i >= 0) & (next_i < T) & (next_i - prev_i <= max_span)


def _within_span(j, span: int):
    """Whether index j (..., T) (-1 or T: none) is a sample of the track within ``span`` frames
    of the sample it is read for."""
    T = j.shape[-1]
    return (j >= 0) & (j < T) & (np.abs(j - np.arange(T)) <= span)


def _residual_2d(x, y, span: int):
    """Distance of each sample from the line (or, at an end, the extrapolation within 6 frames)
    through its observed neighbours (:func:`_interp_residual` of both coordinates)."""
    return np.hypot(_interp_residual(x, span, 6), _interp_residual(y, span, 6))


def _interp_residual(a, max_span: int = 6, end_span: int | None = None):
    """a[j] minus the straight line between its previous and next *observed* samples (at most
    ``max_span`` frames apart, else NaN): the second difference across tracking gaps; (..., T).
    A track's end is extrapolated from the two samples beside it within ``end_span`` frames
    (default ``max_span``): an extrapolation magnifies their noise by the distance over theirs."""
    end_span = max_span if end_span is None else end_span
    T = a.shape[-1]
    ok = np.isfinite(a)
    idx = np.arange(T)
    prev_i, next_i = _observed_neighbours(ok)
    valid = _on_a_line(ok, prev_i, next_i, max_span)
    pa = np.take_along_axis(a, np.clip(prev_i, 0, T - 1), -1)
    na = np.take_along_axis(a, np.clip(next_i, 0, T - 1), -1)
    w = (idx - prev_i) / np.maximum(next_i - prev_i, 1)
    out = np.where(valid, a - (pa + w * (na - pa)), np.nan)
    # Track ends (first or last observed sample): extrapolate the two observed samples beside
    # it, d2 frames apart, over d1 frames (r = d1 / d2); that residual has (1 + (1 + r)^2 + r^2)
    # noise variances (6 for adjacent frames: halved), scaled to the interior one's 1.5. (Halved
    # at every r, a sample 4 frames beyond a pair 1 frame apart was removed 9 % of the time.)
    for near, far_of in ((next_i, next_i), (prev_i, prev_i)):
        inside = (near >= 0) & (near < T)
        n1 = np.clip(near, 0, T - 1)
        n2 = np.take_along_axis(far_of, n1, -1)
        ok2 = ok & inside & _within_span(n2, end_span) & np.isnan(out)
        a1 = np.take_along_axis(a, n1, -1)
        a2 = np.take_along_axis(a, np.clip(n2, 0, T - 1), -1)
        d1, d2 = (idx - n1), (n1 - n2)
        r = d1 / np.where(d2 == 0, 1, d2)
        pred = a1 + (a1 - a2) * r
        # scaled to the interior residual's sd: (1 + (1 + r)^2 + r^2) noise variances against 1.5
        out = np.where(ok2, (a - pred) * np.sqrt(1.5 / (1 + (1 + r) ** 2 + r**2)), out)
    return out


def reject_glitches(x, y, noise_m: float, k: float = 4.5, floor_m: float = 0.001, rounds: int = 3,
                    dt_s: float | None = None):
    """Remove heavy-tailed tracking glitches: a sample farther than ``k`` x its expected sd
    (``sqrt(1.5) noise_m`` per coordinate, floored at ``floor_m``) from the line through its
    observed neighbours (2-D distance), and the farthest of its neighbourhood, the two observed
    samples on each side (a glitch of size G shows as G at its frame and about G/2 at each
    neighbour). Repeated ``rounds`` times (a glitch next to a glitch). Returns copies with those
    samples NaN and how many were removed.
    A Gaussian sample is removed with probability below exp(-k^2 / 2) = 4e-5 (3.9 sds where the
    line's ends are far apart and the sample near one: its residual's variance is up to 2, not
    1.5, noise variances; 1e-4).

    Neighbours up to :data:`GLITCH_SPAN_S` apart count (frames ``dt_s`` apart; without it, 6
    frames): a tracker that loses a robot for a second reports a few stray frames in the gap, and a false
    detection among them has no neighbour within 6 frames. Left in, one such 13 cm glitch set one
    track's heading diffusion 100x the others' and the base's heading noise 3.6x the truth (the
    third world's seed 3003: 0.0127 for 0.0035). Track ends are extrapolated within 6 frames only."""
    thr = k * max(np.sqrt(1.5) * noise_m, floor_m)
    x, y = x.copy(), y.copy()
    total = 0
    span = max(int(round(GLITCH_SPAN_S / dt_s)) if dt_s else 6, 6)
    T = x.shape[-1]
    for _ in range(rounds):
        dn = np.nan_to_num(_residual_2d(x, y, span), nan=0.0)
        # The neighbourhood: the two observed samples on each side within the span (across a
        # gap, the stray frames a line is drawn through, not the empty frames beside them).
        prev_i, next_i = _observed_neighbours(np.isfinite(x))
        near = []
        for hop, none in ((prev_i, -1), (next_i, T)):
            j = hop
            for _hop in range(2):
                inside = _within_span(j, span)
                jc = np.clip(j, 0, T - 1)
                near.append(np.where(inside, np.take_along_axis(dn, jc, -1), 0.0))
                j = np.where(inside, np.take_along_axis(hop, jc, -1), none)
        neigh = np.max(np.stack(near), axis=0)
        bad = (dn > thr) & (dn >= neigh)
        bad = _end_glitches(x, y, dn, bad, thr, span, prev_i, next_i)
        if not bad.any():
            break
        total += int(bad.sum())
        x[bad] = np.nan
        y[bad] = np.nan
    return x, y, total


def _end_glitches(x, y, dn, bad, thr, span, prev_i, next_i):
    """``bad`` with a glitch on or beside a track's end (its first or last observed sample, or
    one beside a gap longer than the span) told from its neighbours. Extrapolated from the two
    samples beside it, an end's residual is scaled to half for its noise, so a glitch G on the
    end reads G / 2 there and G / 2 at its neighbour, whose line runs to it; a glitch on the
    neighbour reads G there and G at the end. Both are ties, which the wrong sample won as
    often as not: removed, then the next sample the round after, while the glitch stayed
    (third world 3292: the last frame of a track 24 cm off, three good frames before it
    removed; that track's heading diffusion was 1,300x the median track's and the base's held-out gap on
    null data 7.5). Each of the two (end, neighbour) is tried out: a sample explains the
    residuals where, without it, each of its neighbours lies within the threshold of its own
    line or extrapolation. Where one of the two explains them (both: the one that leaves the
    smaller residual beside it), it is removed and the other kept; else the rule of
    :func:`reject_glitches` stands."""
    T = x.shape[-1]
    ok = np.isfinite(x)
    end = ok & ~_on_a_line(ok, prev_i, next_i, span) & (dn > thr)
    if not end.any():
        return bad

    def near(hop, where):  # each marked sample's neighbour on one side: (rows, columns) pairs
        j = np.where(where & _within_span(hop, span), hop, -1)
        at = np.nonzero(j >= 0)
        return at, at[:-1] + (j[at],)

    def explains(cand):  # cand: bool (..., T); whether removing each explains its neighbours
        dm = _residual_2d(np.where(cand, np.nan, x), np.where(cand, np.nan, y), span)
        worst, seen = np.zeros(x.shape), np.zeros(x.shape, bool)
        for hop in (prev_i, next_i):
            inside = _within_span(hop, span)
            r = np.take_along_axis(dm, np.clip(hop, 0, T - 1), -1)
            use = inside & np.isfinite(r)
            worst = np.where(use, np.maximum(worst, r), worst)
            seen |= use
        return cand & seen & (worst <= thr), worst

    pairs = [near(hop, end) for hop in (prev_i, next_i)]  # (end, its neighbour) on each side
    # an end's neighbours that read above the threshold and are not ends themselves
    beside = np.zeros(x.shape, bool)
    for _, nb in pairs:
        beside[nb] = True
    beside &= ~end & (dn > thr)
    (e_ok, e_left), (b_ok, b_left) = explains(end), explains(beside)
    remove, keep = np.zeros(x.shape, bool), np.zeros(x.shape, bool)
    for at, nb in pairs:
        e_x, b_x = e_ok[at], b_ok[nb]
        # where both explain, the one whose removal leaves the smaller residual beside it
        e_only = e_x & (~b_x | (e_left[at] < b_left[nb]))
        b_only = b_x & (~e_x | (b_left[nb] < e_left[at]))
        remove[tuple(a[e_only] for a in at)] = True  # the end is the glitch, its neighbour kept
        keep[tuple(a[e_only] for a in nb)] = True
        remove[tuple(a[b_only] for a in nb)] = True  # the neighbour is, the end kept
        keep[tuple(a[b_only] for a in at)] = True
    return (bad | remove) & ~(keep & ~remove)


def mask_before_onset(x, y, noise_m: float, move_m: float = 0.004):
    """NaN the samples before a robot starts moving (robots start late in real trials).

    Onset: the first sample farther than ``move_m + 4 noise_m`` from the track's first observed
    position; ``noise_m``: the sd of the tracker's whole error (the part correlated over frames
    too: a resting robot seems to wander by it). Applied to measured tracks only; the simulated
    twin then sees the same missing samples (the workflow's mask), so both are summarised over
    the same moving part."""
    first_i = np.argmax(np.isfinite(x), axis=-1)[..., None]
    x0 = np.take_along_axis(x, first_i, -1)
    y0 = np.take_along_axis(y, first_i, -1)
    far = np.hypot(x - x0, y - y0) > move_m + 4 * noise_m
    started = np.maximum.accumulate(np.nan_to_num(far.astype(float)), axis=-1) > 0
    has = started.any(-1, keepdims=True)
    onset = np.argmax(started, axis=-1)[..., None]
    keep = (np.arange(x.shape[-1]) >= onset - 1) | ~has  # keep the sample just before the move
    return np.where(keep, x, np.nan), np.where(keep, y, np.nan)


#: The reading below which a sweep is summarised by a line (:func:`light_sweep`), and above which
#: its bend is read (:func:`sensor_knee`).
KNEE_COUNTS = 600.0


def light_sweep(stimulus, reading, knee_counts: float = KNEE_COUNTS, min_stimulus: float = 0.02,
                passes: int = 3) -> dict:
    """Gain (counts per unit stimulus), offset (counts) and residual sd of each track's
    linear response, from the stimuli at which the response lies below ``knee_counts``: well
    below the ceiling (1023), where a sensor's approach to saturation (its knee, which differs
    between sensors and between worlds) bends the response by under 1 %. Nearer the ceiling,
    which samples of the bend a track happens to include varies from sweep to sweep and makes
    the fitted gain vary with it.

    The samples are chosen by their stimulus, not by their reading: a first line through the
    readings below the knee, then ``passes - 1`` lines through the samples whose stimulus the
    previous line puts below it. A cut on the noisy reading keeps the samples whose noise came
    out low near the knee and drops those whose noise came out high, which flattens the line
    in proportion to the noise (a sweep of 2.2 x 1024 counts per unit: the slope 0.82 of the
    truth at 100 counts of reading noise, 0.97 chosen by stimulus). The workflow reads the twin's
    and the data's sweeps alike, so the flattening cancelled where the twin's reading noise was
    the data's; but where another world's sweeps vary for another reason (ambient light that
    wanders over tens of seconds, which the twin's fit takes in as white reading noise of 10x
    the world's), it set the fitted gains 10 % above the truth (the third world, seeds 3068 and
    3070)."""
    ok = np.isfinite(reading) & np.isfinite(stimulus) & (stimulus > min_stimulus)
    use = ok & (reading < knee_counts)
    s_all = np.where(ok, stimulus, 0.0)
    r_all = np.where(ok, reading, 0.0)

    def line(use):
        # From the sums of s, r, s^2 and s r over the samples in use (a pass each, no centred
        # temporaries the size of the sweeps: 1.6x faster). A sweep's stimuli spread over much of
        # their range, so taking the means off afterwards loses a digit or two of 16.
        s = np.where(use, s_all, 0.0)
        r = np.where(use, r_all, 0.0)
        n = np.count_nonzero(use, axis=-1).astype(float)
        nn = np.maximum(n, 1)
        ms, mr = s.sum(-1) / nn, r.sum(-1) / nn
        var = np.maximum(np.einsum("...t,...t->...", s, s) - n * ms * ms, 0.0)
        cov = np.einsum("...t,...t->...", s, r) - n * ms * mr
        gain = cov / np.maximum(var, 1e-12)
        return gain, mr - gain * ms, n, ms, var

    gain, offset, n, ms, var = line(use)
    for _ in range(passes - 1):
        with np.errstate(invalid="ignore"):
            below = offset[..., None] + gain[..., None] * s_all < knee_counts
        nxt = ok & below
        # (a line that has no 5 samples below the knee, or none at all, keeps the previous choice)
        keep = (np.count_nonzero(nxt, axis=-1) >= 5) & np.isfinite(gain)
        use = np.where(keep[..., None], nxt, use)
        gain, offset, n, ms, var = line(use)
    resid = np.where(use, reading - (offset[..., None] + gain[..., None] * stimulus), 0.0)
    sd = np.sqrt((resid**2).sum(-1) / np.maximum(n - 2, 1))
    # What rounding to whole counts alone (variance 1/12 per reading) makes the fitted gain and
    # offset vary by: differences below it are the ADC's, not the sensor's.
    q = 1.0 / 12.0
    floors = {"gain_floor": q / np.maximum(var, 1e-12), "offset_floor": q * (1.0 / np.maximum(n, 1) + ms**2 / np.maximum(var, 1e-12))}
    bad = n < 5
    return {k: np.where(bad, np.nan, v) for k, v in {"gain": gain, "offset": offset, "residual_sd": sd, **floors}.items()}


#: The knees :func:`sensor_knee` chooses from (the twin's soft clip, ``SensorModel.knee``): from a
#: sensor that bends over hundreds of counts below its ceiling (2.1) to one all but straight up
#: to it (68), 12 % apart, through the twin's own 6; 0 is a hard clip.
KNEE_GRID = 6.0 * 2.0 ** (np.arange(-9, 22) / 6.0)


def sensor_knee(stimulus, reading, gain, offset, knee_counts: float = KNEE_COUNTS,
                ceiling: float = LIGHT_READING_MAX) -> float | None:
    """How the sensors bend towards their ceiling, as the twin's soft clip y / (1 + (y / c)^p)^(1/p)
    (``SensorModel.knee`` = p; 0 for a hard clip at c): the p of :data:`KNEE_GRID` (or the hard
    clip) whose bend fits the readings best (least squares) where each track's line from below
    ``knee_counts`` (``gain``, ``offset`` (K, N), from :func:`light_sweep`) runs above it, up to
    twice the ceiling. None where fewer than 20 readings lie there.

    The bend below the cut is what matters: it is under 1 % at 600 counts for every knee of the
    grid from p = 4, but a robot whose offset shifts from trial to trial moves along it, which moves
    its fitted gain too. A twin that bends more than the data's sensor (the twin's p = 6 against
    another world's 9) made its gains vary 4-5x as much as a noiseless sensor's from sweep to sweep."""
    with np.errstate(invalid="ignore"):
        y = offset[..., None] + gain[..., None] * stimulus
        use = np.isfinite(reading) & np.isfinite(y) & (y > knee_counts) & (y < 2.0 * ceiling)
    if use.sum() < 20:
        return None
    y, r = y[use], reading[use]
    p = KNEE_GRID[:, None]
    soft = np.minimum(y / (1.0 + (y / ceiling) ** p) ** (1.0 / p), ceiling)
    sse = np.append(((r - soft) ** 2).sum(-1), ((r - np.minimum(y, ceiling)) ** 2).sum())
    best = int(np.argmin(sse))
    return float(KNEE_GRID[best]) if best < len(KNEE_GRID) else 0.0


def blink(led, dt_s: float, threads: int = 1) -> dict:
    """Toggle rate (toggles per second) of each track from its LED samples (0/1, NaN = missing).

    A camera's colour classification is not a clean square wave: a misread frame is two spurious
    toggles one frame apart, and a loss of frames can hide a whole on or off phase. Counting colour
    changes, as a first version did, read such a track's rate up to 50 % high (a third world,
    ``benchmarks/stress_world.py``, misclassifying 0.1-1 % of frames), and the spread of the
    spurious counts between trials swamped the clocks' own. So, per track:

    1. the observed samples are cut into runs of one colour (missing frames ignored);
    2. the shortest run inside the track, while its extent (first to last sample) is under half
       the median run's, is a misread: it is removed and its neighbours, of one colour, joined
       (one at a time, the median taken again each time). A run at either end is cut by the
       recording: a short one is a misread only if its toggle also falls more than a quarter
       phase off the grid of the others;
    3. a toggle is timed at a run's first sample. The anchors are the toggles seen sharp (the
       sample before each observed too: timed to a frame, not to the end of a loss); between two
       consecutive anchors the phases passed are the whole number nearest their spacing over a
       phase's length, odd where the colours after them differ and even where they agree (a lost
       phase, or a real one removed in step 2, is counted back). A phase's length is first the
       median spacing of toggles, then the mean spacing of the phases counted, until the count
       settles;
    4. the rate is the phases counted from the first anchor to the last over the time between.

    On a clean square wave every spacing counts 1 and the rate is (toggles - 1) / (last toggle -
    first toggle), the plain count. Where the median run spans two samples or fewer, a misread is
    not told from a phase: steps 2 and 3 are skipped (each spacing counts 1). Three toggles at
    least, else NaN. Vectorised over all leading axes (one compiled pass per track).

    ``toggle_rate_floor``: the variance that rounding the first and the last toggle to frames
    gives the rate where the clock's place in its cycle is not known to within a frame, (rate dt /
    span)^2 / 6 (two uniform roundings of a frame; span: the track's first to last observed
    sample, a little longer than its first to last toggle).
    """
    led = np.asarray(led, float)
    lead = led.shape[:-1]
    rows = np.ascontiguousarray(led.reshape(-1, led.shape[-1]))
    R = rows.shape[0]
    out = np.empty(R)
    rates = kernel.compiled(_toggle_rates)

    def part(r0, r1):
        rates(rows[r0:r1], out[r0:r1])

    engine.share(part, R, threads)
    rate = (out / dt_s).reshape(lead)
    seen = np.isfinite(led)
    first, last = np.argmax(seen, axis=-1), led.shape[-1] - 1 - np.argmax(seen[..., ::-1], axis=-1)
    with np.errstate(all="ignore"):
        floor = (rate / np.maximum(last - first, 1)) ** 2 / 6.0
    return {"toggle_rate": rate, "toggle_rate_floor": floor}


def _toggle_rates(led, out):  # pragma: no cover - compiled
    """:func:`blink`'s steps 1-4 for tracks ``led`` (R, T): phases per sample into ``out`` (R,)."""
    R, T = led.shape
    col = np.empty(T, np.int64)
    beg = np.empty(T, np.int64)
    end = np.empty(T, np.int64)
    sharp = np.empty(T, np.int64)
    for r in range(R):
        m = 0
        for j in range(T):  # 1. runs of one colour over the observed samples
            v = led[r, j]
            if not math.isfinite(v):
                continue
            c = 1 if v > 0.5 else 0
            if m > 0 and col[m - 1] == c:
                end[m - 1] = j
            else:
                col[m] = c
                beg[m] = j
                end[m] = j
                m += 1
        if m >= 3 and np.median((end[:m] - beg[:m] + 1).astype(np.float64)) <= 2.0:
            coarse = True  # phases of a frame or two: a misread is not told from a phase
        else:
            coarse = False
        while m >= 3 and not coarse:  # 2. misreads inside the track out, shortest first
            ext = (end[:m] - beg[:m] + 1).astype(np.float64)
            i = 1 + int(np.argmin(ext[1:m - 1]))
            if ext[i] >= 0.5 * np.median(ext):
                break
            end[i - 1] = end[i + 1]  # its neighbours (one colour) become one run
            col[i:m - 2], beg[i:m - 2], end[i:m - 2] = col[i + 2:m].copy(), beg[i + 2:m].copy(), end[i + 2:m].copy()
            m -= 2
        if m >= 5 and not coarse:  # a short run at either end: a misread only off the phase grid
            h = np.median((beg[2:m] - beg[1:m - 1]).astype(np.float64))
            d = (beg[2] - beg[1]) / h  # (a quarter phase or more from an odd number of phases)
            if end[0] - beg[0] + 1 < 0.5 * h and abs(d - 2.0 * math.floor((d - 1.0) / 2.0 + 0.5) - 1.0) > 0.25:
                col[:m - 1], beg[:m - 1], end[:m - 1] = col[1:m].copy(), beg[1:m].copy(), end[1:m].copy()
                m -= 1
            d = (beg[m - 1] - beg[m - 2]) / h
            if end[m - 1] - beg[m - 1] + 1 < 0.5 * h and abs(d - 2.0 * math.floor((d - 1.0) / 2.0 + 0.5) - 1.0) > 0.25:
                m -= 1
        if m < 4:  # three toggles at least (run starts 1..m-1)
            out[r] = np.nan
            continue
        if coarse:
            out[r] = (m - 2) / (beg[m - 1] - beg[1])
            continue
        # 3. anchors: the toggles seen sharp (the sample before each observed too), else all
        ns = 0
        for k in range(1, m):
            if end[k - 1] == beg[k] - 1:
                sharp[ns] = k
                ns += 1
        if ns < 3:
            ns = m - 1
            sharp[:ns] = np.arange(1, m)
        # a phase's length: first the median spacing of toggles one run apart, then the mean
        # spacing of the phases counted, until the count settles
        h = np.median((beg[2:m] - beg[1:m - 1]).astype(np.float64))
        phases, last = 0.0, -1.0
        for _ in range(6):
            phases = 0.0
            for i in range(1, ns):  # the whole number nearest each spacing, of the colours' parity
                k0, k1 = sharp[i - 1], sharp[i]
                x = (beg[k1] - beg[k0]) / h
                if col[k1] != col[k0]:
                    c = 2.0 * math.floor((x - 1.0) / 2.0 + 0.5) + 1.0
                else:
                    c = max(2.0 * math.floor(x / 2.0 + 0.5), 2.0)
                phases += c
            if phases == last:
                break
            last = phases
            h = (beg[sharp[ns - 1]] - beg[sharp[0]]) / phases
        out[r] = phases / (beg[sharp[ns - 1]] - beg[sharp[0]])  # 4.


#: How many standard errors a lens's radial distortion must stand from 0 for :func:`lens_distortion`
#: to report it (the data's positions are then undistorted by it; a world without one reads 0 +- 1 se).
LENS_Z = 5.0

#: Where a camera's optical axis lies, a priori: about the middle of the field its positions span,
#: within this share of the field's extent per axis (sd). Calibrated cameras put the principal
#: point within a few per cent of the image's size of its centre, and a camera hung over an arena
#: is centred on it by eye (:func:`lens_distortion` weighs the data's centre against it).
LENS_AXIS_SD = 0.03


def lens_distortion(x, y, dt_s: float, lag_s: float = 4.0, z: float = LENS_Z, axis_m=None,
                    axis_sd_m: float | None = None) -> dict | None:
    """The camera's residual radial distortion, read off how a robot's chords lengthen across
    the field: a first-order radial lens maps a true position p to c + q (1 + k |q|^2), q = p - c,
    so a chord of true length l in direction u with midpoint m is seen l (1 + k (|q|^2 + 2 (q.u)^2))
    long. A robot's speed is steady within a track, so log chord length less each track's mean
    is linear in G = |m|^2 + 2 (m.u)^2 with coefficient k, in H = m + 2 (m.u) u with coefficient
    -2 k c, and in u_x^2 and u_x u_y (terms of c's square). (A linear trend in time per track,
    against speeds that drift over a trial, was tried: a straight robot's H is linear in time,
    so the trend took the centre with it, and k's standard error grew 5-8x.)

    The midpoints and directions are seen through the lens too, which understates k by about
    2 k |q|^2 of itself (12 % at 6e-2 / m^2 over a field 0.8 m across): the tracks are
    undistorted with the estimate and what is left estimated again, three times. Chords over
    ``lag_s``; chords more than 5 robust sds off the fit are dropped and it is refitted. The
    standard error is the jackknife's over tracks (overlapping chords share their errors).

    The centre the chords give (``centre_data_m``, its jackknife se ``centre_se_m``) is weighed
    against a prior at the middle of the field the positions span (``centre_prior_m``, sd
    :data:`LENS_AXIS_SD` of its extent: ``centre_prior_sd_m``), each by its precision: ``centre_m``.
    Where the user knows where the camera's axis meets the floor (``axis_m``, (x, y) in m; with
    ``axis_sd_m``, how well, else the same sd), the prior sits there instead: robots that keep to
    part of the frame put the middle of their span elsewhere.

    Returns ``{"k1_per_m2", "centre_m": (cx, cy), "k1_se", "z", ...}`` where |k| stands ``z``
    standard errors from 0, else None (no lens to model)."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    first = _lens_pass(x, y, dt_s, lag_s)
    if first is None:
        return None
    k, c, se, se_h = first
    if not abs(k) > z * se:
        return None
    for _ in range(3):
        lens = {"k1_per_m2": k, "centre_m": c}
        more = _lens_pass(*lens_undistort(x, y, lens), dt_s, lag_s)
        if more is None:
            break
        dk, dc, se, se_h = more
        # the residual lens composes with the first to first order: the k's add, and the centre
        # is their k-weighted mean (both stretch by k |p - c|^2, whose terms linear in p add)
        c = tuple((k * np.asarray(c) + dk * np.asarray(dc)) / (k + dk)) if abs(k + dk) > 0 else c
        k += dk
    # The centre rests on how chords lengthen along x and y, which at a few per cent of distortion
    # pins it to several cm only (the jackknife's se, of -2 k c over 2 |k|). Third world 3308 and
    # 3319 (40 robots, k1 -0.025 and -0.075 / m^2): centres read 8 and 7 cm off the true axis (1.6
    # and 1.8 se), and the positions undistorted about them left a speed that followed the heading
    # (flagged at z 3.7; about the true axis, or about the field's middle, nothing was flagged). So
    # the centre is weighed against where a camera's axis lies: near the middle of the field it
    # sees (a principal point is within a few per cent of the image's size of its centre, and a
    # camera over an arena is centred by eye), sd LENS_AXIS_SD of the field's extent per axis;
    # the data's centre counts by its own se. k stays the joint fit's, whose se allows for the
    # centre's error (k refitted about the weighed centre had a se that did not: its errors
    # scattered by 1.6 of it, on the tests' own lens worlds).
    se_c = np.asarray(se_h, dtype=float) / (2 * abs(k))
    lo, hi = (np.nanpercentile(np.stack([x.ravel(), y.ravel()]), q, axis=1) for q in (0.5, 99.5))
    prior, tau = (lo + hi) / 2, LENS_AXIS_SD * (hi - lo)
    if axis_m is not None:
        prior = np.asarray(axis_m, dtype=float)
    if axis_sd_m is not None:
        tau = np.full(2, float(axis_sd_m))
    w = tau**2 / (tau**2 + se_c**2)
    data_c = np.asarray(c, dtype=float)
    c = tuple(prior + w * (data_c - prior))
    return {"k1_per_m2": float(k), "centre_m": (float(c[0]), float(c[1])), "k1_se": float(se), "z": float(abs(k) / se),
            "centre_data_m": (float(data_c[0]), float(data_c[1])), "centre_se_m": (float(se_c[0]), float(se_c[1])),
            "centre_prior_m": (float(prior[0]), float(prior[1])), "centre_prior_sd_m": (float(tau[0]), float(tau[1]))}


def _lens_pass(x, y, dt_s, lag_s):
    """One least-squares pass of :func:`lens_distortion`: (k, centre, se of k, se of the two
    coefficients -2 k c) or None."""
    L = max(1, int(round(lag_s / dt_s)))
    T = x.shape[-1]
    if T <= 3 * L:
        return None
    x2, y2 = x.reshape(-1, T), y.reshape(-1, T)
    a, b = slice(L, T - 2 * L), slice(2 * L, T - L)  # chords from frame j (L..T-2L-1) to j + L
    dx, dy = x2[:, b] - x2[:, a], y2[:, b] - y2[:, a]
    mx, my = (x2[:, b] + x2[:, a]) / 2, (y2[:, b] + y2[:, a]) / 2
    # the direction from frames j - L to j + 2 L, whose errors are not the chord's own: a
    # direction read off the chord itself turns with the error that lengthens it (at 8 mm of
    # tracking noise on 3 cm chords that read k = 0.28 / m^2 where there was no lens)
    wx, wy = x2[:, 3 * L:] - x2[:, :T - 3 * L], y2[:, 3 * L:] - y2[:, :T - 3 * L]
    length, wide = np.hypot(dx, dy), np.hypot(wx, wy)
    ok = np.isfinite(length) & (length > 0) & np.isfinite(wide) & (wide > 0)
    n_tracks = x2.shape[0]
    track = np.broadcast_to(np.arange(n_tracks)[:, None], ok.shape)[ok]
    ux, uy = wx[ok] / wide[ok], wy[ok] / wide[ok]
    mx, my = mx[ok], my[ok]
    mu = mx * ux + my * uy
    X = np.column_stack([mx**2 + my**2 + 2 * mu**2, mx + 2 * mu * ux, my + 2 * mu * uy, ux**2, ux * uy])
    Y = np.log(length[ok])
    if len(Y) < 10 * X.shape[1] or (np.bincount(track, minlength=n_tracks) >= 2).sum() < 3:
        return None
    use = np.ones(len(Y), bool)
    for _ in range(3):
        # each track's mean out: a within-track regression
        A, B = _within(X, track, use, n_tracks), _within(Y[:, None], track, use, n_tracks)[:, 0]
        beta = np.linalg.lstsq(A[use], B[use], rcond=None)[0]
        r = B - A @ beta
        used, use = use, use & (np.abs(r) <= 5 * robust_sd(r[use]))
        if np.array_equal(use, used):
            break
    use = used
    A, B, track = A[use], B[use], track[use]
    AtA = A.T @ A
    if np.linalg.matrix_rank(AtA) < AtA.shape[0]:
        return None
    # the standard error by the jackknife over tracks (each track's chords share their errors,
    # and tracks at the field's edge carry most of G's spread: the sandwich clustered on tracks
    # understated it by 20-30 % with 48 tracks of 60 s; theory-free and cheap from each track's
    # sums of squares, as the tracks are contiguous rows)
    edges = np.flatnonzero(np.diff(track)) + 1
    parts = [(a.T @ a, a.T @ b) for a, b in zip(np.split(A, edges), np.split(B, edges))]
    AtB = A.T @ B
    drop = []
    for aa, ab in parts:
        try:
            drop.append(np.linalg.solve(AtA - aa, AtB - ab)[:3])
        except np.linalg.LinAlgError:
            return None
    drop = np.asarray(drop)
    G = len(drop)
    if G < 3:
        return None
    se = np.sqrt((G - 1) / G * np.sum((drop - drop.mean(0)) ** 2, axis=0))
    k = float(beta[0])
    if not (np.isfinite(se).all() and se[0] > 0 and k != 0):
        return None
    return k, (float(-beta[1] / (2 * k)), float(-beta[2] / (2 * k))), float(se[0]), se[1:]


def _within(a, track, use, n_tracks):
    """``a`` (n, p) less its mean over each track's used rows."""
    w = use.astype(float)
    cnt = np.bincount(track, weights=w, minlength=n_tracks)
    out = np.empty_like(a)
    for j in range(a.shape[1]):
        sm = np.bincount(track, weights=a[:, j] * w, minlength=n_tracks)
        with np.errstate(all="ignore"):
            out[:, j] = a[:, j] - np.nan_to_num(sm / cnt)[track]
    return out


def lens_undistort(x, y, lens: dict | None, iterations: int = 8):
    """Positions on the floor from positions (any shape) a camera with ``lens``
    (:func:`lens_distortion`) reported, inverting c + q (1 + k |q|^2) by fixed-point iteration
    (|k| |q|^2 is a few per cent)."""
    if lens is None:
        return x, y
    (cx, cy), k = lens["centre_m"], lens["k1_per_m2"]
    ox, oy = x - cx, y - cy
    qx, qy = ox, oy
    for _ in range(iterations):
        f = 1 + k * (qx * qx + qy * qy)
        qx, qy = ox / f, oy / f
    return cx + qx, cy + qy
