"""``kilobot-twin gap``: hold the twin against measured data.

1. **Simulate** the current model under the data's conditions (robots, trials, durations, start
   poses, sampling, observed samples) many times.
2. **Detect** disagreement: per-(trial, robot) summaries give statistics (between-robot F ratios,
   trial trends, levels, speed-vs-heading dependence) whose null distribution under the current
   model comes from those simulations; a statistic is flagged when its calibrated p-value is
   below ``alpha`` / (number of statistics). **Localise** it to robots and trials by z-scores of
   their means against the simulated ones.
3. **Name** the effect: every candidate of the library is fitted on all but one trial and scored
   by the log-likelihood of the held-out trial's summaries under its predictive
   distribution (leave-one-trial-out): Gaussian within 4 sd, with tails for gross errors
   (:func:`log_density`); its spread is the simulated spread of the fitted model plus the
   estimation error of the parameters fitted on the other trials (``effects.leverage``), per
   robot, also through the spread where the fitted level sets it (``effects.spread_leverage``);
   a bootstrap over robots gives intervals. The
   best is named only if its gain over the current model and over the runner-up both have a
   95 % interval above zero. Otherwise the disagreement is ``unexplained``.
4. **Add** it: its per-robot parameters, fitted on all trials, go into the model.
5. **Show the gap shrink**: on held-out trials, the excess mean deviance (squared z-score, linear
   beyond 4 sd: :func:`deviance`) of measured summaries against simulations of the base and of the final model (0 = as good as the
   model's own predictive spread, which a right model is in expectation), with 95 % bootstrap
   intervals over robots. Repeat from 2.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import json
import math
import os
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import __version__
from ..core.constants import BODY_RADIUS_M
from ..core.kinematics import heading_bias_from_turn_rate
from ..recording import measured
from ..errors import ConfigError
from . import effects as E
from . import summaries, synth
from .model import COMPONENTS, Conditions, measured_summaries, simulate, total_tracking_noise


#: One-sided confidence of the naming rule's clause 1 (gain over the current model) and of its
#: clause 2 and parsimony (gain over the runner-up, or over the simpler model an extension
#: contains: the lower end of a 95 % interval). See :func:`decide`.
GAIN_LEVEL = 0.90
RIVAL_LEVEL = 0.975


@dataclass
class GapSettings:
    """Workflow settings. ``library`` maps names to the :class:`effects.Effect` objects that are
    candidates (default: the built-in library); add your own effect there."""

    seed: int = 0
    alpha: float = 0.01
    m_null: int = 120
    m_ref: int = 20  # replicates per reference simulation of a fit on all trials
    m_fold: int = 10  # ... of a fit on the training trials of one fold (held-out scoring)
    m_score: int = 30
    boot: int = 500
    gain_level: float = GAIN_LEVEL  # one-sided confidence of the naming rule's clause 1 (see decide)
    max_steps: int = 4
    threads: int = field(default_factory=lambda: min(2, os.cpu_count() or 1))  # folds fitted at once
    library: dict = field(default_factory=lambda: dict(E.LIBRARY))


_PURPOSE = {"base_ref": 1, "base_probe": 2, "effect_ref": 3, "effect_resim": 4, "heldout": 5, "null": 6, "bootstrap": 7, "power": 8,
            "sensitivity": 9, "base_level": 10, "shared": 11, "nuisance_ci": 12}


def child_seed(root: int, purpose: str, *keys: int) -> int:
    """An independent seed for one purpose of the workflow: the child of ``root`` at
    ``spawn_key = (purpose, *keys)`` (what ``SeedSequence(root).spawn`` hands out, addressed by
    key rather than by the order of spawning, so that caching a fit does not shift any stream).
    The null of the next round and the check that a name resolves a signal share a key on purpose:
    both ask whether the same model flags the same signal."""
    ss = np.random.SeedSequence(root, spawn_key=(_PURPOSE[purpose], *(int(k) for k in keys)))
    return int(ss.generate_state(1, dtype=np.uint32)[0])


# --- statistics ------------------------------------------------------------------------------

#: The least within-robot mean square the F statistics count, relative to the summary's level
#: squared (a part in 10^4): where a summary has no noise at all (no speed noise and no tracking
#: noise), its within-robot scatter is rounding and numerical residue, and an F ratio over it
#: would compare residues between data and simulation instead of robots.
_REL_RESOLUTION = 1e-4


def _rel_floor(x):
    with np.errstate(all="ignore"):
        return (_REL_RESOLUTION * np.nanmean(np.abs(x), axis=(-2, -1))) ** 2


def _predictive_floor(kind: str, x, data, simulated_var: float = 0.0) -> float:
    """The least variance a robot's summary is predicted with on held-out trials (:func:`_heldout`)
    and emulated with (:func:`minimum_detectable`): a part in 10^4 of the level squared of ``x``
    (..., K, N; :func:`_rel_floor`), so that a deterministic prediction cannot turn a tiny
    mismatch into an infinite log-likelihood. A light sweep's summaries are floored lower: at the
    replicates' own variance ``simulated_var`` where they vary at all, else at the within-robot
    variance of the data's summaries ``data`` (K, N) where that is above 0. A sensor that reads
    without noise varies from sweep to sweep by how its trial's offset meets the ADC's rounding,
    which the twin reproduces at the data's stimuli (:func:`model.sweep_readings`), and that can
    be half a part in 10^4 of the gain: another world's noiseless sensor (independent world 22,
    21 robots x 5 trials) varied by an sd of 0.102 counts per unit within a robot, the floor's
    was 0.156, and its held-out null gains read a mean z^2 of 0.40, as did every candidate's,
    which divided what a right sensor gain gains by 2.5 (tests/gap/test_indep_world.py). The
    data's own variance is not the floor where the replicates vary: it holds each track's share
    of the rounding that the twin, reading at that track's stimuli, predicts in its mean (there
    0.102 against the 0.081 the world's tracks vary by over its offsets' draws), and floored
    there the same null read 0.63."""
    floor = float(_rel_floor(x))
    if kind != "light_sweep":
        return floor
    v = simulated_var if simulated_var > 0.0 else float(E.within_var(np.asarray(data, dtype=float)))
    return min(float(v), floor) if v > 0.0 else floor


def _robot_weights(v):
    """Each robot's weight in the F statistics, 1 / its variance ``v`` (N,) under the model,
    scaled to a mean of 1 over robots (so robots alike weigh 1 each and the statistics keep the
    summary's units); None: every robot weighs 1."""
    v = None if v is None else np.asarray(v, dtype=float)
    if v is None or not np.all(np.isfinite(v) & (v > 0)):  # a model without noise: nothing to weigh by
        return 1.0
    w = 1.0 / v
    return w / np.mean(w)


def _mean_squares(x, v=None):
    """One-way ANOVA of robots over trials: the between-robot and the within-robot mean square;
    x (..., K, N) -> ((...), (...)). ``v`` (N,): each robot's variance under the model
    (:func:`model_variances`): each robot's squares count in its own units (:func:`_robot_weights`),
    about the mean of robots weighed alike, so that robots whose noise differs, as the model says,
    are compared as robots alike are; None: robots alike."""
    w = _robot_weights(v)
    with np.errstate(all="ignore"):
        m_i = np.nanmean(x, axis=-2, keepdims=True)
        n_i = np.isfinite(x).sum(-2, keepdims=True)
        if v is None:
            m = np.nanmean(x, axis=(-2, -1), keepdims=True)
        else:
            m = np.nansum(n_i * w * m_i, axis=(-2, -1), keepdims=True) / np.sum(n_i * w, axis=(-2, -1), keepdims=True)
        N = x.shape[-1]
        msb = np.nansum(n_i * w * (m_i - m) ** 2, axis=(-2, -1)) / (N - 1)
        msw = np.nansum(w * (x - m_i) ** 2, axis=(-2, -1)) / np.maximum(np.isfinite(x).sum((-2, -1)) - N, 1)
        return msb, msw


def _f_between(x, floor=None, v=None):
    """One-way ANOVA F of robots over trials (its log); x (..., K, N) -> (...). ``floor`` (...;
    optional): the least within-robot mean square that counts (a measurement's resolution), at
    least :data:`_REL_RESOLUTION` of the level. ``v``: robots' variances, see :func:`_mean_squares`."""
    floor = _rel_floor(x) if floor is None else np.maximum(floor, _rel_floor(x))
    msb, msw = _mean_squares(x, v)
    with np.errstate(all="ignore"):
        return np.log(msb / np.maximum(msw, floor))


def _ms_between(x, v=None):
    """The between-robot mean square alone (its log): how far robots' means spread, with no
    within-robot yardstick (see :func:`detect`)."""
    with np.errstate(all="ignore"):
        return np.log(np.maximum(_mean_squares(x, v)[0], 1e-300))


def _log_scale(x):
    """A noise summary on a log scale, where robots that differ in noise intensity by a factor
    differ by a step and scatter alike: asinh(x / (2 m)), m the median |x| over the tracks of the
    array (per replicate: the leading axes), which is log(x / m) above m and linear through 0
    (a summary that is a difference of variances can be negative). On the summary itself, one
    robot e^1.6 noisier than the rest scatters within itself 25x as much and hides the robots'
    differences in the F ratio's within-robot mean square; synth's robots, sigma_omega x exp(N(0,
    0.8)), were flagged in 1 of 5 datasets."""
    with np.errstate(all="ignore"):
        m = np.nanmedian(np.abs(x), axis=(-2, -1), keepdims=True)
        return np.arcsinh(x / (2.0 * np.where(m > 0, m, 1.0)))


def _f_noise(x):
    """F of robots over trials for a noise summary: :func:`_f_between` on :func:`_log_scale`."""
    return _f_between(_log_scale(x))


def _f_trend(x, v=None):
    """F of per-robot linear trends over trials against per-robot means; x (..., K, N). ``v``:
    robots' variances about their lines, see :func:`_trend_squares`."""
    ms_trend, ms_res = _trend_squares(x, v)
    with np.errstate(all="ignore"):
        return np.log(ms_trend / np.maximum(ms_res, _rel_floor(x)))


def _ms_trend(x, v=None):
    """The per-robot trends' mean square alone (its log), with no residual yardstick (see
    :func:`detect`)."""
    with np.errstate(all="ignore"):
        return np.log(np.maximum(_trend_squares(x, v)[0], 1e-300))


def _trend_squares(x, v=None):
    """Per-robot lines over trials: the trends' mean square and the residual mean square about
    the lines; x (..., K, N) -> ((...), (...)). ``v`` (N,): each robot's variance about its line
    under the model, whose squares then count in its own units (:func:`_robot_weights`); None:
    robots alike."""
    w = _robot_weights(v)
    K, N = x.shape[-2:]
    about_line, about_mean, _ = E.line_residuals(x)
    with np.errstate(all="ignore"):
        ss0 = np.nansum(w * about_mean**2, axis=(-2, -1))
        ss1 = np.nansum(w * about_line**2, axis=(-2, -1))
        return (ss0 - ss1) / N, ss1 / max(N * (K - 2), 1)


def _heading_dependence(v, h):
    """Speed's dependence on heading, as an F ratio on the normal scale: each robot's trial speeds
    and the cos and sin of the trial's mean heading, centred on that robot's means (per-robot
    speed differences and headings do not count), pooled regression of speed on the two; the
    regression's mean square over the residual's, F, read as the normal quantile of its upper
    tail under F(2, dof) (:func:`_f2_normal_score`). The data's own residual is the yardstick, so
    the null does not rest on the fitted speed noise: as an amplitude (the regression's relative
    size) it flagged 2 of 20 null datasets of the randomised synth evaluation (seeds 1017, 1019:
    speed noise 1.5-1.9x nominal under 3-5 mm tracking noise, fitted as 0), z 6.9.
    Works on (K, N) or (M, K, N)."""
    with np.errstate(all="ignore"):
        ok = np.isfinite(v) & np.isfinite(h)
        cols = [np.where(ok, a, np.nan) for a in (v, np.cos(h), np.sin(h))]
        dv, dc, ds = (np.nan_to_num(a - np.nanmean(a, axis=-2, keepdims=True)) for a in cols)

        def S(a, b):
            return (a * b).sum((-2, -1))

        svv, scv, ssv, scc, sss, scs = S(dv, dv), S(dc, dv), S(ds, dv), S(dc, dc), S(ds, ds), S(dc, ds)
        det = scc * sss - scs**2
        ss_reg = np.where(det > 0, (sss * scv**2 - 2 * scs * scv * ssv + scc * ssv**2) / np.where(det > 0, det, 1), 0.0)
        dof = np.maximum(ok.sum((-2, -1)) - (ok.sum(-2) > 0).sum(-1) - 2, 1)
        ms_res = np.maximum((svv - ss_reg) / dof, _rel_floor(np.where(ok, v, np.nan)))
        return _f2_normal_score(np.maximum(ss_reg / 2, 0.0) / ms_res, dof)


def _f2_normal_score(F, dof):
    """An F ratio with 2 numerator degrees of freedom as the standard normal quantile of its
    upper tail under F(2, dof), whose survival function is (1 + 2 F / dof)^(-dof / 2): N(0, 1)
    where the regression's assumptions hold, so the simulated null's mean and sd (the calibrated
    p of :func:`_p_value`) correct only what they miss. On its log the null is far from normal
    (log of an exponential, near dof -> inf: a long left tail, sd 1.28), and the null's mean +
    z sd there stood at log F 2.7-3.4 over ten nulls of one dataset (independent world, 36 robots
    x 5 trials, dof 139, family level 0.0017, z 2.94) where that level's exact quantile is 1.90:
    the test ran at a level near 10^-8. On this scale the same ten nulls' thresholds read
    1.76-1.95 in log F. The lower tail is clipped at p = 1 - 1e-15 (z -7.9): the statistic is
    tested upwards only."""
    from scipy.special import ndtri_exp

    with np.errstate(all="ignore"):
        log_sf = -0.5 * dof * np.log1p(2.0 * np.asarray(F, dtype=float) / dof)
        return -ndtri_exp(np.minimum(log_sf, -1e-15))


#: The summaries whose scatter a library effect makes differ from robot to robot (a robot's own
#: heading noise, ``motion_noise``, sets how much its trial turn rates and speeds vary), and whose
#: F statistics therefore weigh each robot by its variance under the model
#: (:func:`model_variances`). The noise summary itself is read on a log scale instead
#: (:func:`_log_scale`), where robots noisier by a factor scatter alike.
_WEIGHED = {"motion": ("turn_rate", "speed")}


def model_variances(kind: str, null: dict) -> dict:
    """Each robot's variance under the model, read off the model's simulated null (M, K, N), for
    the summaries of :data:`_WEIGHED`: ``comp`` about each robot's mean and ``comp:line`` about its
    line over trials, each pulled towards the typical robot's by as much as the robots' variances
    differ beyond replicate noise (:func:`_replicate_spread`), so robots alike weigh alike. The
    residuals are studentised (:func:`effects.line_residuals`): a robot seen in 2 of 3 trials lies on its
    line exactly, and its variance read as 0 had made it weigh 10^33 times the others (third world
    3093, 36 robots x 3 trials with four robots missing one each: its drift's trend F, at z 4.6
    pooled, stood at -0.6); it takes the typical robot's.

    With robots alike, a pooled F is every robot's test at once. Where the model says robots
    differ in noise (``motion_noise`` named), its pooled squares are the noisiest robots': in the
    independent world's 3087 (10 robots x 8 trials, no drift; one robot's trial turn rates 14x as
    variable as the typical robot's) that one robot made 81 % of the trend's sum of squares, and
    its chance line (t = 3.6 on its own 6 degrees of freedom) with a second robot's (t = -3.8) set
    the trend F at z 3.8 against the null of the model with the noise named, so a drift was named
    beside the noise; weighed by that model's variances (the noisy robot's 5.3x the typical) the
    same trials stand at z 2.8, the null's 99th percentile, below the family's threshold of 2.9.
    Drawn from a model of 10 x 8 with one robot 15x as variable as the rest (benchmarks/weighed_f.py),
    the pooled trend F flagged 0.23 % of datasets at a nominal 0.17 % (0.07 % weighed) and found
    a drift of 0.25 sd per trial in the quiet robots in 0.7 % (30 % weighed; 36 % with robots alike)."""
    out = {}
    for comp in _WEIGHED.get(kind, ()):
        x = null.get(comp)
        if x is None or np.ndim(x) != 3:
            continue
        M, K, N = x.shape
        about_line, about_mean, _ = E.line_residuals(np.asarray(x, dtype=float), studentised=True)
        out[comp] = _replicate_spread(about_mean.reshape(M * K, N))[0]
        if K >= 3:
            out[comp + ":line"] = _replicate_spread(about_line.reshape(M * K, N))[0]
    return out


def statistics(kind: str, s: dict, trials: int, v: dict | None = None) -> dict:
    """name -> (value(s), sidedness). Works on (K, N) measured or (M, K, N) simulated summaries.
    ``v``: robots' variances under the model (:func:`model_variances`), the same for the data and
    for its null; None: robots alike."""
    v = v or {}
    out = {}
    if kind == "motion":
        out["turn_rate:between_robots"] = (_f_between(s["turn_rate"], v=v.get("turn_rate")), 1)
        if trials >= 3:
            out["turn_rate:trial_trend"] = (_f_trend(s["turn_rate"], v.get("turn_rate:line")), 1)
        out["speed:between_robots"] = (_f_between(s["speed"], v=v.get("speed")), 1)
        out["diffusion:level"] = (np.nanmean(s["diffusion"], axis=(-2, -1)), 2)
        out["diffusion:between_robots"] = (_f_noise(s["diffusion"]), 1)  # as _ALONE reads it
        out["speed:heading_dependence"] = (_heading_dependence(s["speed"], s["heading"]), 1)
    elif kind == "light_sweep":
        out["gain:between_robots"] = (_f_between(s["gain"], _resolution(s, "gain")), 1)
        out["offset:between_robots"] = (_f_between(s["offset"], _resolution(s, "offset")), 1)
    else:
        out["toggle_rate:between_robots"] = (_f_between(s["toggle_rate"]), 1)
    return out


def _resolution(s: dict, comp: str):
    """The variance a summary has from the ADC's rounding alone (mean over tracks), if known."""
    floor = s.get(comp + "_floor")
    if floor is None:
        return None
    with np.errstate(all="ignore"):
        return np.nanmean(floor, axis=(-2, -1))


#: The least spread a one-sided statistic's simulated null is taken to have: those statistics are
#: log ratios of mean squares (the heading dependence one's normal score, sd 1), and sampling
#: alone gives the log F of <= 40 robots a null sd of
#: sqrt(2 / 39) = 0.23 or more under any noise. A null far narrower is a world without noise (clocks
#: started with the frames and never jittering: every replicate blinks alike), where the fitted
#: model's pooled per-robot rates differ from the data's means by parts in a thousand and the
#: between-robot F by 0.005, which against a null sd of 0 read as z 10^9: a right clock_drift
#: resolved nothing (synth blink 3012). A missing effect moves such an F by orders of magnitude.
LOG_RATIO_RESOLUTION = 0.05


def null_sd(null, sided: int) -> float:
    """The spread of a statistic under the simulated null (finite replicates, ddof 1), at least
    its resolution: :data:`LOG_RATIO_RESOLUTION` for the one-sided log ratios,
    :data:`_REL_RESOLUTION` of its mean for the two-sided levels."""
    null = np.asarray(null, dtype=float)
    null = null[np.isfinite(null)]
    floor = LOG_RATIO_RESOLUTION if sided == 1 else _REL_RESOLUTION * abs(float(null.mean()))
    return max(float(null.std(ddof=1)), floor, 1e-300)


def _p_value(obs, null, sided):
    """Calibrated p-value: z of the observed statistic against the simulated null (normal tail,
    so that p can be smaller than 1 / number of simulations), in the null's :func:`null_sd`."""
    from scipy.stats import norm

    null = null[np.isfinite(null)]
    z = (obs - null.mean()) / null_sd(null, sided)
    p = norm.sf(z) if sided == 1 else 2 * norm.sf(abs(z))
    return float(z), float(p)


#: A signal's second test where the model's effects already account for it (see :func:`detect`):
#: the F ratio's numerator alone, on the F's scale (the diffusion's on :func:`_log_scale`, as
#: :func:`_f_noise` reads it), and the key its z is reported under.
_ALONE = {"between_robots": (lambda comp, x, v: _ms_between(_log_scale(x)) if comp == "diffusion" else _ms_between(x, v.get(comp)),
                             "z_between_ms"),
          "trial_trend": (lambda comp, x, v: _ms_trend(x, v.get(comp + ":line")), "z_trend_ms")}


def detect(kind, meas, null, trials, alpha, fitted=()):
    """Flag statistics whose calibrated p < alpha / n; localise each to robots and trials.

    ``fitted``: the model's effects (:class:`effects.Effect`). Where one of them accounts for a
    signal (``Effect.explains``: it fits robots' own means, or lines, of that summary), a
    between-robot F ratio that stands far above its null can come from the within-robot mean
    square alone: with robots' means fitted, the F is their spread over the
    within-robot mean square, and where the data's trials vary less from trial to trial than the
    model's, the data's F stands high by that factor however well the means agree (synth pair
    3049: speed factors 27x their detectable size, fitted; the data's trial speeds varied 0.39x as
    much as the model's, whose floor from tracking alone, fitted at the truth, has its 5 % quantile
    at 0.60x its median: the data's was about 3 log-sds low; the F stood at z 4.0, so the right
    speed spread resolved nothing and was not named).
    Robots that differ beyond the model also spread their means more than the model's do, so
    there the signal is flagged only if the between-robot mean square, with no within-robot
    yardstick, stands above its null as well (both tests at the family's level, the larger p
    counts). Where the model fits no per-robot means (the base), the F alone decides: its
    within-robot yardstick keeps a wrong noise level from reading as robots that differ.
    A trend F where the model fits robots' own lines is read the same way, with the trends' mean
    square alone as the second test (independent world 3070: drifts 9.7x their detectable size,
    the trend F at z 4.5 with the drift fitted, which resolved nothing)."""
    v = model_variances(kind, null)
    obs = statistics(kind, meas, trials, v)
    sim = statistics(kind, null, trials, v)
    found = []
    for name, (value, sided) in obs.items():
        z, p = _p_value(float(value), np.asarray(sim[name][0]), sided)
        comp, _, stat = name.partition(":")
        f = {"signal": name, "statistic": float(value), "z": z, "p_value": p}
        if stat in _ALONE and any(e.explains(name) for e in fitted):
            alone, key = _ALONE[stat]
            za, pa = _p_value(float(alone(comp, meas[comp], v)), np.asarray(alone(comp, null[comp], v)), 1)
            f.update({key: za, "p_value": max(p, pa)})
        f["robots"], f["trials"] = _localise(meas.get(comp), null.get(comp), kind)
        found.append(f)
    for f, flag in zip(found, flagged_by_family([f["p_value"] for f in found], alpha)):
        f["flagged"] = bool(flag)
    return found


def _localise(x, null, kind, z_cut=3.0):
    """Robots (by index) and trials whose mean deviates by > z_cut sd from the simulated mean."""
    if x is None or null is None:
        return [], []
    with np.errstate(all="ignore"):
        rm, rn = np.nanmean(x, axis=0), np.nanmean(null, axis=1)  # (N,), (M, N)
        zr = (rm - np.nanmean(rn, 0)) / np.nanstd(rn, 0, ddof=1)
        tm, tn = np.nanmean(x, axis=1), np.nanmean(null, axis=2)  # (K,), (M, K)
        zt = (tm - np.nanmean(tn, 0)) / np.nanstd(tn, 0, ddof=1)
    robots = [int(i) for i in np.argsort(-np.abs(zr)) if np.abs(zr[i]) > z_cut]
    trials = [int(k) for k in np.argsort(-np.abs(zt)) if np.abs(zt[k]) > z_cut]
    return robots, trials


# --- fitting and held-out scoring -------------------------------------------------------------------

class _Fitter:
    """Fits sequences of effects on subsets of trials (cached), via reference simulations."""

    def __init__(self, cond: Conditions, meas: dict, start: E.TwinModel, gs: GapSettings, fit_base: bool):
        self.cond, self.meas, self.start, self.gs, self.fit_base = cond, meas, start, gs, fit_base
        self.cache = {}  # (names, trials) -> fitted model (names () : the base)
        self.refs = {}  # (names so far, trials) -> reference simulation of that model

    def meas_on(self, trials):
        return E.Summaries({k: v[trials] for k, v in self.meas.items()}, trials)

    def fit(self, names: tuple, trials) -> E.TwinModel:
        """The base fitted on ``trials``, then each effect of ``names`` in turn. A model of several
        effects is its prefix's model (cached: the model named in an earlier round, fitted on the
        same trials) with the last effect fitted on top, so a candidate differs from the current
        model by that effect alone, not also by the prefix refitted on other simulations."""
        key = (names, tuple(int(t) for t in trials))
        if key in self.cache:
            return self.cache[key]
        all_trials = tuple(range(self.cond.trials))
        M = self.gs.m_ref if key[1] == all_trials else self.gs.m_fold
        if not names:
            model = self.start
            if self.fit_base:
                ref = simulate(self.cond, model, M, child_seed(self.gs.seed, "base_ref"), trials)
                calls = itertools.count(1)

                def resim_base(m):
                    return simulate(self.cond, m, M, child_seed(self.gs.seed, "base_probe", next(calls)), trials)

                def resim_level(m):  # the same random numbers in every step (common random numbers)
                    return simulate(self.cond, m, M, child_seed(self.gs.seed, "base_level"), trials)

                noise = None if key[1] == all_trials else self.fit((), all_trials)
                model = E.fit_base(model, self.meas_on(np.asarray(trials)), ref, resim_base, noise, resim_level)
            self.cache[key] = model
            return model
        prefix = self.fit(names[:-1], trials)
        depth, j = len(names), len(names) - 1
        # The reference simulation depends only on the model so far (same seed for every
        # candidate at this depth): simulated once per (names so far, trials), not per candidate.
        ref_key = (names[:j], key[1])
        ref = self.refs.get(ref_key)
        if ref is None:
            ref = self.refs[ref_key] = simulate(self.cond, prefix, M, child_seed(self.gs.seed, "effect_ref", depth, j), trials)

        def resim(m):
            return simulate(self.cond, m, M, child_seed(self.gs.seed, "effect_resim", depth, j), trials)

        effect, meas = self.gs.library[names[-1]], self.meas_on(np.asarray(trials))
        if effect.refits_noise and key[1] != all_trials:
            model = effect.fit(prefix, meas, ref, resim, noise=self.fit(names, all_trials))
        else:
            model = effect.fit(prefix, meas, ref, resim)
        if model is prefix:  # an effect with nothing to fit: the prefix's cached model stays as it is
            model = prefix.with_traits()
        model.named = list(names)
        self.cache[key] = model
        return model


def _heldout(fitter: _Fitter, names: tuple, kind: str) -> dict:
    """Leave-one-trial-out predictive distributions: per fold, the simulated mean of each summary
    and its predictive sd, for one robot's summary (``sd``) and for the mean over robots
    (``sd_level``, per robot: divide by sqrt(n)). Both are the simulated spread of a trial plus
    the estimation error of the parameters fitted on the other trials (:func:`effects.leverage`;
    for a summary whose spread a named effect's per-robot level sets, ``Effect.scales_spread``,
    :func:`effects.spread_leverage` with the spread on :func:`level_spread`'s line)."""
    K = fitter.cond.trials
    N = len(fitter.cond.robot_ids)
    comps = COMPONENTS[kind]
    pred = {c: {"mean": np.full((K, N), np.nan), "sd": np.full((K, N), np.nan), "sd_level": np.full(K, np.nan)}
            for c in comps}
    sim = fitter.gs.library[names[-1]].simulate if names else functools.partial(simulate)

    def train_of(k):
        return [t for t in range(K) if t != k]

    def fold(k):
        model = fitter.fit(names, train_of(k))
        return model, sim(fitter.cond, model, fitter.gs.m_score, child_seed(fitter.gs.seed, "heldout", k), [k])

    # Folds are independent and their simulations release the GIL: threads. The all-trials base
    # (whose noise levels every fold uses) is fitted first, once. Seeds are per fold: the result
    # does not depend on the number of threads.
    fitter.fit((), tuple(range(K)))
    if any(fitter.gs.library[n].refits_noise for n in names):  # and so is the effects' (Effect.refits_noise)
        fitter.fit(names, tuple(range(K)))
    with ThreadPoolExecutor(max(1, fitter.gs.threads)) as pool:
        folds = list(pool.map(fold, range(K)))
    kept = {c: [] for c in comps}  # each fold's replicates kept, for the robots' shared deviation
    spread = {c: np.full(K, np.nan) for c in comps}  # ... and a robot's simulated variance in each
    for k, (model, sims) in enumerate(folds):
        train = train_of(k)
        for c in comps:
            x = _without_wild_replicates(sims[c][:, 0, :])  # (M, N)
            kept[c].append(x)
            pred[c]["mean"][k] = E._nanmean(x, axis=0)  # NaN for a robot missing from trial k
            # Floored at the F statistics' resolution (_REL_RESOLUTION of the level) so a
            # deterministic prediction (a nuisance fitted as 0) cannot turn a tiny mismatch into
            # an infinite log-likelihood. Floored, not added to: a noiseless sensor's gains vary
            # from sweep to sweep by about that much (a part in 10^4), and the sum had doubled
            # their predictive variance, halving what a right sensor gain gains on held-out
            # trials against what the naming power's emulation expects (independent world 3060:
            # score -1.0 at its stated size, 36 robots x 8 trials, flagged at z 3.5). A light
            # sweep's floor is lower, at what the replicates vary by (_predictive_floor).
            scales = any(c in fitter.gs.library[n].scales_spread for n in names)
            b, centre = level_spread(x) if scales else (0.0, None)
            var_i, pooled = _replicate_spread(x, centre)
            floor = _predictive_floor(kind, x, np.asarray(fitter.meas[c])[train], pooled)
            rounding = fitter.meas.get(c + "_floor") if kind == "blink" and model.frame_lead == "random" else None
            if rounding is not None:
                # Clocks anywhere in their cycle: no robot's rate is predicted closer than the
                # frames' rounding of its first and last toggle (summaries.blink). The replicates
                # can vary less, where the trial's periods span nearly a whole number of frames,
                # but which values they then take depends on the rate to 1e-4 and on how the
                # track's ends fall: independent blink 3244 (robots started up to 1.1 s late,
                # 12.5 Hz) predicted trial 2 at 2.5590 +- 0.0003 while the robots' rates lay on
                # 2.5594 and 2.5578, a gap of 1.69 on null data.
                r = np.asarray(rounding[k], dtype=float)
                var_i = np.where(np.isfinite(r), np.fmax(var_i, r), var_i)
                pooled = max(pooled, float(np.nanmean(r)) if np.isfinite(r).any() else 0.0)
            h_track, h_level = E.leverage(kind, names, c, train, k, N, fitter.fit_base, fitter.gs.library, model,
                                         fitter.gs.m_fold, seen=np.isfinite(fitter.meas[c]))
            if scales:
                h_track = E.spread_leverage(h_track, b)
            # The predicted mean is itself a mean of the replicates kept, so it is off by their
            # Monte Carlo error too: var / M of a robot's summary, and as much of the mean over
            # robots (those simulated: a robot missing from the trial has none). Without it a
            # right model's held-out tracks read 1 + 1/M of their variance.
            reps = np.isfinite(x).sum(0)
            mc = 1.0 / np.maximum(reps, 1)
            h_track = h_track + mc
            h_level = h_level + (float(np.mean(mc[reps > 0])) if (reps > 0).any() else 0.0)
            pred[c]["sd"][k] = np.sqrt(np.maximum(var_i, floor) * (1 + h_track))
            spread[c][k] = max(pooled, floor)
            pred[c]["sd_level"][k] = np.sqrt(spread[c][k] * (1 + h_level))
    # A trial's level is a mean over robots whose deviations the model draws independently. A
    # sensor whose reading noise is too small to dither the ADC's rounding (below
    # :data:`DITHER_COUNTS`) rounds a smooth sweep by a function of the sweep itself: robots
    # reading the same sweep round it alike, and their mean varies by that shared rounding, not by
    # 1 / n of one robot's. Independent light null 3296 (no sensor noise, identical robots: 31
    # robots on the same integers) read per trial level deviances of 7.2 and 11.0 on null data.
    # There the level's variance takes the part rho of a robot's variance that the data's robots
    # share (:func:`shared_deviation`) for every robot but one. Where the noise dithers the
    # rounding, nothing is shared by rounding, and what the robots of a trial share (the light's
    # level shifting from trial to trial) is a disagreement that stays in the gap.
    rng = np.random.default_rng(child_seed(fitter.gs.seed, "shared"))
    undithered = kind == "light_sweep" and data_reading_noise(fitter.meas) < DITHER_COUNTS
    for c in comps:
        rho = shared_deviation(fitter.meas[c] - pred[c]["mean"], kept[c], pred[c]["mean"], rng)
        shared = np.nan_to_num(rho * spread[c]) if undithered else np.zeros(K)
        seen = np.isfinite(fitter.meas[c]).sum(axis=1)
        pred[c]["sd_level"] = np.sqrt(pred[c]["sd_level"] ** 2 + np.maximum(seen - 1, 0) * shared)
        pred[c]["shared"] = rho
        pred[c]["shared_sd"] = float(np.sqrt(np.mean(shared)))
    return pred


#: The reading noise (counts, sd) that dithers an ADC's rounding: with Gaussian noise of sd s, a
#: rounded reading's mean error follows the signal by at most exp(-2 pi^2 s^2) / pi counts (the
#: rounding's Fourier series; 0.002 at 0.5 counts, 0.09 at 0.25), so below it robots that read the
#: same sweep round it alike.
DITHER_COUNTS = 0.5


def data_reading_noise(meas) -> float:
    """The light sensor's reading noise (counts, sd) as the data show it, beyond the ADC's rounding:
    the typical track's scatter about its line (``residual_sd``, median over tracks) less the
    rounding's 1/12 in variance. Read off the data, not the base's fit: the base's noise fitted
    to noiseless sweeps of another world can read 0.56 counts where the data scatter by 0.294
    (rounding alone: 0.289; indep_world seed 108 without sensor noise)."""
    sd = np.asarray(meas["residual_sd"], dtype=float)
    if not np.isfinite(sd).any():
        return math.inf
    return math.sqrt(max(float(np.nanmedian(sd**2)) - E.ADC_ROUNDING_VAR, 0.0))


#: One-sided level at which the data's robots are taken to share their deviations
#: (:func:`shared_deviation`): independent robots widen a level's spread in 1 % of datasets.
SHARED_ALPHA = 0.01


def shared_deviation(resid, reps, mu, rng: np.random.Generator, alpha: float = SHARED_ALPHA, draws: int = 400) -> float:
    """The share rho of a robot's deviation that the robots of a trial have in common (the
    intraclass correlation), 0 unless the data show it: from how far the data's robots scatter
    about their trial's mean, against how far robots drawn independently from the model's
    replicates do.

    ``resid`` (K, N): measured minus predicted (NaN: a robot not seen); ``reps``: per trial the
    replicates (M, N) the prediction ``mu`` (K, N) is the mean of; rho is the residuals' (whose
    prediction's Monte Carlo error, var / M, no robot shares). Robots with a common deviation
    rho scatter about their trial's mean by (1 - rho) of their variance, so the data's pooled
    within-trial mean square W is (1 - rho) times what the model's independent robots give
    (``draws`` draws, each robot's replicate chosen at random for every trial, pooled as the data
    are). Where W is below those draws' ``alpha`` quantile (independent robots do that in
    ``alpha`` of datasets), rho is 1 - W / (their mean); otherwise 0. Not the lower confidence
    bound: at rho = 0.5 on 30 robots x 5 trials that bound (about 0.32) left the level's z^2 at
    1.65.
    Robots that differ more than the model says only raise W: never a shared deviation. A small
    shared part on many robots (rho 0.1 on 30: a design effect of 3.9) is below what W resolves
    (its relative sd sqrt(2 / dof)) and is missed."""
    resid = np.asarray(resid, dtype=float)
    K = resid.shape[0]
    num, null, dof = 0.0, np.zeros(draws), 0.0
    for k in range(K):
        seen = np.isfinite(resid[k])
        n = int(seen.sum())
        x = np.asarray(reps[k], dtype=float)[:, seen]
        if n < 2 or x.shape[0] < 2:
            continue
        num += float(np.var(resid[k, seen], ddof=1)) * (n - 1)
        # A replicate less the mean of its own M varies by (1 - 1/M) of the spread, a robot's
        # measurement less that mean by (1 + 1/M): the draws are scaled to the latter.
        m = np.isfinite(x).sum(axis=0)
        grow = np.sqrt((m + 1.0) / np.maximum(m - 1.0, 1.0))
        pick = (x[rng.integers(0, x.shape[0], (draws, n)), np.arange(n)] - mu[k, seen]) * grow
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # a draw of wild (NaN) replicates only
            null += np.nan_to_num(np.nanvar(pick, axis=1, ddof=1)) * (n - 1)
        dof += n - 1
    if dof == 0:
        return 0.0
    if not num < float(np.quantile(null, alpha)):
        return 0.0
    return float(np.clip(1.0 - num / float(np.mean(null)), 0.0, 1.0))


def _replicate_spread(x, centre=None):
    """Each robot's simulated spread from replicates x (M, N), and the mean over robots (what a
    mean over robots varies by, times n).

    M replicates estimate a variance only to sqrt(2 / M) (more for skewed summaries), so each
    robot's variance is pulled towards the typical robot's, on the log scale, by as much as the
    robots' variances differ beyond that noise (empirical Bayes, method of moments): weight
    w = tau^2 / (tau^2 + s^2), s^2 the sampling variance of a robot's log variance (from the
    two halves of its replicates: distribution-free) and tau^2 the robots' spread of log
    variances beyond it. Alike robots (w near 0) share the typical variance; robots that differ
    in noise by factors of several (a lognormal spread of noise intensities, whose summaries
    scatter in proportion) keep their own (w near 1), where a fixed halfway pull had left the
    noisiest robots' spreads too narrow by sqrt(2) and the gap after naming the noise effect
    far from 0.

    The typical spread is the robots' median variance over the median of the chi-square that M
    replicates draw (the common variance when robots are alike), not their mean: one robot 6x
    noisier than the rest (robots that differ in noise) had widened every other robot's
    prediction through the mean; the centre of the pull is that median too. ``centre`` (N,), where
    given, is each robot's own centre instead (:func:`level_spread`: a spread that grows with the
    robot's level, read off its mean), and the pull's weight is what the robots' variances differ
    from it by beyond replicate noise."""
    from scipy.stats import chi2

    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a robot with no replicates (all NaN) has no variance
        var_i = np.nanvar(x, axis=0, ddof=1)
        half = x.shape[0] // 2
        split = np.log(np.nanvar(x[:half], axis=0, ddof=1) / np.nanvar(x[half:], axis=0, ddof=1))
    mean = float(np.nanmean(var_i))
    dof = max(float(np.median(np.isfinite(x).sum(0))) - 1.0, 1.0)
    typical = float(np.nanmedian(var_i)) * dof / chi2.median(dof)
    ok = np.isfinite(var_i) & (var_i > 0)
    if ok.sum() < 3 or not typical > 0:
        return np.where(ok, 0.5 * var_i + 0.5 * typical, typical), mean
    centre = np.full(var_i.shape, typical) if centre is None else np.where(np.asarray(centre) > 0, centre, typical)
    dev = np.log(var_i[ok] / centre[ok])
    s2 = float(np.mean(split[np.isfinite(split)] ** 2)) / 4.0  # var(half a - half b) = 2 x 2 x a whole's
    tau2 = max(float(np.var(dev, ddof=1)) - s2, 0.0)
    w = tau2 / (tau2 + s2) if tau2 + s2 > 0 else 0.0
    out = centre.copy()
    out[ok] = centre[ok] * np.exp(w * dev)
    return out, mean


def level_spread(x):
    """How a summary's one-trial variance grows with its level, from replicates x (M, N) of
    robots at different levels: ``(b, centre)``, var = a + b L^2 by least squares over robots
    of each robot's replicate variance on its squared mean (less the mean's own sampling
    variance, var / M), and each robot's variance on that line (NaN where it has none). ``b`` is
    bounded by 0 (a spread that does not scale) and the robots' median var / L^2 (all of it
    scales, a = 0): robots that hardly differ in level cannot tell the two apart, and a slope
    fitted to noise there would not be bounded at all. For :func:`effects.spread_leverage` and
    as the centre of :func:`_replicate_spread`'s pull: a robot's mean is known from M replicates
    far better than its variance (of a skewed summary: relative sd 0.2 against 0.6 at M = 30)."""
    with np.errstate(all="ignore"):
        var = np.nanvar(x, axis=0, ddof=1)
        n = np.isfinite(x).sum(0)
        sq = np.nanmean(x, axis=0) ** 2 - var / np.maximum(n, 1)
        ratio = var / sq
    ok = np.isfinite(var) & np.isfinite(sq) & (sq > 0) & (n > 1)
    if ok.sum() == 0:
        return 0.0, np.full(var.shape, np.nan)
    top = max(float(np.median(ratio[ok])), 0.0)
    if ok.sum() < 3 or np.ptp(sq[ok]) == 0:
        b = top
    else:
        b = float(np.clip(np.polyfit(sq[ok], var[ok], 1)[0], 0.0, top))
    a = max(float(np.mean(var[ok] - b * sq[ok])), 0.0)
    return b, np.where(ok, a + b * sq, np.nan)


def _without_wild_replicates(x, k: float = 10.0):
    """Simulated replicates (M, N) with the wild ones NaN: farther than ``k`` robust sds (1.4826
    median absolute deviations) from the robot's median. A simulated track that is short and
    gappy (the data's mask) now and then fails to unwrap its heading and gives a turn rate far
    from the rest (the chord-heading diffusion of before gave thousands of times the rest); one
    such replicate in 30 would set the robot's predictive spread, and through the pooled spread
    every robot's.

    A summary that takes few values ties: a toggle rate counted between frame times (5 Hz over
    100 s: steps of 0.2 %) lands on one value in half the replicates or more, and its median
    absolute deviation is then 0 or a sliver (third world blink 3239: 15 of 30 tied, the MAD 2 %
    of a step). Every replicate a step off read as wild, and a robot kept only its tied ones: a
    predictive sd of 0.01 % where the step is 0.2 %, one held-out trial a step away scored -18 sd,
    and a clock drift 7x its detectable size was not named. Nor are the steps of such a rate
    only one apart: with robots anywhere in their LED cycle a rate can fall on two clusters of
    steps, a few 1e-3 apart, the smaller holding 3-40 % of the replicates (robot 13 of trial 5 of
    independent blink 3253: 64 % within 1e-4 of the median, 36 % 2e-3 below). The median absolute
    deviation measures the larger cluster alone, and every replicate of the smaller read as wild:
    the predictive sd came out 1.1e-4 and the data's rate, in the smaller cluster, lay at z -17
    (the clock drift's gap after naming 1.35).

    So a robot whose replicates tie (fewer distinct values than half of them: a summary counted
    on a lattice) has its robust sd floored at the typical robot's sd (the median over robots of
    each one's replicate sd, which a wild replicate of one robot does not move): a replicate is
    wild beyond 10 of those, several steps, where no cluster lies. Any other robot's is floored at
    a tenth of it: a summary that does not tie keeps its own robust sd unless one robot is 10x
    quieter than the median robot, and then a replicate is wild beyond 10 typical sds, still far
    inside the failures this is for."""
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a robot missing from the trial: all NaN
        med = np.nanmedian(x, axis=0)
        scale = summaries.robust_sd(x, axis=0)
        typical = np.nanmedian(np.nanstd(x, axis=0, ddof=1))
        seen = np.isfinite(x)
        xs = np.sort(x, axis=0)  # NaNs last
        distinct = seen.any(0) + ((np.diff(xs, axis=0) != 0) & np.isfinite(xs[1:])).sum(0)
        lattice = 2 * distinct < seen.sum(0)
        scale = np.where(lattice, np.maximum(scale, typical), np.where(scale < 0.1 * typical, typical, scale))
        wild = np.abs(x - med) > k * np.where(scale > 0, scale, np.inf)
    return np.where(wild, np.nan, x)


#: Where the held-out log-density turns from Gaussian to linear, in predictive sds (Huber's
#: least favourable density, the model of a normal with a share of gross errors). A right model
#: puts a held-out summary beyond 4 sd in 6 of 100,000, so scores and the stated sizes are those
#: of the Gaussian; but one gross error (a trial whose tracked heading slipped: z = 39 on synth
#: seed 1014, 8 mm tracking noise) no longer outweighs every robot: its z^2 / 2 of 750 had set
#: the naming bounds to -663 .. 263 and left a speed spread 2.6x its detectable size unnamed.
HUBER_K = 4.0


def deviance(z):
    """A held-out summary's deviance, -2 x its :func:`log_density` above that of a perfect
    prediction: z^2 within ``HUBER_K`` predictive sds, 2 k |z| - k^2 beyond. The gap is its excess
    over a right model's mean (:data:`DEVIANCE_MEAN`), so one gross error (z = 39: 296, not 1,521)
    does not outweigh a swarm, as it no longer does in the scores."""
    a = np.abs(z)
    return np.where(a <= HUBER_K, a * a, 2.0 * HUBER_K * a - HUBER_K**2)


def log_density(z, sd):
    """Held-out log-density of a summary at z predictive sds from its predicted mean, predictive
    sd ``sd``: -z^2 / 2 within ``HUBER_K``, -k |z| + k^2 / 2 beyond (the same constant for every
    model, so it is left out), minus log sd; that is -:func:`deviance` / 2 - log sd."""
    return -0.5 * deviance(z) - np.log(sd)


#: E[deviance(Z)] for Z ~ N(0, 1): 2 Phi(k) - 1 + 2 k phi(k) - 2 k^2 (1 - Phi(k)) (1 - 7e-6 at k = 4).
DEVIANCE_MEAN = (math.erf(HUBER_K / math.sqrt(2)) + 2 * HUBER_K * math.exp(-HUBER_K**2 / 2) / math.sqrt(2 * math.pi)
                 - HUBER_K**2 * math.erfc(HUBER_K / math.sqrt(2)))


def _loglik_per_robot(meas, pred, comps):
    """Sum over held-out trials and components of the held-out log-density
    (:func:`log_density`) of the measured summaries, per robot."""
    ll = 0.0
    for c in comps:
        mu, sd = pred[c]["mean"], pred[c]["sd"]
        ll = ll + np.nansum(log_density((meas[c] - mu) / sd, sd), axis=0)
    return ll  # (N,)


def _normal_pdf(x):
    """The standard normal's density (scipy.stats.norm.pdf's expression, without its per-call checks)."""
    return np.exp(-x**2 / 2.0) / np.sqrt(2 * np.pi)


def resampled_excess(z, v):
    """E[:func:`deviance`(Z)] - deviance(z) for Z ~ N(z, v): how much a mean resampled over
    robots, at z predictive sds with a resampling variance v, raises the deviance on average.
    Within ``HUBER_K`` it is v (z^2 grows by the variance); beyond, the deviance is linear and
    it is nearly 0. Taking v off in every case, as the gap's bootstrap once did, centred a level
    gap in the linear part far below its value: 68.8 with an interval of -102 .. -31 (the third
    world's seed 3008, speed factors). Closed form by the normal's partial moments; a NaN z stays
    NaN, and v of 0 adds nothing."""
    from scipy.special import ndtr  # the normal's cdf (scipy.stats.norm.cdf without its per-call checks)

    z, v = np.asarray(z, dtype=float), np.asarray(v, dtype=float)
    k = HUBER_K
    with np.errstate(all="ignore"):
        s = np.sqrt(np.maximum(v, 0.0))
        ok = s > 0
        s1 = np.where(ok, s, 1.0)
        a, b = (-k - z) / s1, (k - z) / s1
        Fa, Fb, fa, fb = ndtr(a), ndtr(b), _normal_pdf(a), _normal_pdf(b)
        quad = z * z * (Fb - Fa) + 2 * z * s1 * (fa - fb) + s1 * s1 * ((Fb - Fa) + a * fa - b * fb)
        lin = 2 * k * (z * (1 - Fb) + s1 * fb - z * Fa + s1 * fa) - k * k * ((1 - Fb) + Fa)
        return np.where(ok, quad + lin - deviance(z), 0.0)


def _level_z(m, mu, sd_level):
    """Each trial's level residual in predictive sds: (mean over robots of measured - of
    predicted) / (sd_level / sqrt(robots seen)); m, mu (K, N) -> (K,), or (K, B, N) -> (K, B)
    (sd_level then (K, 1))."""
    n = np.isfinite(m).sum(axis=-1)
    return (np.nanmean(m, axis=-1) - np.nanmean(mu, axis=-1)) / (sd_level / np.sqrt(n))


def _gap(meas, pred, yard, comps, robots=None, parts=("track", "own", "level")):
    """The gap: held-out prediction error in noise units, the mean :func:`deviance` (z^2 within
    ``HUBER_K`` sds, linear beyond) minus a right model's mean (0 = as good as the model's noise).

    Three equally weighted parts, each 0 in expectation for a model that reproduces the data
    (spreads are predictive: the model's noise plus the estimation error of what was fitted on
    the other trials, so a fitted population level does not leave a floor of 1/K' per part):

    - per track, against the final model's spread: z = (measured - the model's simulated mean for
      that trial and robot) / final spread; sees missing per-robot or per-trial structure;
    - per track, against the model's own spread: sees a model whose noise is too narrow or wide
      (a wrong noise level moves spreads, not means);
    - per trial level: z = (mean over robots of measured - of predicted) / (level spread / sqrt(n));
      sees population-level errors that single tracks hide.

    ``robots`` resamples robots for the bootstrap: indices (n,), which may repeat (a float, as
    without), or (B, n), B resamples at once (an array of B: ``GapSettings.boot`` resamples in one
    pass of arrays rather than a call each). ``parts`` chooses parts.
    """
    n = meas[comps[0]].shape[1]
    rows = np.arange(n)[None] if robots is None else np.atleast_2d(robots)  # (B, n); B = 1 but for a batch
    sums, counts = dict.fromkeys(parts, 0.0), dict.fromkeys(parts, 0)
    for c in comps:
        m, mu = meas[c], pred[c]["mean"]
        sd_level = np.broadcast_to(np.asarray(yard[c]["sd_level"], dtype=float), m.shape[:1])  # (K,)
        extra = np.zeros(m.shape[:1])
        if robots is not None:
            # A resampled mean over robots varies by the robots' spread / n more than the mean
            # does, which raises its expected deviance: that much is taken off the level part, so
            # the bootstrap is centred on it.
            with np.errstate(all="ignore"):
                v = np.nanvar(m - mu, axis=1) / sd_level ** 2
                extra = resampled_excess(_level_z(m, mu, sd_level), v)
        # (K, B, n): the resamples on an axis of their own
        m, mu, sd, sd_own = (a[:, rows] for a in (m, mu, yard[c]["sd"], pred[c]["sd"]))
        with np.errstate(all="ignore"):
            terms = {"track": deviance((m - mu) / sd), "own": deviance((m - mu) / sd_own),
                     "level": deviance(_level_z(m, mu, sd_level[:, None]))[..., None] - extra[:, None, None]}
        for p in parts:  # sums and counts over (K, n) per resample
            sums[p] = sums[p] + np.nansum(terms[p], axis=(0, 2))
            counts[p] = counts[p] + (~np.isnan(terms[p])).sum(axis=(0, 2))
    with np.errstate(all="ignore"):
        g = np.mean([sums[p] / counts[p] - DEVIANCE_MEAN for p in parts], axis=0)  # (B,)
    return g if np.ndim(robots) == 2 else float(g[0])


#: The parts of the gap (:func:`_gap`), as the report names them.
GAP_PARTS = {"track": "per track, final model's spread", "own": "per track, the model's own spread",
             "level": "per trial level"}


def gap_by_part(meas, pred_base, pred_final, comps) -> dict:
    """Where the gap is: :func:`_gap` of each summary and part alone, ``{summary: {part: [before,
    after]}}``, before on the base's predictions and after on the final model's, both on the
    final model's yardstick as the gap is (the own-spread part on each model's own). The gap is
    the mean over parts of these, over summaries weighted by the values each holds. A gap on null
    data that no test flags shows here: in the light sweep of a world without reading noise,
    every robot's track agreed (track parts 0.10 and -0.17) while the swarm's gain moved from trial
    to trial by up to 12 level sds (per-trial level parts 21 and 17: the independent world, seed
    3012)."""
    return {c: {p: [_gap(meas, pred_base, pred_final, [c], parts=(p,)), _gap(meas, pred_final, pred_final, [c], parts=(p,))]
                for p in GAP_PARTS} for c in comps}


def _tail_count(n: int, level: float) -> int:
    """How many of ``n`` bootstrap resamples lie beyond each end of a central ``level`` interval
    (at least 1): the order statistics :func:`shrink_interval` and :func:`removed_interval` share."""
    return max(int(math.ceil((1 - level) / 2 * n - 1e-9)), 1)


def shrink_interval(before: float, after: float, before_boot, after_boot, level: float = 0.95) -> list:
    """Interval for the shrink 1 - after / before, by inverting the bootstrap's test of each ratio:
    a ratio r is in it when after - r before, over the bootstrap resamples, has 0 within its
    central ``level`` range. Where every resample's gap before is above 0 this is the percentile
    interval of the resampled ratios; where some are not, the set widens, and it has no end on a
    side where resamples no longer tell (returned as None: the data cannot say how much of the
    gap was removed). The bare percentiles of the ratio are no interval then (seen: -6.6 .. 4.4
    around a shrink of 0.83 whose gaps were 0.40 -> 0.07), and a normal-theory Fieller interval
    is none either: a gap is a mean of squared z-scores that a few robots dominate, and its
    bootstrap spread is far from normal (unbounded for a speed gap 6.28 -> 0.02)."""
    b, a = np.asarray(before_boot, dtype=float), np.asarray(after_boot, dtype=float)
    ok = np.isfinite(a) & np.isfinite(b)
    a, b = a[ok], b[ok]
    k = _tail_count(len(a), level)  # resamples needed on each side of 0

    def accepted(r):
        d = a[:, None] - np.asarray(r, dtype=float)[None, :] * b[:, None]
        return ((d <= 0).sum(0) >= k) & ((d >= 0).sum(0) >= k)

    with np.errstate(all="ignore"):
        ratios = np.unique(np.where(b != 0, a / b, np.nan))
    ratios = ratios[np.isfinite(ratios)]
    # The counts change only at the resamples' ratios: test there and between them, and far out.
    mids = (ratios[1:] + ratios[:-1]) / 2
    r = np.concatenate([ratios, mids, [-1e12, 1e12]])
    ok_r = accepted(r)
    if not ok_r.any():
        return [None, None]
    lo = None if ok_r[-2] else float(r[:-2][ok_r[:-2]].min())
    hi = None if ok_r[-1] else float(r[:-2][ok_r[:-2]].max())
    return [None if hi is None else float(1 - hi), None if lo is None else float(1 - lo)]


def removed_interval(before_boot, after_boot, level: float = 0.95) -> list:
    """Interval for the gap removed, before - after, from the same paired bootstrap and the same
    order statistics (k from each end) as :func:`shrink_interval`'s test. It excludes 0 exactly
    where that test rejects a shrink of 0 (the ratio 1), so it says whether naming reduced the
    gap at all also where the ratio's interval has no end: a gap before within its noise of 0
    leaves the ratio unbounded, yet the robots' gaps before and after move together, and their
    difference can be clear (independent world 3281: before 0.14, 95 % CI -0.33 .. 0.71;
    removed 0.72, 0.30 .. 1.22)."""
    b, a = np.asarray(before_boot, dtype=float), np.asarray(after_boot, dtype=float)
    d = np.sort((b - a)[np.isfinite(a) & np.isfinite(b)])
    if not len(d):
        return [None, None]
    k = _tail_count(len(d), level)
    return [float(d[k - 1]), float(d[len(d) - k])]


def _residuals(meas, base, final, comps):
    """Per-robot held-out residuals of each model, in units of the final model's spread (for plots)."""
    out = {}
    for name, pred in (("before", base), ("after", final)):
        z = [np.nanmean(deviance((meas[c] - pred[c]["mean"]) / final[c]["sd"]), axis=0) for c in comps]
        out[name] = np.mean(z, axis=0)
    return out


def flagged_by_family(p_values, alpha: float) -> np.ndarray:
    """Which of a family of tests is flagged: p < alpha / (number of tests) (Bonferroni), so that
    a model that is right flags anything with probability at most ``alpha``."""
    p = np.asarray(p_values, dtype=float)
    return p < alpha / max(len(p), 1)


def decide(scores: dict, resolves, rng: np.random.Generator, boot: int, library: dict | None = None,
           gain_level: float = GAIN_LEVEL) -> dict:
    """The naming rule, applied to each family of rival explanations in turn.

    Candidates that predict disjoint summaries explain different data (:func:`_rivals`), so they
    are not judged against each other: the rule of :func:`_decide_family` is applied to the family
    of the best-scoring candidate (it and every candidate that predicts a summary in common with
    it), and when that family's best is not named, to the best-scoring family left, and so on.
    Where per-robot speeds and per-robot turn rates both differ, a speed effect that scores higher
    but cannot resolve its signal while the turn rates are still taken for trial-to-trial spread
    (the base's chords shorten by a different amount each trial) no longer hides the turn-rate
    effect that can. Within a family nothing is loosened: the runner-up is not tried in place of
    a best that fails. Returns the first named family's decision or, when none is named, the
    first family's; ``passed`` lists the families' bests tried before it and why each was not
    named.
    """
    library = E.LIBRARY if library is None else library
    left, passed, first = dict(scores), [], None
    while left:
        d = _decide_family(left, resolves, rng, boot, library, gain_level)
        first = first or d
        if d["named"]:
            break
        passed.append({"name": d["best"], "why_not": d["why_not"]})
        left = {k: v for k, v in left.items() if k != d["best"] and not _same_data(library, d["best"], k)}
    d = d if d["named"] else first
    d["passed"] = passed if d["named"] else []
    if d["passed"]:
        d["runner_up_reason"] += "; " + "; ".join(
            f"{x['name']} scored higher and predicts other summaries, but was not named ({x['why_not']})" for x in d["passed"])
    return d


def _decide_family(scores: dict, resolves, rng: np.random.Generator, boot: int, library: dict,
                   gain_level: float = GAIN_LEVEL) -> dict:
    """The naming rule within a family of rival explanations.

    ``scores[name]`` is each candidate's held-out log-likelihood gain over the current model,
    per robot (N,). The best (largest sum) is named only if

    1. the lower confidence bound at ``gain_level`` (one-sided, bootstrap over robots) of its
       gain over the current model is above 0,
    2. the lower end of the 95 % bootstrap interval of its gain over the runner-up is above 0:
       the runner-up is the best other candidate that is a rival
       explanation (:func:`_rivals`): not one that merely extends the best (it contains it, so
       it fits at least as well in sample; when it scores lower held-out the simpler best is
       preferred), nor one that predicts other summaries (it explains other data); and
    3. adding it resolves at least one flagged signal: ``resolves(name)`` returns the signals it
       removes (called only when 1 and 2 hold), counting only those of a kind the effect
       accounts for (:meth:`effects.Effect.explains`).

    Nested models are judged by parsimony: when the best extends another candidate (contains it
    as a special case) and does not beat it clearly (the lower end of the interval of its gain
    over it is not above 0), the simpler model takes its place as the best, and the rule goes on
    with it (the extension is then no rival of it).

    Clause 1 asks less confidence than clause 2 and parsimony (``gain_level``, 0.90 by default,
    against 0.975): it guards against naming an effect that does not predict held-out trials
    better, while false alarms on a right model are held off by the family-wise detection and by
    clause 3, and wrong names by clause 2. The held-out score is a much noisier test of a
    between-robot spread than the detection's F ratio (12 robots x 4 trials: at the spread the
    detection flags in 76 % of datasets, the gain's 95 % interval clears 0 in 52 %, its one-sided
    90 % bound in 76 %), so at 0.975 naming, not detection, set what a small dataset could see.

    Returns best, order (best then the rivals, runner-up first), both intervals (``ci_gain``:
    the bounds at 1 - ``gain_level`` and ``gain_level``; ``ci_diff``: 95 %), ``clear`` (1 and
    2), ``resolved``, ``named``, ``why_not`` (the first clause the best fails, None when named)
    and ``simplified`` (the extensions set aside for the simpler model they contain, with the
    95 % interval of their gain over it).
    """
    by_sum = sorted(scores, key=lambda k: -np.nansum(scores[k]))
    n = len(np.asarray(scores[by_sum[0]]))
    # One set of resampled robots for every interval of the decision: the same difference read
    # twice gives the same interval. With fresh draws per interval, an extension that beat the
    # model it contains clearly (parsimony) could then fail to beat it as its runner-up (clause
    # 2, the same difference): the third world's heading bias + drift 3223 named nothing so.
    idx = rng.integers(0, n, (boot, n))

    def ci(x, level=RIVAL_LEVEL):
        x = np.asarray(x, dtype=float)
        return np.percentile(np.nansum(x[idx], axis=-1), [100 * (1 - level), 100 * level])

    best, simplified = by_sum[0], []
    while best in library:
        simpler = [k for k in library[best].extends if k in scores]
        if not simpler:
            break
        # the best-scoring model it contains
        s = max(simpler, key=lambda k: np.nansum(scores[k]))
        ci_s = ci(np.asarray(scores[best], dtype=float) - np.asarray(scores[s], dtype=float))
        if ci_s[0] > 0:
            break
        simplified.append({"name": best, "instead": s, "ci95": [float(x) for x in ci_s]})
        best = s
    gain = np.asarray(scores[best], dtype=float)
    ci_gain = ci(gain, gain_level)
    rivals = [k for k in by_sum if k != best and _rivals(library, best, k)]
    order = [best] + rivals
    ci_diff = ci(gain - np.asarray(scores[rivals[0]], dtype=float)) if rivals else np.array([np.inf, np.inf])
    clear = bool(ci_gain[0] > 0 and ci_diff[0] > 0)
    resolved = list(resolves(best)) if clear else []
    extending = [k for k in by_sum if k != best and k in library and best in library[k].extends]
    apart = [k for k in by_sum if k != best and k not in rivals and k not in extending]
    why = "the best-scoring other candidate" if rivals else "no other candidate"
    if extending:
        why += (f"; {', '.join(extending)} skipped: it extends {best} (contains it as a special case), so it cannot be "
                "a rival to a simpler model it contains")
    if apart:
        why += (f"; {', '.join(apart)} skipped: it predicts other summaries than {best} does, so it is no other "
                "explanation of the same data (it may be named in a later step)")
    if simplified:
        why += "; " + "; ".join(f"{x['name']} scored higher but does not beat {x['instead']}, which it contains, clearly "
                                f"(gain over it, 95 % CI {x['ci95'][0]:.1f} .. {x['ci95'][1]:.1f}): the simpler model is preferred"
                                for x in simplified)
    if not ci_gain[0] > 0:
        why_not = f"its gain over the current model is not above 0 at the one-sided {gain_level:.0%} bound"
    elif not ci_diff[0] > 0:
        why_not = f"it does not beat the runner-up, {order[1]}, clearly (the 95 % interval of its gain over it reaches 0)"
    else:
        why_not = None if resolved else "adding it removes none of the flagged signals"
    return {"best": best, "order": order, "ci_gain": ci_gain, "ci_diff": ci_diff, "clear": clear,
            "resolved": resolved, "named": clear and bool(resolved), "why_not": why_not,
            "runner_up_reason": why, "simplified": simplified}


def _rivals(library: dict, best: str, other: str) -> bool:
    """Whether ``other`` is a rival explanation to ``best``: it does not merely extend ``best``,
    and the two predict at least one summary in common (candidates that predict disjoint
    summaries, such as per-robot speeds and per-robot turn rates, explain different data and
    are named one after the other, not against each other). Candidates outside the library
    are always rivals."""
    if best not in library or other not in library:
        return True
    return best not in library[other].extends and _same_data(library, best, other)


def _same_data(library: dict, a: str, b: str) -> bool:
    """Whether ``a`` and ``b`` are of one family: they predict a summary in common (candidates
    outside the library: always). Rivals, extensions and the models extended are of the family."""
    if a not in library or b not in library:
        return True
    return bool(set(library[a].predicts) & set(library[b].predicts))


# --- the loop -------------------------------------------------------------------------------------

def _enough_to_summarise(ds: measured.Dataset, meas: dict) -> None:
    """A one-line error unless some robot's tracks give the kind's first summary (turn rate, gain,
    toggle rate: the one every fit needs) in two trials (tracks of a sample or two each left every
    summary NaN, and the noise fit stopped on a NumPy traceback)."""
    key = COMPONENTS[ds.kind][0]
    if np.isfinite(meas[key]).sum(axis=0).max(initial=0) < 2:
        raise ConfigError(str(ds.path), f"no robot has two trials whose tracks give a {key} (each {ds.kind} summary "
                          "needs a track of some seconds)", "record longer tracks, or check the t_s column")


def analyse(ds: measured.Dataset, gs: GapSettings, base: E.TwinModel | None = None, log=print) -> dict:
    """Run the workflow on one dataset; returns the report section and the final model."""
    t0 = time.perf_counter()
    cond, meas = measured_summaries(ds)
    kind = ds.kind
    _enough_to_summarise(ds, meas)
    meas = E.Summaries(meas, np.arange(cond.trials))
    fit_base = base is None
    start = (dataclasses.replace(base, forward_speed_m_s=cond.forward_speed_m_s) if base is not None
             else E.nominal_model(kind, cond.robot_ids, cond.forward_speed_m_s))
    fitter = _Fitter(cond, meas, start, gs, fit_base)
    comps = COMPONENTS[kind]
    all_trials = list(range(cond.trials))
    rng = np.random.default_rng(np.random.SeedSequence(gs.seed, spawn_key=(_PURPOSE["bootstrap"],)))
    names: tuple = ()
    steps, disagreements, not_named = [], [], None
    unexplained, unexplained_signals = False, []
    pred_cache = {(): _heldout(fitter, (), kind)}
    nulls = {}  # (model names, round) -> a null simulated already
    candidates = [e for e in gs.library.values() if e.kind == kind]
    for round_ in range(gs.max_steps + 1):
        model = fitter.fit(names, all_trials)
        null = nulls.pop((names, round_), None)
        if null is None:
            null = simulate(cond, model, gs.m_null, child_seed(gs.seed, "null", round_))
        found = detect(kind, meas, null, cond.trials, gs.alpha, [gs.library[n] for n in names])
        if round_ == 0:
            tests = [f["signal"] for f in found]
            mde = minimum_detectable(kind, meas, null, cond.trials, gs.alpha, seed=child_seed(gs.seed, "power"), base=model,
                                     gain_level=gs.gain_level, threads=gs.threads,
                                     sensitivity=summary_sensitivity(cond, model, child_seed(gs.seed, "sensitivity")))
            # Effects of your own that give at_size: the size flagged, by simulating the twin
            for j, e in enumerate(candidates):
                if e.name not in mde and e.states_size():
                    log(f"[{kind}] what the data can see of {e.name}: simulating it at sizes up to {e.size_range[1]:g}")
                    mde[e.name] = simulated_detection(kind, cond, model, null, gs.alpha, e, child_seed(gs.seed, "power", 1 + j),
                                                      threads=gs.threads)
                elif e.name not in mde:
                    mde[e.name] = none_stated(e.size_unit or None, "the effect gives no at_size (with size_range and "
                                              "size_unit), so the twin cannot be simulated with it at a size")
        flagged = [f for f in found if f["flagged"]]
        for f in flagged:
            disagreements.append({"round": round_, "signal": f["signal"], "robots": [int(cond.robot_ids[i]) for i in f["robots"]],
                                  "trials": f["trials"], "statistic": f["statistic"], "z": f["z"], "p_value": f["p_value"],
                                  **{key: f[key] for _, key in _ALONE.values() if key in f}})
        log(f"[{kind}] round {round_}: model {list(names) or ['base']}; flagged "
            f"{[f['signal'] for f in flagged] or 'nothing'}")
        if not flagged or round_ == gs.max_steps:
            break
        cur = pred_cache[names]
        ll_cur = _loglik_per_robot(meas, cur, comps)
        scores, aside = {}, []
        for e in candidates:
            if e.name in names:
                continue
            if not any(e.explains(f["signal"]) for f in flagged):
                # It could not resolve any flagged signal (clause 3 of the naming rule), so it does
                # not compete: a per-robot speed effect that scores well where robots' speeds differ
                # by a chord's shortening does not stop the search for what turns them apart.
                aside.append(e.name)
                continue
            cand = names + (e.name,)
            pred_cache[cand] = _heldout(fitter, cand, kind)
            scores[e.name] = _loglik_per_robot(meas, pred_cache[cand], comps) - ll_cur  # (N,)
        if not scores:
            log(f"[{kind}]   no candidate accounts for {[f['signal'] for f in flagged]}")
            unexplained, unexplained_signals = True, [f["signal"] for f in flagged]
            not_named = {"round": round_, "signals": unexplained_signals, "scores": {}, "set_aside": aside,
                         "best": None, "why": "no candidate of the library accounts for these signals"}
            break
        def resolves(name):
            # A name must remove a disagreement, not only raise the likelihood elsewhere.
            cand_model = fitter.fit(names + (name,), all_trials)
            next_null = simulate(cond, cand_model, gs.m_null, child_seed(gs.seed, "null", round_ + 1))
            nulls[(names + (name,), round_ + 1)] = next_null  # the next round's null, if it is named
            after = {f["signal"]: f for f in detect(kind, meas, next_null, cond.trials, gs.alpha,
                                                    [gs.library[n] for n in names + (name,)])}
            return [f["signal"] for f in flagged if not after[f["signal"]]["flagged"] and gs.library[name].explains(f["signal"])]

        d = decide(scores, resolves, rng, gs.boot, gs.library, gs.gain_level)
        best, order, ci_gain, ci_diff, resolved = d["best"], d["order"], d["ci_gain"], d["ci_diff"], d["resolved"]
        gain = scores[best]
        log(f"[{kind}]   scores: " + ", ".join(f"{k} {np.nansum(scores[k]):+.1f}" for k in order)
            + f"; best {best} vs current [{ci_gain[0]:.1f}, {ci_gain[1]:.1f}] (one-sided {gs.gain_level:.0%}), vs runner-up "
            f"[{ci_diff[0]:.1f}, {ci_diff[1]:.1f}] (95 % CI)"
            + (f"; resolves {resolved or 'no flagged signal'}" if d["clear"] else ""))
        if not d["named"]:
            unexplained, unexplained_signals = True, [f["signal"] for f in flagged]
            not_named = {"round": round_, "signals": unexplained_signals, "set_aside": aside, "best": best,
                         "scores": {k: float(np.nansum(v)) for k, v in scores.items()},
                         "ci_gain": [float(x) for x in ci_gain], "level": gs.gain_level,
                         "runner_up": order[1] if len(order) > 1 else None,
                         "ci95_over_runner_up": [float(x) for x in ci_diff] if len(order) > 1 else None,
                         "why": d["why_not"]}
            break
        names = names + (best,)
        steps.append({
            "name": best,
            "score_vs_current": {"loglik_gain": float(np.nansum(gain)), "ci": [float(x) for x in ci_gain],
                                 "level": gs.gain_level},  # ci: the one-sided bounds at level
            "runner_up": {"name": order[1] if len(order) > 1 else None,
                          "loglik_gain_over_it": float(np.nansum(gain - scores[order[1]])) if len(order) > 1 else None,
                          "ci95": [float(x) for x in ci_diff] if len(order) > 1 else None,
                          "why_this_one": d["runner_up_reason"]},
            "scores": {k: float(np.nansum(v)) for k, v in scores.items()},
            "set_aside": aside,  # candidates that account for none of the flagged signals
            "signals": [f["signal"] for f in flagged],
            "resolved": resolved,
        })
    final = fitter.fit(names, all_trials)
    # The gap before/after on held-out trials (leave-one-trial-out), on the final model's
    # yardstick, with a paired bootstrap over robots.
    pred_base, pred_final = pred_cache[()], pred_cache[names]
    n = len(cond.robot_ids)
    before, after = _gap(meas, pred_base, pred_final, comps), _gap(meas, pred_final, pred_final, comps)
    idx = rng.integers(0, n, (gs.boot, n))
    bb = np.stack([_gap(meas, pred_base, pred_final, comps, idx), _gap(meas, pred_final, pred_final, comps, idx)], -1)
    # The shrink is measured where the disagreement was: the summaries of the signals flagged
    # against the base, per track on the final model's yardstick (robots or trials that differ)
    # and, for a flagged level, per trial level. Summaries and parts that agreed already add only
    # their sampling noise to both terms of the ratio.
    first = [d["signal"].split(":") for d in disagreements if d["round"] == 0]
    where = [c for c in comps if any(c == comp for comp, _ in first)]
    # per track, and also the model's own spread where a named effect changes how much robots
    # scatter (robots that differ in noise show in their spread more than in their means)
    own = any("own" in gs.library[n].gap_parts for n in names)
    parts = ("track",) + (("own",) if own else ()) + (("level",) if any(stat == "level" for _, stat in first) else ())
    if where:
        fb, fa = _gap(meas, pred_base, pred_final, where, parts=parts), _gap(meas, pred_final, pred_final, where, parts=parts)
        fbb = np.stack([_gap(meas, pred_base, pred_final, where, idx, parts), _gap(meas, pred_final, pred_final, where, idx, parts)], -1)
        shrink_doc = {"value": float(1 - fa / fb) if fb > 0 else 0.0, "ci95": shrink_interval(fb, fa, fbb[:, 0], fbb[:, 1]),
                      "removed": float(fb - fa), "removed_ci95": removed_interval(fbb[:, 0], fbb[:, 1]),
                      "summaries": where, "before": fb, "after": fa,
                      "before_ci95": [float(x) for x in np.percentile(fbb[:, 0], [2.5, 97.5])],
                      "after_ci95": [float(x) for x in np.percentile(fbb[:, 1], [2.5, 97.5])]}
    else:
        shrink_doc = {"value": 0.0, "ci95": [0.0, 0.0], "removed": 0.0, "removed_ci95": [0.0, 0.0], "summaries": [],
                      "before": 0.0, "after": 0.0,
                      "before_ci95": [0.0, 0.0], "after_ci95": [0.0, 0.0]}
    for j, st in enumerate(steps):
        st["gap_after"] = _gap(meas, pred_cache[names[: j + 1]], pred_final, comps)
    metric = ("held-out prediction error (leave-one-trial-out) of the summaries (" + ", ".join(comps)
              + "): mean deviance (z^2 within 4 sd, 2k|z| - k^2 beyond) minus a right model's, per track (final "
              "model's spread), per track (own spread) and per trial level; "
              "spreads are predictive (simulated noise + estimation error of the fitted parameters)")
    section = {
        "dataset": str(ds.path), "kind": kind, "robots": [int(r) for r in cond.robot_ids], "trials": cond.trials,
        "named_effects": list(names), "unexplained": unexplained, "unexplained_signals": unexplained_signals,
        "gap_before": {"metric": metric, "value": before, "ci95": [float(x) for x in np.percentile(bb[:, 0], [2.5, 97.5])]},
        "gap_after": {"metric": metric, "value": after, "ci95": [float(x) for x in np.percentile(bb[:, 1], [2.5, 97.5])]},
        "gap_shrink": shrink_doc,
        "gap_by_part": gap_by_part(meas, pred_base, pred_final, comps),
        # per summary: the share of a robot's held-out deviation its trial's robots have in common
        # (0 unless the data show it; shared_deviation), and the sd of what of it the per trial
        # level's spread takes as shared: only rounding that no noise dithers (see _heldout)
        "shared_deviation": {c: float(pred_final[c]["shared"]) for c in comps},
        "shared_rounding_sd": {c: pred_final[c]["shared_sd"] for c in comps},
        "tests": tests,  # the detection's statistics (round 0), flagged or not
        "nuisances": _nuisances(fitter.fit((), all_trials), cond) if fit_base else {},
        # how far the robots at hand pin the base's noise levels (effects.noise_intervals)
        "nuisance_ci90": (_nuisance_intervals(fitter, meas, cond, gs) if fit_base else {}),
        # Per-robot estimates of the named effects' traits: ``individual`` (in model.yaml: the
        # robots' spread kept) and ``predictive`` (pooled towards the population: each robot's
        # best prediction, what the held-out gap was scored with).
        # ``expected_r``: how closely the individual estimates can follow the robots' true values
        # from these trials (sqrt of the pooling weights' mean, see effects.TwinModel.with_individual).
        "estimates": {k: {"individual": [float(x) for x in v], "predictive": [float(x) for x in final.swarm.values[k]],
                          "expected_r": final.expected_r[k]}
                      for k, v in final.individual.items()},
        # scenario fields the named effects fitted for the whole swarm (TwinModel.scenario), as a
        # scenario file spells them: a user's own effect's tilted floor, for instance
        "scenario": dict(final.scenario),
        "minimum_detectable": mde,
        "tracked_point": (tracked_point_offset(meas, final)
                          if kind == "motion" and "speed_heterogeneity" in names else None),
        "steps": steps,
        # the round that named nothing while signals were flagged: its scores and why its best was not named
        "not_named": not_named,
        "disagreements": disagreements, "seconds": time.perf_counter() - t0,
    }
    return {"section": section, "model": final, "residuals": _residuals(meas, pred_cache[()], pred_cache[names], comps)}


def tracked_point_offset(meas, model: E.TwinModel) -> dict | None:
    """How far to the side of its rotation centre each robot's tracked point would have to sit to
    make the named speed spread alone. A point r_perp to the side of the centre of a robot
    turning at omega moves at v - omega r_perp, so robots that turn at different rates, tracked
    at points scattered about their centres, differ in tracked speed by sd over robots
    omega_i r_i / v = rms(omega) rms(r_perp) / v, however alike their motors: the summaries cannot
    tell the two apart (the third world's markers, up to 3.6-12 mm off the centre, on robots
    whose turn rates differ by 0.0086 rad/s or drift, read as a spread of 0.4-0.5 % of the
    speed). ``offset_m``: that rms(r_perp), from the individual speed factors' relative spread,
    the data's mean speed and the rms of the robots' mean turn rates (the population's included);
    ``within_body``: whether it is at most a Kilobot's body radius (a marker or LED blob sits on the
    robot; beyond that, no tracked point can make the spread: for the evaluations' hidden spreads
    of sd 0.12, 11-68 cm)."""
    f = model.individual.get("speed_factor")
    f = np.asarray(model.swarm.values["speed_factor"] if f is None else f, dtype=float)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a robot seen in no trial
        w = np.nanmean(np.asarray(meas["turn_rate"], dtype=float), axis=0)
        v = float(np.nanmean(meas["speed"]))
    w = w[np.isfinite(w)]
    spread = float(np.std(f, ddof=1) / np.mean(f)) if len(f) > 1 else 0.0
    rms = float(np.sqrt(np.mean(w**2))) if len(w) else 0.0
    if not (rms > 0 and np.isfinite(v) and v > 0):
        return None
    offset = spread * v / rms
    return {"speed_spread": spread, "turn_rate_rms_rad_s": rms, "speed_m_s": v, "offset_m": offset,
            "body_radius_m": BODY_RADIUS_M, "within_body": bool(offset <= BODY_RADIUS_M)}


#: effect -> (summary whose between-robot F statistic detects it, how its size is expressed)
_MDE_OF = {"motion": {"heading_bias": ("turn_rate", "sd of the per-robot turn rate, rad/s"),
                      "bias_drift": ("turn_rate", "sd of the per-robot change of turn rate per trial, rad/s"),
                      "speed_heterogeneity": ("speed", "relative sd of the per-robot speed factor"),
                      "motion_noise": ("diffusion", "sd of the per-robot heading diffusion, rad^2/s")},
           "light_sweep": {"sensor_gain": ("gain", "relative sd of the per-robot sensor gain")},
           "blink": {"clock_drift": ("toggle_rate", "relative sd of the per-robot clock rate")}}


_NOISE_UNIT = "sd over robots of ln sigma_omega (heading-noise intensities differ by a factor exp(size) per sd)"
#: The largest spread of noise intensities the MDE search goes to: robots' sigma_omega a factor
#: e^2 = 7.4 apart per sd (beyond it a lognormal spread is one robot against the rest).
_MAX_LOG_SD = 2.0

#: Effects whose spread the base model takes in as trial-to-trial spread (Eq. 4: identical robots,
#: all of the spread beyond measurement is per trial), so that the base predicts them wider.
_BASE_ABSORBS = {"heading_bias", "bias_drift", "clock_drift"}

#: Per kind, the trait each summary's size moves (a turn rate in rad/s through the heading bias,
#: or a factor on the trait) and the step of the probe (:func:`summary_sensitivity`).
_PROBE_TRAIT = {"motion": {"turn_rate": ("heading_bias", 0.002), "speed": ("speed_factor", 0.01)},
                "light_sweep": {"gain": ("sensor_gain", 0.01)}, "blink": {"toggle_rate": ("clock_rate", 0.01)}}


def summary_sensitivity(cond: Conditions, model: E.TwinModel, seed: int, M: int = 8) -> dict:
    """How far each summary that a minimum detectable size is read in moves per unit of that size,
    under this dataset's conditions (its frame rate, gaps, tracking noise): summary -> slope, in
    the summary's units per rad/s (turn rate) or as a share of its level per relative step of the
    trait (speed, gain, toggle rate). 1 for a summary that follows its trait exactly.

    It is not 1 in general: the speed summary is a mean distance over a lag, which tracking noise
    lengthens the more the shorter it is, so it moves by 0.79 of a robot's relative speed
    difference under 5 mm of tracking noise at 10 Hz (independent world, seed 3000; the robots'
    measured means against their true speeds: 0.73), and speed sizes read through the summary's
    level alone were named in 10 of 20 datasets set to them.

    Measured by simulation: the model, and the model with each robot's trait moved by a small
    step times a standardised draw (each summary's own draw), on the same random numbers; the
    slope of the robots' mean differences on their steps, both traits at once (a robot's speed
    also moves its turn rate). A slope that is not positive (no robot tracked) is taken for 1."""
    probe = _PROBE_TRAIT.get(cond.kind, {})
    N = len(model.swarm)
    if N < 3 or not probe:
        return {}
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(1,)))
    z = rng.standard_normal((len(probe), N))
    z = (z - z.mean(1, keepdims=True)) / z.std(1, ddof=1, keepdims=True)
    moved = {}
    for (comp, (trait, step)), zj in zip(probe.items(), z):
        if trait == "heading_bias":  # a turn-rate step, in the twin's bias at each robot's speed
            moved[trait] = model.swarm.heading_bias + E._bias((step * zj)[None, :], model)[0]
        else:
            moved[trait] = getattr(model.swarm, trait) * (1.0 + step * zj)
    s0 = simulate(cond, model, M, seed)
    s1 = simulate(cond, model.with_traits(**moved), M, seed)
    X = np.column_stack([step * zj for (_, step), zj in zip(probe.values(), z)] + [np.ones(N)])
    out = {}
    for j, comp in enumerate(probe):
        with np.errstate(all="ignore"):
            d = np.nanmean(s1[comp] - s0[comp], axis=(0, 1))
            if comp != "turn_rate":
                d = d / abs(float(np.nanmean(s0[comp])))
        ok = np.isfinite(d)
        slope = float(np.linalg.lstsq(X[ok], d[ok], rcond=None)[0][j]) if ok.sum() > X.shape[1] else float("nan")
        out[comp] = slope if np.isfinite(slope) and slope > 0 else 1.0
    return out


def none_stated(unit: str | None, why: str) -> dict:
    """A ``minimum_detectable`` entry for an effect these data give no size for, and why: every
    effect a report can name is listed, so that its absence never reads as "nothing to see"."""
    return {"size": None, "detection_size": None, "unit": unit, "why_none": why}


def minimum_detectable(kind: str, meas: dict, null: dict, trials: int, alpha: float, power: float = 0.8,
                       seed: int = 0, base: E.TwinModel | None = None, gain_level: float = GAIN_LEVEL,
                       sensitivity: dict | None = None, threads: int = 1) -> dict:
    """The smallest between-robot spread of each effect that this dataset (its robots, trials,
    gaps, noise) would have named with ``power``: ``size``, and ``detection_size``, the smallest
    the detection step alone flags with ``power``. A spread is that of the dataset's own robots
    (their sd, ddof 1), not of a population they are drawn from: what a user's swarm has, and
    what an evaluation sets. Sizes are found in the summary's units and read in the trait's
    through ``sensitivity`` (:func:`summary_sensitivity`; without it the summary is taken to
    follow its trait exactly), which each entry states as ``summary_per_size``.

    Detection: between robots that differ by sd tau, a robot's mean over its K trials varies by
    an extra tau^2, so the F ratio of between- to within-robot mean squares grows by the factor
    1 + K tau^2 / s_w^2 (s_w^2: the within-robot variance of one trial's summary, from the data:
    a between-robot effect, if present, is not in it). Its logarithm is what :func:`detect`
    compares with the simulated null (sd s0), flagging above z(alpha / n) s0; so ``power`` is
    reached near log(1 + K tau^2 / s_w^2) = (z(alpha / n) + z(1 - power)) s0. A drift (summaries
    changing by sd tau per trial) raises the trend statistic's ratio by 1 + S_kk tau^2 / s_w^2.
    That closed form carries the null's sd to the alternative, where the log F of robots that
    differ by a fixed spread scatters less, and it overstates the size (by 9 % at 12 robots x 4
    trials: the random-effects answer, for robots drawn from a population of that sd); it only
    sets where the search starts. ``detection_size`` is read off the emulation below
    (:func:`detection_power`: its flags alone), on the same emulated datasets as the size named,
    so it is never above it.

    Naming also needs the held-out score (:func:`decide`), which is noisier than the F ratio: at
    the detection size it is often not clear. Its power is found by emulation in summary space
    (:func:`naming_power`): the data's gaps and within-robot variance, robots differing by tau,
    detection against the null's spread, and the leave-one-trial-out likelihood of the effect's
    pooled per-robot estimates against the base, with the bootstrap over robots of the rule.
    The within-robot variance is itself estimated from the dataset's trials: the emulation
    averages the power over what it may be (``naming_power``'s ``dof``), so a size is the one a
    fresh dataset of the same noise names with ``power``, not the one this dataset's estimate,
    taken for exact, would. An effect that predicts more summaries per robot than the one its
    size is read in (a sensor gain: offsets too) pays for their estimates in the held-out score,
    and the emulation charges it (``companions``).

    Robots that differ in noise (``motion_noise``) differ by a factor: the emulation draws their
    intensities lognormal around the ``base`` model's and lets the noisier robots' summaries
    scatter more (:func:`naming_power`), and the size is the sd over robots of ln sigma_omega
    (the base fit's map, ``base.noise_map``, says how much of the diffusion summary the heading
    noise makes), searched up to 2 (sigma_omega a factor 7.4 apart per sd).
    """
    from scipy.stats import norm

    stats = statistics(kind, null, trials, model_variances(kind, null))
    sd0 = {name: null_sd(v, sided) for name, (v, sided) in stats.items()}  # each statistic's null spread
    z_det = norm.isf(alpha / len(stats))
    z = z_det + norm.isf(1 - power)
    out = {}
    for effect, (comp, unit) in _MDE_OF.get(kind, {}).items():
        drift = effect == "bias_drift"
        stat = f"{comp}:trial_trend" if drift else f"{comp}:between_robots"
        if stat not in stats:  # fewer than 3 trials: no trend statistic
            out[effect] = none_stated(unit, f"a trend over trials needs 3 trials or more; these data have {trials}")
            continue
        s0 = sd0[stat]
        x = meas[comp]  # (K, N)
        shift = 0.0  # where the resolution floors the data's F and the null's apart (below)
        with np.errstate(all="ignore"):
            seen = np.isfinite(x)
            if drift:
                # Within-robot variance about each robot's line (a drift, if any, is not noise).
                s_w2, dof, k_eff = about_lines(x)
            elif effect == "motion_noise":
                k_eff = float(np.nanmean(seen.sum(0)))
                # Robots that differ in noise scatter within themselves by more than the
                # population's noise makes (a robot e^1.2 noisier scatters 11x as much), so the
                # data's within-robot variance holds the effect: the emulation, which scales its
                # noise by each robot's intensity, starts from the variance at the population's
                # intensity, the base model's own (its simulated null; mean over replicates).
                s_w2 = float(np.nanmean(E.within_var(null[comp])))
                dof = None  # the base model's, simulated: not estimated from the dataset's trials
            else:
                k_eff = float(np.nanmean(seen.sum(0)))
                dof = int((seen.sum(0) - 1).clip(0).sum())
                s_w2 = E.within_var(x)
                # Below the ADC's rounding the F ratios count no difference: their within-robot
                # mean square is floored there (:func:`_resolution`), which lowers the data's F
                # by phi_d = ln(floor / s_w^2) where the data's trials vary less, and the null's
                # by phi_m (its mean over the base's replicates). The test flags the data's F
                # above the null's, so on the emulation's scale (the F without the floor) the
                # threshold moves by phi_d - phi_m: 0 where the base rounds as the data do (both
                # floored alike, a sensor without noise fitted without any) or where neither is
                # floored. Taking the floor for the data's within-robot variance instead said
                # nothing of where the null lies: a base whose gains vary at the floor from
                # sweep to sweep against data that vary 0.55x as much (independent world 3060)
                # names less than stated, one that varies as little as the data names more.
                floor = _resolution(meas, comp)
                if floor is not None:
                    floored = _resolution(null, comp)
                    shift = float(_f_between(x) - _f_between(x, floor)
                                  - np.nanmean(_f_between(null[comp]) - _f_between(null[comp], floored)))
            least = _predictive_floor(kind, x, x)  # as the held-out trials are predicted
            if s_w2 < least:
                s_w2, dof = least, None
            tau_det = float(np.sqrt(s_w2 * np.expm1(z * s0 + shift) / max(k_eff, 1.0)))
            level = float(np.nanmean(x))
        noise, scale = None, (1.0 if comp == "turn_rate" else 1.0 / abs(level))
        if effect == "motion_noise":
            # Robots whose heading-noise intensities differ by a factor: sizes are the sd over robots
            # of ln sigma_omega, emulated lognormal (naming_power). The noise's share of the
            # summary at the population's intensity comes from the base fit's map (without one, a
            # base given by the user, the whole summary is taken for noise).
            nm = base.noise_map if base is not None else {}
            nm = nm if nm.get("diffusion_per_var", 0.0) > 0 else {}  # a map that sees no heading noise
            lvl = nm["diffusion_per_var"] * float(np.mean(base.swarm.sigma_omega**2)) if nm else level
            if not lvl > 0:  # no heading noise to differ in
                out[effect] = none_stated(_NOISE_UNIT, (
                    "the base model fits no heading noise to these tracks (sigma_omega 0: they wander no more than the "
                    "tracker's noise makes them), and robots that differ in noise differ by factors of it"
                    if nm else "the tracks' mean diffusion is not above 0: no heading noise to differ in"))
                continue
            noise = (lvl, float(np.clip(1.0 - nm.get("diffusion_within_var0", 0.0) / max(s_w2, 1e-300), 0.0, 1.0)))
            # the detection size in those units: the summary's sd over robots is lvl sqrt(exp(4 tau^2) - 1)
            tau_det = 0.5 * float(np.sqrt(np.log1p((tau_det / lvl) ** 2)))
            scale, unit = 1.0, _NOISE_UNIT
        # The effects a drift contains (the heading bias) compete where a signal they explain is flagged.
        contained = [n for n in stats if drift and any(E.LIBRARY[r].explains(n) for r in E.LIBRARY[effect].extends)]
        rival = z_det * sd0[contained[0]] if contained else None
        # The other summaries the effect predicts per robot (a sensor gain's offsets): their
        # estimates cost held-out likelihood where robots do not differ in them.
        companions = [np.isfinite(meas[c]) for c in E.LIBRARY[effect].predicts if c != comp and c in meas]
        taus = _spreads(tau_det, 0.7, 20, noise is not None)
        # 2 trials: the size named is not emulated (below), only the detection size.
        two = (f"with {trials} trials each is held out against one other, which cannot tell a robot's own level "
               "from that trial's noise; record 3 trials or more") if trials < 3 else None
        if two is None:
            pw = naming_power(seen, s_w2, taus, drift, effect in _BASE_ABSORBS, z_det * s0 + shift, seed=seed, noise=noise,
                              gain_level=gain_level, dof=dof, rival_threshold=rival, companions=companions,
                              threads=threads, stop_at=power)
            tau = _first_crossing(taus, pw, power)
        else:
            # 2 trials: each is held out against the other alone, on which a fold fits each
            # robot's level with nothing left to tell it from that trial's own noise. The
            # emulation's folds read the within-robot variance of the trials they keep, which is
            # 0 for one (every robot predicted exactly), and it stated "none" where the workflow
            # named a heading bias in 3 of 3 datasets of 6 robots x 2 trials. Taking each
            # replicate's own variance there instead, its sizes were named in 8 of 11 (heading
            # bias) and 1 of 5 (speed) 2-trial datasets of the independent world at the size
            # stated. So the size named is not stated; the detection size (the F test's) is.
            pw, tau = np.full(len(taus), np.nan), np.inf
        # The detection size on the same emulated datasets, from well below the closed form's
        # (which overstates it, see detection_power); never above the size named (naming needs
        # the flag: only the interpolation between spreads could put it above).
        det_taus = _spreads(tau_det, 0.2, 28, noise is not None)
        tau_flag = min(_first_crossing(det_taus, detection_power(seen, s_w2, det_taus, drift, z_det * s0 + shift, seed=seed,
                                                                 noise=noise, dof=dof), power), tau)
        per_size = 1.0 if noise is not None else float((sensitivity or {}).get(comp, 1.0))
        scale /= per_size
        # None: not named (or flagged) with that power within the spreads searched (too few
        # robots), up to ``searched_to``: 16x the closed form's detection size or, for noise
        # intensities, a spread of _MAX_LOG_SD.
        named = tau * scale if np.isfinite(tau) else None
        out[effect] = {"size": named, "detection_size": tau_flag * scale if np.isfinite(tau_flag) else None,
                       "searched_to": float(max(taus[-1], det_taus[-1])) * scale, "unit": unit, "summary_per_size": per_size}
        if named is None and np.isfinite(pw).any():
            # How near it came: the power need not grow without end (robots whose noise differs by
            # factors of e^2 per sd are one loud robot among quiet ones that read the tracker's
            # floor alike), so "none up to" can hide a spread named in 70 % of datasets.
            j = int(np.nanargmax(pw))
            out[effect] |= {"best_power": float(pw[j]), "best_at": float(taus[j]) * scale}
        if two:
            out[effect]["why_none"] = two
        if noise is None and np.isfinite(tau_flag):  # robots that differ in noise differ by factors: not an F's spread
            robots = int(seen.any(axis=0).sum())
            out[effect]["at_other_designs"] = other_designs(kind, tau_flag * scale, robots, trials, drift, alpha, power)
        if effect == "heading_bias" and named is not None:  # also in the twin's units, b = -omega L / v
            v = float(np.nanmean(null["speed"]))
            out[effect]["heading_bias_sd"] = float(abs(heading_bias_from_turn_rate(named, v)))
    return out


#: The designs a report scales each detection size to (:func:`other_designs`): a trial or two
#: more, twice the trials, twice the robots.
OTHER_DESIGNS = ((0, 1), (0, 2), (0, "x2"), ("x2", 0))


def f_test_size(robots: int, trials: int, drift: bool, alpha: float, power: float = 0.8) -> float:
    """The spread that the exact F test at one-sided level ``alpha`` flags with ``power``, in units
    of the within-robot sd of one trial's summary (for a drift: of its scatter about the robot's
    line), for robots whose own spread (ddof 1) is that: between robots, F(N - 1, N (K - 1)) with
    noncentrality K (N - 1) tau^2 / s_w^2; for drifts (each robot's slope over its trials), F(N,
    N (K - 2)) with S_kk (N - 1) tau^2 / s_w^2, S_kk = K (K^2 - 1) / 12 (the trend statistic of
    :func:`detect`, whose drifts are lines through each robot's own mean)."""
    from scipy import optimize
    from scipy import stats as st

    if drift:
        d1, d2, per = robots, robots * (trials - 2), trials * (trials**2 - 1) / 12.0
    else:
        d1, d2, per = robots - 1, robots * (trials - 1), float(trials)
    if robots < 2 or d2 < 1:
        raise ValueError(f"f_test_size: {robots} robots x {trials} trials leave the F test no degrees of freedom")
    crit = st.f.isf(alpha, d1, d2)
    hi = 1.0
    while st.ncf.sf(crit, d1, d2, hi) < power:
        hi *= 2.0
    lam = optimize.brentq(lambda lam: st.ncf.sf(crit, d1, d2, lam) - power, 0.0, hi, xtol=1e-10 * hi)
    return float(np.sqrt(lam / (per * (robots - 1))))


def other_designs(kind: str, detected: float, robots: int, trials: int, drift: bool, alpha: float,
                  power: float = 0.8) -> list:
    """The detection size at each of :data:`OTHER_DESIGNS`, scaled from this dataset's own
    (``detected``, emulated on its robots and trials) by the exact F test's size at both designs:
    robots and trials like these, more of them. The F test is what :func:`detect` runs on a
    summary, at the family's level, which counts the trend statistic once a design has 3 trials;
    the within-robot variance of a summary does not depend on how many trials or robots there
    are, so the ratio carries this dataset's noise, gaps and units over."""
    def level(k):  # the family's level at k trials: count the statistics :func:`statistics` makes there
        probe = np.random.default_rng(0).normal(1.0, 0.1, (k, 4))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return alpha / len(statistics(kind, {c: probe for c in (*COMPONENTS[kind], "heading")}, k))

    here = f_test_size(robots, trials, drift, level(trials), power)
    out, seen = [], set()
    for dn, dk in OTHER_DESIGNS:
        n = robots * 2 if dn == "x2" else robots + dn
        k = trials * 2 if dk == "x2" else trials + dk
        if (n, k) in seen:  # 2 trials: two more is twice as many
            continue
        seen.add((n, k))
        out.append({"robots": int(n), "trials": int(k),
                    "detection_size": float(detected * f_test_size(n, k, drift, level(k), power) / here)})
    return out


#: :func:`simulated_detection`: replicates per size (the share flagged has a Monte Carlo sd of
#: 0.04 at 80 %), in groups that each draw the effect afresh, and sizes tried over an effect's
#: ``size_range`` (geometric).
POWER_REPS, POWER_GROUPS, POWER_SIZES = 100, 5, 13
#: The pool a replicate's own null is drawn from holds this many times the data's null replicates
#: (each replicate's null of m is a random sample of the model's nulls whatever the pool's size; a
#: larger pool only lowers how alike two replicates' nulls are, m / size of the pool).
POOL_FACTOR = 4
#: Grid steps :func:`simulated_detection` goes below an effect's ``size_range`` where its smallest
#: size is flagged with the power already (synth 3374: 98 % at 0.005, the tilt's range's smallest),
#: each halving the size at least (a range guessed 100x too high is still searched down).
BELOW_RANGE_STEPS = 8
#: :func:`simulated_detection` screens each size on the first 1 / SCREEN_PARTS of each group's
#: replicates (20 of 100), and simulates the rest only where the screen flags more replicates than
#: a share of ``power`` flags with a probability below SCREEN_LEVEL (binomial: more than 9 of 20 at
#: 80 %, which a share of 80 % falls to with probability 0.0006).
SCREEN_PARTS, SCREEN_LEVEL = 5, 1e-3


def simulated_detection(kind: str, cond: Conditions, model: E.TwinModel, null: dict, alpha: float, effect: E.Effect,
                        seed: int, reps: int = POWER_REPS, sizes: int = POWER_SIZES, power: float = 0.8,
                        groups: int = POWER_GROUPS, pool: dict | None = None, threads: int = 1) -> dict:
    """The smallest size of an effect of your own that the detection step flags with ``power`` on
    datasets like this one, found by simulating the twin with the effect in it
    (:meth:`effects.Effect.at_size`): for each size of the effect's ``size_range`` (geometric), the
    model with the effect at that size is simulated under the data's conditions (their robots,
    trials, start poses, frames and gaps) ``reps`` times, in ``groups`` that each draw the effect
    afresh (``at_size``'s ``rng``: a floor's direction, robots' values; the share is then the
    power for an effect drawn so, not for one draw), and each replicate's statistics are
    tested against this dataset's null as :func:`detect` tests the data's, at the family's level.
    A replicate counts where a signal the effect explains is flagged. Every size draws the same
    random numbers, so the share flagged grows smoothly with the size; the size is read where it
    first reaches ``power`` (log-linear between sizes). The search stops at the first size flagged
    in 98 % of replicates, and goes on below the range (:data:`BELOW_RANGE_STEPS`) where its
    smallest size is flagged with ``power`` already (``at_most``: still so at the last one).
    Each size is screened first on a fifth of each group's replicates (:data:`SCREEN_PARTS`); the
    rest are simulated only where the screen could come from a share of ``power`` (all but where
    that is less likely than :data:`SCREEN_LEVEL`), and at the size below the crossing. The size
    found is then the one all replicates at every size would give, but where a share of ``power``
    or more looked like at most 45 % on the screen (probability under 1e-3); the sizes well below
    the crossing, which the search climbs through, cost a fifth (independent world 3327's tilted
    floor: 800 replicates simulated against 1,200, and with the pool at 4x rather than 8x the
    data's null, the search took 44.9 s against 74.6 s).

    The null is the one of the model fitted to these data: the statistics are ratios of mean
    squares (their own within-robot or residual yardstick), so the higher noise level that a base
    fitted to data with the effect in them may read moves their null little. Each replicate is
    tested against a null of its own, as a fresh dataset is against a null simulated afresh: as
    many replicates as this null has, drawn without replacement from a ``pool`` of the model's
    replicates (default: this null and :data:`POOL_FACTOR` - 1 times as many simulated beside it).
    The pool's parts and the sizes' groups are simulated ``threads`` at a time, each on its own
    seed, so the result does not depend on ``threads`` (on the third world's 3431, 35 x 8 at
    12 Hz, two threads took the whole ``gap`` with the user's tilt from 57.4 s to 44.2 s).
    The threshold (the null's mean plus z of its sd) scatters from null to null. When the
    heading dependence was read as a log F (2 degrees of freedom: long tails) rather than on its
    normal scale (:func:`_f2_normal_score`), the size read at this null's threshold alone was
    flagged in 75 % of fresh datasets (synth, indep, stress, seeds 3340-3359: 45/60 pooled), and
    with each replicate tested against a bootstrap resample of this null, which scatters less
    than fresh nulls do, in 74 % (seeds 3360-3399: 89/120); non-central F theory on one dataset
    gave 0.71, 0.74 and, for nulls drawn from a pool of ten, 0.81 (``benchmarks/eval_user_effect.py
    --at-mde``). On the normal scale the scatter is smaller, and the pool still reads it. Naming needs
    the held-out score as well, which is not simulated here (it would fit every replicate): the
    size named with ``power`` is at least this one, and "nothing flagged" reads "nothing larger".
    ``size`` is therefore None, ``detection_size`` the size found (None: not reached within the
    range), ``power_by_size`` the curve."""
    v = model_variances(kind, null)
    sim0 = statistics(kind, null, cond.trials, v)
    names = list(sim0)
    explained = np.array([effect.explains(n) for n in names])
    per = reps // groups
    # Each replicate's own null (the same for every size): M of the pool's replicates, M this null's
    m = len(np.asarray(sim0[names[0]][0]))
    if pool is None:  # in POOL_FACTOR - 1 parts of m, each its own seed, simulated ``threads`` at once
        def part(c):
            return simulate(cond, model, m, int(np.random.SeedSequence(seed, spawn_key=(groups + 1, c)).generate_state(1)[0]))

        with ThreadPoolExecutor(max(1, threads)) as ex:
            extra = list(ex.map(part, range(POOL_FACTOR - 1)))
        pool = {k: np.concatenate([null[k]] + [e[k] for e in extra]) for k in extra[0] if k in null}
    sp = statistics(kind, pool, cond.trials, v)
    nulls = {n: np.asarray(sp[n][0], dtype=float) for n in names}
    draw = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(groups,))).random((groups * per, len(nulls[names[0]])))
    pick = np.argsort(draw, axis=1)[:, :m]  # m without replacement, per replicate

    screen = max(1, per // SCREEN_PARTS)  # each group's first replicates: the screen's
    if explained.any():  # the screen's flags at most which rule out a share of ``power`` (binomial, SCREEN_LEVEL)
        from scipy import stats as _stats

        cut = int(_stats.binom.ppf(SCREEN_LEVEL, groups * screen, power)) - 1
    else:  # nothing the effect explains is tested, so nothing is flagged at any size: screens only
        cut = groups * screen

    def group(g, size, part):  # each group its own draw of the effect (a floor's direction, robots' values)
        ss = np.random.SeedSequence(seed, spawn_key=(g,))
        at = effect.at_size(model, float(size), np.random.default_rng(ss.spawn(1)[0]))
        # its screen's replicates (part 0) and the rest (part 1), each their own seed
        n, sim = (screen, per - screen)[part], np.random.SeedSequence(seed, spawn_key=(g, 1 + part))
        return statistics(kind, simulate(cond, at, n, int(sim.generate_state(1)[0])), cond.trials, v)

    def run(flags, size, part):  # fills flags (groups, per): 1 flagged, 0 not
        rows = range(screen) if part == 0 else range(screen, per)
        # the groups' simulations at once (they release the GIL); each its own seed, so the
        # shares do not depend on ``threads``
        with ThreadPoolExecutor(max(1, threads)) as ex:
            stats = list(ex.map(group, range(groups), [size] * groups, [part] * groups))
        for g, st in enumerate(stats):
            for i, r in enumerate(rows):
                p = [_p_value(float(np.asarray(st[n][0])[i]), nulls[n][pick[g * per + r]], st[n][1])[1] for n in names]
                flags[g, r] = flagged_by_family(p, alpha)[explained].any()

    tried = {}  # size -> its flags; NaN where not simulated (a size the screen ruled out)

    def share(size, whole=False):
        flags = tried.setdefault(size, np.full((groups, per), np.nan))
        if np.isnan(flags).all():
            run(flags, size, 0)
            whole = whole or np.sum(flags[:, :screen]) > cut
        if whole and np.isnan(flags).any():
            run(flags, size, 1)
        return float(np.nanmean(flags)) if explained.any() else 0.0

    grid = np.geomspace(*(float(x) for x in effect.size_range), sizes)
    shares = []
    for size in grid:
        shares.append(share(size))
        if shares[-1] >= 0.98:
            break
    ratio = max(float(grid[1] / grid[0]) if sizes > 1 else 2.0, 2.0)
    grid = list(grid[: len(shares)])
    for _ in range(BELOW_RANGE_STEPS):  # flagged at the range's smallest size already: on down
        if shares[0] < power:
            break
        grid.insert(0, grid[0] / ratio)
        shares.insert(0, share(grid[0]))
    j = next((i for i, w in enumerate(shares) if w >= power), 0)
    if j > 0:  # four more sizes where the share crosses: a steep curve is not linear between the grid's
        for size in np.geomspace(grid[j - 1], grid[j], 6)[1:-1]:
            grid.insert(j, float(size))
            shares.insert(j, share(size))
            j += 1
    while (j := next((i for i, w in enumerate(shares) if w >= power), 0)) > 0 and np.isnan(tried[grid[j - 1]]).any():
        shares[j - 1] = share(grid[j - 1], whole=True)  # the size below the crossing, read at all replicates
    found = _first_crossing(np.array(grid), shares, power)
    return {"size": None, "detection_size": found if np.isfinite(found) else None, "searched_to": float(grid[-1]),
            "at_most": bool(shares[0] >= power),  # flagged with power at the smallest size tried: the size is at most that
            "unit": effect.size_unit, "by": "simulation", "replicates": reps,
            "power_by_size": [[float(s), float(w)] for s, w in zip(grid, shares)],
            "replicates_by_size": [int(np.isfinite(tried[s]).sum()) for s in grid]}


def _spreads(tau_det: float, lowest: float, n: int, capped: bool) -> np.ndarray:
    """The spreads the MDE search tries: ``n`` from ``lowest`` to 16 times the closed form's
    detection size, geometrically; noise intensities (``capped``) up to :data:`_MAX_LOG_SD` (at
    least the first)."""
    taus = tau_det * np.geomspace(lowest, 16.0, n)
    if not capped:
        return taus
    return taus[taus <= _MAX_LOG_SD] if (taus <= _MAX_LOG_SD).any() else taus[:1]


def about_lines(x):
    """Each robot's line over its trials, x (K, N) with gaps: the residual variance about the
    lines (pooled), its degrees of freedom (a robot's observed trials less 2, summed) and the
    mean over robots of S_kk, the sum of squared trial offsets about the robot's mean trial (a
    robot's slope has the variance residual / S_kk)."""
    about_line, _, sxx = E.line_residuals(x)
    with np.errstate(all="ignore"):
        dof = int((np.isfinite(x).sum(0) - 2).clip(0).sum())
        return float(np.nansum(about_line**2) / max(dof, 1)), dof, float(np.mean(sxx))


def _first_crossing(x, y, level):
    """The x where y first reaches ``level`` (log-linear interpolation); inf if it never does."""
    hit = np.nonzero(np.asarray(y) >= level)[0]
    if not hit.size:
        return float("inf")
    j = int(hit[0])
    if j == 0:
        return float(x[0])
    t = (level - y[j - 1]) / max(y[j] - y[j - 1], 1e-12)
    return float(np.exp(np.log(x[j - 1]) + t * (np.log(x[j]) - np.log(x[j - 1]))))


def naming_power(seen, s_w2: float, taus, drift: bool, base_absorbs: bool, threshold: float, reps: int = 200,
                 boot: int = 200, seed: int = 0, noise: tuple | None = None, gain_level: float = GAIN_LEVEL,
                 dof: float | None = None, rival_threshold: float | None = None, companions=(),
                 threads: int = 1, stop_at: float | None = None) -> np.ndarray:
    """Probability that a between-robot effect of spread ``tau`` (each of ``taus``) is flagged
    and named, by emulation in summary space: per replicate, each robot's trial summaries are
    its own level (sd tau over the replicate's robots, exactly; a drift: its own slope over
    trials, sd tau, through the robot's mean over its trials) plus within-robot noise (variance ``s_w2``), where ``seen`` (K, N) has data. Flagged: the statistic of :func:`detect`
    above its null mean by ``threshold`` (z(alpha / n) times the null's sd). Named: the lower bound at
    ``gain_level`` (bootstrap over robots, as :func:`decide`) of the leave-one-trial-out
    log-likelihood gain of the effect's pooled per-robot estimates (:func:`effects.partial_pool`;
    noise intensities :func:`effects.pool_intensities`, as the effect pools them; with their
    predictive variance) over the base (a population level; its spread the
    within-robot one, or the whole spread where ``base_absorbs``) is above 0; a drift must also
    beat a robot's mean, its rival, at 95 % (``RIVAL_LEVEL``), where the rival competes: with
    ``rival_threshold`` (the between-robot statistic's flagging threshold, as ``threshold`` is the
    trend's) only in datasets where the robots' means differ flaggably, as the workflow scores only
    candidates that explain a flagged signal; without it, always.
    ``companions``: the ``seen`` arrays (K, N) of the other summaries the effect predicts per
    robot (a sensor gain's offsets), emulated without any spread between robots: the effect's
    per-robot estimates of them, pooled, still cost some held-out likelihood, which its score
    carries (about 0.5 in all on 40 robots x 7 trials; what a right sensor gain lost beyond that on
    the third world's offsets was the Monte Carlo error that :func:`effects.smooth_over_robots`
    removes). Their noise is normal; the cost does not depend on its scale. Where robots do differ in them, the effect
    gains there too, so the size stated is the one that holds when they do not.
    Common random numbers across ``taus``, so the curve is smooth in tau; ``threads`` of them are
    emulated at once, with the same result. ``stop_at``: the taus after the first whose power
    reaches it (and after the others emulated with it) are not emulated; their powers are NaN. A
    first crossing of that power (:func:`_first_crossing`) is the same as on the whole curve.

    ``noise = (level, f)``: robots that differ in a noise intensity (a variance, never negative),
    ``taus`` the sd over robots of the log of its square root (ln sigma_omega). The noise's share
    of a track's summary is ``level`` G at the population's intensity, G gamma-distributed with
    mean 1 and the variance ``f s_w2 / level^2`` (``f``: the share of the within-robot variance the
    noise makes; the rest, tracking, is normal and the same for every robot), and ``level r_i G``
    for a robot whose intensity is r_i = exp(s z_i - s^2 / 2) times the population's (s = 2 tau,
    lognormal with mean 1): a noisier robot's summary scales, its shape does not. A variance
    estimated from a track is skewed and rarely below 0 (simulated diffusion summaries: skew 2,
    1.6 % below 0 at 9 x the intensity); normal scatter scaled by r_i put 15 % of a noisy robot's
    tracks far below 0, where the log scale makes them outliers, and the stated power fell at
    large spreads. ``dof``: the degrees of freedom of ``s_w2`` where it was estimated from the
    dataset's own trials; each replicate then takes its own within-robot variance, one that could
    have given that estimate (a power averaged over what the variance may be, so that sizes stated
    from one dataset hold in the next). Random numbers are drawn in this order: the within-robot
    noise, the robots' effects, G (``noise`` only), the bootstrap indices, the replicates'
    variances (``dof`` only), the companions' noise. The effect's predictive variance is each
    robot's own at its fitted ratio (robots apart in noise keep their own simulated spread in
    :func:`_heldout`, see :func:`_replicate_spread`), widened by its level's error through the
    spread as there (:func:`effects.spread_leverage`, b = f s_w2 / level^2); the base's is the
    population's, ``s_w2``."""
    rng, emulated, stat, shift, null_mean, idx = _emulation(seen, s_w2, drift, reps, boot, seed, noise, dof)
    N = seen.shape[1]

    extra = np.zeros((reps, N))  # what the companions' pooled estimates gain (or cost), the same at every tau
    for seen_c in companions:
        e_c = rng.standard_normal((reps,) + np.shape(seen_c))
        e_c[:, ~np.asarray(seen_c, dtype=bool)] = np.nan
        extra += _heldout_gain(e_c, False, base_absorbs)[0]

    if drift and rival_threshold is not None:
        between_null = float(np.nanmean(_f_between(emulated(0.0))))

    def power_at(tau):
        x = emulated(tau)
        flagged = stat(shift + x) - null_mean > threshold
        gain, rival = _heldout_gain(x, drift, base_absorbs, noise=None if noise is None else (*noise, s_w2))
        gain, rival = gain + extra, rival + extra
        lo = np.percentile(gain[:, idx].sum(-1), 100 * (1 - gain_level), axis=1)
        named = flagged & (lo > 0)
        if drift:
            beats = np.percentile((gain - rival)[:, idx].sum(-1), 100 * (1 - RIVAL_LEVEL), axis=1) > 0
            if rival_threshold is not None:  # the heading bias competes where robots' means differ
                beats |= ~(_f_between(x) - between_null > rival_threshold)
            named &= beats
        return float(np.mean(named))

    # Every random number is drawn above, so each tau's power is a function of tau alone and
    # the sizes do not depend on ``threads``; NumPy's array work releases the GIL. In order,
    # ``threads`` at a time, up to the first that reaches ``stop_at``.
    taus, step = list(taus), max(1, threads)
    out = np.full(len(taus), np.nan)
    with ThreadPoolExecutor(step) as pool:
        for i in range(0, len(taus), step):
            out[i:i + step] = list(pool.map(power_at, taus[i:i + step]))
            if stop_at is not None and np.any(out[i:i + step] >= stop_at):
                break
    return out


def detection_power(seen, s_w2: float, taus, drift: bool, threshold: float, reps: int = 200, boot: int = 200,
                    seed: int = 0, noise: tuple | None = None, dof: float | None = None) -> np.ndarray:
    """Probability that the detection step alone flags a between-robot effect of spread ``tau``
    (each of ``taus``): the statistic above its null mean by ``threshold``, on the datasets that
    :func:`naming_power` emulates with the same arguments. The same draws, so at every tau it is
    at least the naming power (naming needs the flag), and the detection size read from it is
    never above the size named with the same power; and the same robots, whose spread is their
    sd exactly, as an evaluation sets it (a fixed effect: the F ratio's numerator is then a
    non-central chi-square, which scatters less on the log scale than the null's, so the closed
    form of :func:`minimum_detectable`, the null's sd carried to the alternative, overstates the
    size: by 9 % at 12 robots x 4 trials against the non-central F's power, tests/gap/test_mde.py)."""
    _, emulated, stat, shift, null_mean, _ = _emulation(seen, s_w2, drift, reps, boot, seed, noise, dof)
    with np.errstate(all="ignore"):
        return np.array([float(np.mean(stat(shift + emulated(t)) - null_mean > threshold)) for t in taus])


def _emulation(seen, s_w2: float, drift: bool, reps: int, boot: int, seed: int, noise: tuple | None,
               dof: float | None):
    """The emulated datasets of :func:`naming_power` (its docstring says what they are, and the
    order of the draws): ``(rng, emulated, stat, shift, null_mean, idx)``, the generator (its
    next draws are the companions'), ``emulated(tau)`` the replicates' summaries (reps, K, N)
    at spread tau, the detection statistic ``stat`` of ``shift`` + summaries, its mean over the
    replicates without an effect, and the bootstrap's robot indices. :func:`detection_power`
    reads the same draws."""
    rng = np.random.default_rng(seed)
    K, N = seen.shape
    eps = rng.normal(0.0, np.sqrt(s_w2), (reps, K, N))
    eps[:, ~seen] = np.nan
    effect = rng.standard_normal((reps, 1, N))
    # Sizes are the spread among the dataset's robots (their sd, ddof 1), as minimum_detectable
    # states them and as an evaluation sets them: each replicate's robots have that sd exactly.
    # Drawn from a population of that sd, 12 robots' sd scatters by a fifth, and the power
    # averaged over that scatter is below the power at the sd itself (near 80 %): the sizes
    # stated were 7-12 % larger.
    with np.errstate(all="ignore"):
        effect = effect / np.std(effect, axis=-1, ddof=1, keepdims=True)
    if drift:
        # Lines through each robot's own mean over its trials: the drift alone, without the
        # spread of levels that lines through a common start (trial 0) would add. That spread is
        # a heading bias, which helps a drift past the base but not past its rival (a robot's
        # mean); a world whose drifts do not share a start (the independent world's cross at the
        # middle trial) has none of it, and emulated with it the stated size was named in 44 %.
        k = np.arange(K, dtype=float)[:, None]
        k_mean = (np.where(seen, k, 0.0).sum(0)) / np.maximum(seen.sum(0), 1)
        effect = effect * (k - k_mean)
    if noise is not None:
        level, f = noise
        shape = level**2 / (f * s_w2) if f * s_w2 > 0 else np.inf
        g = rng.gamma(shape, 1.0 / shape, eps.shape) if np.isfinite(shape) else np.ones(eps.shape)
        tracking = eps * np.sqrt(1.0 - f)
    idx = rng.integers(0, N, (boot, N))
    if dof is not None and dof > 0 and noise is None:
        # s_w2 was estimated from the dataset's trials (dof degrees of freedom): each replicate
        # takes a within-robot variance that could have given that estimate, s_w2 dof / chi2(dof)
        # (the standard posterior of a normal variance). Sizes stated at the known-variance power
        # were named in about 77 % of fresh datasets at 16-36 degrees of freedom, not 80 %: the
        # estimate scatters, and the power lost where it came out low is more than that gained
        # where it came out high (benchmarks/bench_mde_dof.py).
        eps = eps * np.sqrt(dof / rng.chisquare(dof, (reps, 1, 1)))

    def emulated(tau):
        if noise is None:
            return eps + tau * effect
        sig = 2.0 * tau  # tau: sd of ln sigma_omega; the summary's noise share goes with sigma_omega^2
        r = np.exp(sig * effect - 0.5 * sig**2)
        return level * (r * g - 1.0) + tracking

    # A noise summary is tested as statistics() does, on a log scale: of the summary itself, the
    # population's level plus each robot's departure from it.
    stat = _f_noise if noise is not None else _f_trend if drift else _f_between
    shift = noise[0] if noise is not None else 0.0
    null_mean = float(np.nanmean(stat(shift + emulated(0.0))))
    return rng, emulated, stat, shift, null_mean, idx


def _heldout_gain(x, drift: bool, base_absorbs: bool, noise: tuple | None = None):
    """Leave-one-trial-out log-likelihood gain per (replicate, robot) of pooled per-robot means
    (or lines, with ``drift``) over a population level; for a drift also the gain of the means
    (its rival). x: (R, K, N). ``noise = (level, f, s_w2)``: per-robot noise intensities (see
    :func:`naming_power`)."""
    R, K, N = x.shape

    def loglik(y, mu, var):
        sd = np.sqrt(var)
        return np.nan_to_num(log_density((y - mu) / sd, sd))

    gain, rival = np.zeros((R, N)), np.zeros((R, N))
    kk = np.arange(K, dtype=float)
    for k in range(K):
        tr = x[:, [j for j in range(K) if j != k]]
        t = kk[[j for j in range(K) if j != k]][:, None]
        y = x[:, k]
        with np.errstate(all="ignore"):
            ok = np.isfinite(tr)
            n = ok.sum(1)  # (R, N)
            n_all = np.maximum(n.sum(-1, keepdims=True), 1)
            mu = np.nanmean(tr, axis=(1, 2))[:, None]
            within = E.within_var(tr)
            spread = np.nanvar(tr, axis=(1, 2)) if base_absorbs else within
            if noise is not None:
                level, f, s_w2 = noise
                base = loglik(y, mu, s_w2 * (1 + 1 / n_all))
                # a trial varies by a + b u^2 about a robot's noise part u = level r
                a, b = (1 - f) * s_w2, f * s_w2 / level**2
                # the robots' intensities pooled on a log scale, as MotionNoise.fit pools them
                u, w, _, _ = E.pool_intensities(np.nanmean(tr, axis=1) + level, n, a, b)
                r_hat = u / level
                mean = u - level
                # each robot's own variance at its fitted intensity, as _replicate_spread keeps it
                # for robots whose simulated spreads differ beyond replicate noise
                var_i = s_w2 * (1 - f + f * r_hat**2)
                # the level's error carried through the spread it sets, as in _heldout
                h = E.spread_leverage(w / np.maximum(n, 1), b)
                gain += loglik(y, mean, var_i * (1 + h)) - base
                continue
            mean, w = E.partial_pool(tr)
            base = loglik(y, mu, spread[:, None] * (1 + 1 / n_all))
            mean_ll = loglik(y, mean, within[:, None] * (1 + w / np.maximum(n, 1)))
            if not drift:
                gain += mean_ll - base
                continue
            tb = np.where(ok, t, 0).sum(1) / np.maximum(n, 1)
            dt = np.where(ok, t - tb[:, None, :], 0.0)
            sxx = (dt**2).sum(1)
            dev = np.where(ok, tr - np.nanmean(tr, axis=1, keepdims=True), 0.0)
            slope = (dt * dev).sum(1) / np.where(sxx > 0, sxx, 1.0)
            res = ((dev - slope[:, None] * dt) ** 2).sum((1, 2)) / np.maximum((n - 2).clip(0).sum(-1), 1)
            level, w_a = E.partial_pool(tr, s2=res)
            d, w_d = E.shrink(slope, np.where(sxx > 0, res[:, None] / np.maximum(sxx, 1e-300), np.inf))
            h = w_a / np.maximum(n, 1) + w_d * (k - tb) ** 2 / np.where(sxx > 0, sxx, np.inf)
            line_ll = loglik(y, level + d * (k - tb), res[:, None] * (1 + h))
            gain += line_ll - base
            rival += mean_ll - base
    return gain, rival


def _nuisance_intervals(fitter: _Fitter, meas: dict, cond: Conditions, gs: GapSettings) -> dict:
    """90 % intervals of the base's fitted noise levels over the robots that could have been
    tracked or swept (:func:`effects.noise_intervals`), with its own random numbers, named as
    :func:`_nuisances` names the levels."""
    rng = np.random.default_rng(child_seed(gs.seed, "nuisance_ci"))
    base = fitter.fit((), list(range(cond.trials)))
    ci = E.noise_intervals(base, meas, rng, gs.boot, 0.9,
                           lambda m: simulate(cond, m, gs.m_ref, child_seed(gs.seed, "nuisance_ci", 1)))
    if base.kind == "light_sweep":  # as _nuisances names them: per sample, per reading, in counts
        out = {}
        if "sensor_noise" in ci:
            per = np.sqrt(_samples_per_reading(cond))
            out["sensor_noise_per_sample_counts"] = ci["sensor_noise"]
            out["reading_noise_counts"] = [v / per for v in ci["sensor_noise"]]
        if "sensor_offset_trial_sd" in ci:
            out["sensor_offset_trial_sd_counts"] = ci["sensor_offset_trial_sd"]
        return out
    unit = {"sigma_omega": "sigma_omega_rad_sqrt_s", "sigma_v": "sigma_v_m_sqrt_s"}  # as _nuisances names them
    return {unit.get(k, k): v for k, v in ci.items()}


def _samples_per_reading(cond: Conditions) -> int:
    """ADC samples a light reading averages: the twin's reading noise is per sample, so the noise a
    reading carries (what a user measures of a still robot) is sd / sqrt(samples)."""
    return int(synth.light_scenario(cond.duration_s, cond.dt_s, cond.sensor_knee).sensor.samples)


def _nuisances(base: E.TwinModel, cond: Conditions) -> dict:
    """The nuisance levels the base model fitted to the data (population values)."""
    sw = base.swarm
    if base.kind == "motion":
        return {"sigma_omega_rad_sqrt_s": float(sw.sigma_omega.mean()), "sigma_v_m_sqrt_s": float(sw.sigma_v.mean()),
                "speed_trial_sd": float(base.speed_trial_sd), "bias_trial_sd": float(sw.bias_trial_sd.mean()),
                "tracking_noise_m": float(cond.tracking_noise_m),
                # the lags of the wander that sigma_omega is read from (white noise that wanders as
                # much; a correlated turn noise's long-run intensity is higher: docs/gap_methods.md)
                "wander_lags_s": [float(v) for v in summaries.wander_lags(total_tracking_noise(cond))],
                **({"tracking_correlated_m": float(cond.tracking_correlated_m), "tracking_tau_s": float(cond.tracking_tau_s)}
                   if cond.tracking_correlated_m > 0 else {}),
                **({"pixel_m": [float(g[0]) for g in cond.lattice]} if cond.lattice is not None else {}),
                **({"lens_k1_per_m2": cond.lens["k1_per_m2"], "lens_centre_m": list(cond.lens["centre_m"]),
                    "lens_centre_from_data_m": list(cond.lens["centre_data_m"]),
                    "lens_centre_se_m": list(cond.lens["centre_se_m"]),
                    "lens_centre_prior_m": list(cond.lens["centre_prior_m"]),
                    "lens_centre_prior_sd_m": list(cond.lens["centre_prior_sd_m"])}
                   if cond.lens is not None else {})}
    if base.kind == "light_sweep":
        samples = _samples_per_reading(cond)
        return {"sensor_noise_per_sample_counts": float(sw.sensor_noise.mean()),
                "reading_noise_counts": float(sw.sensor_noise.mean() / np.sqrt(samples)), "samples_per_reading": int(samples),
                "sensor_offset_trial_sd_counts": float(sw.sensor_offset_trial_sd.mean()),
                "sensor_knee": float(cond.sensor_knee)}
    return {"clock_trial_sd": float(sw.clock_trial_sd.mean()), "frame_lead": base.frame_lead}


MODEL_TRAITS = {
    "motion": ("heading_bias", "speed_factor", "bias_drift", "bias_trial_sd", "sigma_omega", "sigma_v"),
    "light_sweep": ("sensor_gain", "sensor_offset", "sensor_noise", "sensor_offset_trial_sd"),
    "blink": ("clock_rate",),
}
ALWAYS = ("heading_bias", "speed_factor", "bias_drift", "sensor_gain", "sensor_offset", "clock_rate")


def _load_base(path, kind, robot_ids):
    from ..core.traits import load_swarm

    sw = load_swarm(path)
    by_id = {int(i): j for j, i in enumerate(sw.ids)}
    missing = [int(r) for r in robot_ids if int(r) not in by_id]
    if missing:
        raise ConfigError(f"{path}: robots", f"robot(s) {missing} of the data are not in the model",
                          "add them to robots: in the model file")
    return E.TwinModel(kind, sw.subset([by_id[int(r)] for r in robot_ids]))


def run_gap(data: list[str], out: str | Path, model_path: str | None = None, gs: GapSettings = GapSettings(),
            log=print) -> dict:
    """Run the workflow on every dataset and write DIR/report.json, DIR/model.yaml, DIR/report.md."""
    import yaml

    datasets = [_load_data(d) for d in data]  # every dataset checked before anything is written
    sections, models, residuals = [], [], []
    for ds in datasets:
        base = _load_base(model_path, ds.kind, ds.robots) if model_path else None
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # robots missing from whole trials
            res = analyse(ds, gs, base, log)
        sections.append(res["section"])
        residuals.append(res["residuals"])
        models.append(res["model"])
    robots: dict = {}
    for m in models:
        for j, rid in enumerate(m.swarm.ids):
            entry = robots.setdefault(int(rid), {})
            for k in MODEL_TRAITS[m.kind]:
                # A fitted effect's traits with the robots' spread kept (the swarm's individuals);
                # the pooled predictions the held-out scores used are in the report's estimates.
                entry[k] = float(m.individual.get(k, m.swarm.values[k])[j])
    for entry in robots.values():
        for k in ALWAYS:
            entry.setdefault(k, 1.0 if k in ("speed_factor", "sensor_gain", "clock_rate") else 0.0)
    model_doc = {"format": "kilobot-twin/traits-v1", "robots": robots}
    # The folder only now: data that analyse refuses (tracks too short to summarise) leave none.
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "model.yaml").write_text(yaml.safe_dump(model_doc, sort_keys=True))
    named = [n for s in sections for n in s["named_effects"]]
    first, last = sections[0], sections[-1]
    report = {
        "version": __version__, "seed": gs.seed,
        # the candidates: the library's and a user's own (``--effects``), with the file each came from
        "library": _library_doc(gs.library),
        "named_effects": named,
        "unexplained": any(s["unexplained"] for s in sections),
        "unexplained_signals": [sig for s in sections for sig in s["unexplained_signals"]],
        "gap_before": first["gap_before"] if len(sections) == 1 else _combine(sections, "gap_before"),
        "gap_after": last["gap_after"] if len(sections) == 1 else _combine(sections, "gap_after"),
        "gap_shrink": first["gap_shrink"] if len(sections) == 1 else None,
        "steps": [dict(st, dataset=s["dataset"]) for s in sections for st in s["steps"]],
        "disagreements": [dict(dg, dataset=s["dataset"]) for s in sections for dg in s["disagreements"]],
        "model": str(out / "model.yaml"),
        "datasets": sections,
    }
    (out / "report.json").write_text(json.dumps(report, indent=1))
    from .report import write_markdown

    write_markdown(out, report, residuals)
    return report


def _library_doc(library: dict) -> dict:
    """name -> where its class is defined: ``kilobot_twin`` for the library's own effects, the
    source file for a user's."""
    import inspect

    doc = {}
    for name, e in library.items():
        cls = type(e)
        own = cls.__module__.startswith("kilobot_twin.")
        try:
            src = "kilobot_twin" if own else str(Path(inspect.getsourcefile(cls)).resolve())
        except TypeError:  # defined where no file holds it (an interactive session)
            src = cls.__module__
        doc[name] = {"class": cls.__qualname__, "source": src}
    return doc


def _combine(sections, key):
    return {"metric": sections[0][key]["metric"] + " (mean over datasets)",
            "value": float(np.mean([s[key]["value"] for s in sections])),
            "ci95": [float(np.mean([s[key]["ci95"][i] for s in sections])) for i in (0, 1)]}


def _load_data(path: str) -> measured.Dataset:
    p = Path(path)
    if (p / "meta.yaml").is_file():
        ds, where = measured.load(p), str(p / "meta.yaml")
    elif (p / "metadata.yaml").is_file() or (p / f"{p.name}_0.mcap").is_file():  # an unfinalised bag too
        from .bags import dataset_from_bag

        ds, where = dataset_from_bag(p), str(p)
    else:
        raise ConfigError(str(p), "neither a measured dataset (meta.yaml) nor a bag (metadata.yaml)",
                          "give a dataset folder or a bag directory")
    # The motion summaries and the simulations under the data's conditions assume robots commanded
    # to drive straight: a random walk's or phototaxis's turns would read as heading noise and bias.
    if ds.kind == "motion" and ds.meta.get("behavior", "straight") != "straight":
        raise ConfigError(f"{where}: behavior", f"the gap workflow models straight runs, not {ds.meta['behavior']}",
                          "hold the twin against trials in which the robots were commanded to drive straight")
    # Every score is of a held-out trial under a fit to the others (a single trial was a traceback).
    if ds.trials < 2:
        raise ConfigError(f"{where}: trials", f"{ds.trials} trial: the workflow scores each trial held out from a fit "
                          "to the others", "record at least 2 trials (3 or more to tell robots' traits from chance)")
    return ds
