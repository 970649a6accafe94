"""A third, deliberately different world: measured-v1 Kilobot datasets from a stress simulator.

Shares no code with ``kilobot_twin`` or ``benchmarks/indep_world.py``; same interface as the
latter (``generate``, ``draw_program``, ``EFFECTS``, ``NOMINAL``, the CLI). Units: m, s, rad
(counter-clockwise positive), ADC counts. Every modelling choice:

Motion: a vibration-driven robot on two legs ``axle_m`` apart (U(25, 35) mm per dataset), on a fixed
200 Hz grid, Euler-Maruyama for the heading and trapezoidal positions. Leg speeds
``v +- w axle/2`` carry independent AR(1) noises (correlation time ``leg_tau_s``, 0 = white): their
difference drives the turn rate, their mean the forward speed (coupled: speed-noise sd =
turn-noise sd x axle/2). A common stick/slip telegraph (slip share U(0.1, 0.35), correlation time
``slip_tau_s``) multiplies both legs: speed factor ``m = 1 - c (S - p_slip)``, mean exactly 1,
long-run relative intensity ``slip_noise`` = sqrt(2 c^2 p (1-p) tau) (c capped so m >= 0). Heading
noise = Gaussian AR(1) part + compound-Poisson stick-slip kicks: Bernoulli(rate h) per step of
Laplace(b) angle; a kick pivots the robot on one leg and moves it forward (axle/2)|J|, which the
continuous speed gives back (v - rate b axle/2) so the mean speed stays v. Long-run diffusion
sigma^2 = h s^2 (1+a)/(1-a) [AR(1) of sd s, a = exp(-h/tau)] + rate 2 b^2 [kicks], with the kick
share q: s^2 = (1-q) sigma^2 (1-a) / (h (1+a)), b = sigma sqrt(q / (2 rate)), so it equals the drawn
sigma exactly on the grid. The telegraph adds w^2 slip_noise^2 (in truth's sigma_omega). Robots stand
still until a start delay, then spin up over 0.2 s. Trial-to-trial: turn rate + N(0, turn_trial_sd),
speed x lognormal (mean 1, sd speed_trial_sd). Floor tilt: along-heading speed +
A v cos(heading - downhill) and 30 % of the cross-slope push as sideways slip.
Camera: one timestamp per frame for all robots (exponential latency, duplicated frames re-delivered
with the previous timestamp and dropped), camera clock off by ``camera_rate_err`` (all capture
times scaled), a marker a few mm off the rotation centre (fixed per robot), residual radial lens
distortion about an off-centre optical axis, Gaussian centroid noise, pixel quantisation,
spurious detections 0.3-3 x ``glitch_m`` away, Gilbert-Elliott bursty loss (90 % in the bad
state), robots leaving the +-0.75 m field of view are not seen.
Light sweep: one 60 s ramp of the 8-bit projector V-value after a lead-in of 0.5-3 s (0 in the
fixed shape), logged over serial with exponential latency. Reading = floor(offset + gain 1024 V +
ambient + noise) hard-clipped to 0..1023; ambient light wanders (AR(1), ``ambient_counts``,
``ambient_tau_s``); the robot samples and holds every ``hold_s`` (stale readings repeat).
Blink: per-robot clock f_i, x (1 + N(0, clock_trial_sd)) per trial, plus a random walk of the rate
within a trial (relative sd ``clock_wander`` after 100 s); LED toggles every half_period ticks from
red, invisible before the robot starts; the camera sees the colour of a random instant of a
0.4-frame exposure, misclassifies with ``led_flip_p``, loses frames in bursts.
Datasets: 6-40 robots, 3-8 trials, frames at one of ``FRAME_HZ``; trials of U(45, 60) s (motion),
lead-in + 60 + U(0, 2) s (light), U(90, 120) s (blink); each (trial, robot) missing with p 0.04 (a
robot keeps two trials). Population per dataset: speed 0.85-1.15 x commanded, turn rate
U(-0.003, 0.003) rad/s, gain 2.2 x 0.6-1.5, offset U(0, 15) counts, clock 0.97-1.03 x tick_hz.
Nuisances (``NOMINAL``): log-uniform 0.25-4 x nominal, zero with p 0.15 where physical, ``CAPS``
applied; ``--nuisance-scale X``: X x nominal but for the time scales (``SHAPE_ONLY``). Files:
block-style meta.yaml; observations.csv with the spec's columns in another order and rows shuffled
(the spec allows any order), repeated times of a (trial, robot) (to 0.1 ms) dropped.

Hidden effects (gap library names; truth in the twin's units, heading bias
b = -w 0.025 / v, clockwise positive): heading_bias turn rate + N(0, 0.008 s); speed_heterogeneity
speed x clip(1 + N(0, 0.12 s), 0.3, 2); bias_drift turn rate + N(0, 0.0045 s) x trial (trial 0 is the
reference: truth's heading_bias is trial 0's); motion_noise sigma x exp(N(0, 0.6 s)); floor_tilt
A = 0.15 s (not in the library); sensor_gain gain x exp(N(0, 0.25 s)), offset + N(0, 6 s); clock_drift
f x (1 + N(0, 0.015 s)). Effect draws come from their own stream, always drawn, so a null dataset
and one with effects at the same seed share robots, trials and noise.

    python benchmarks/stress_world.py --kind motion --hidden heading_bias --seed 3 --out /tmp/s
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import yaml
from scipy.signal import lfilter

FORMAT = "kilobot-twin/measured-v1"
AXLE_M = 0.025  # the twin's unit of heading bias only
COMMANDED_SPEED_M_S = 0.06 * 48 / 255
TICK_HZ, HALF_PERIOD_TICKS = 31.0, 30
H_S = 1 / 200  # internal motion grid
RAMP_S, FIELD_M, CAM_ERR_MAX = 60.0, 0.75, 0.004
FRAME_HZ = (5.0, 8.0, 10.0, 12.0, 15.0, 20.0, 24.0, 25.0, 30.0)
EFFECTS = {"motion": ("heading_bias", "speed_heterogeneity", "bias_drift", "motion_noise", "floor_tilt"),
           "light_sweep": ("sensor_gain",), "blink": ("clock_drift",)}
#: name: (nominal, zero is physical, meaning)
NOMINAL = {
    "heading_noise": (0.01, False, "rad/sqrt(s): long-run heading diffusion intensity"),
    "kick_share": (0.25, True, "share of that diffusion from stick-slip kicks (capped at 0.9)"),
    "kick_rate_hz": (1.0, False, "1/s: rate of stick-slip kicks"),
    "leg_tau_s": (0.1, True, "s: correlation time of the leg-speed noise (0 = white)"),
    "slip_noise": (0.04, True, "1/sqrt(s): long-run relative intensity of the stick/slip speed factor"),
    "slip_tau_s": (0.3, False, "s: correlation time of the stick/slip telegraph"),
    "speed_trial_sd": (0.02, True, "relative sd of a robot's speed from trial to trial"),
    "turn_trial_sd": (0.002, True, "rad/s: sd of a robot's turn rate from trial to trial"),
    "start_delay_s": (1.0, True, "s: robots and clocks start uniformly within this delay"),
    "tracking_noise_m": (0.002, True, "m: Gaussian centroid noise per axis"),
    "pixel_m": (0.0012, True, "m: camera pixel, positions quantised to it"),
    "marker_offset_m": (0.003, True, "m: largest marker offset from the rotation centre"),
    "lens_k1": (0.02, True, "1/m^2: residual radial distortion (sign drawn)"),
    "camera_rate_err": (0.001, True, "relative error of the camera clock (sign drawn, capped 0.4 %)"),
    "time_jitter_s": (0.002, True, "s: mean timestamp latency (exponential, capped at 0.45 frame)"),
    "dup_p": (0.003, True, "probability a frame is a re-delivery of the previous one"),
    "glitch_p": (0.002, True, "probability a position is a spurious detection"),
    "glitch_m": (0.03, False, "m: typical distance of a spurious detection"),
    "drop_p": (0.01, True, "loss probability of a sample in the good state"),
    "burst_frac": (0.02, True, "fraction of time in the bad (bursty loss) state"),
    "burst_s": (0.5, False, "s: mean length of a bad spell"),
    "sensor_noise": (8.0, True, "counts: reading noise sd"),
    "ambient_counts": (3.0, True, "counts: sd of the wandering ambient light"),
    "ambient_tau_s": (20.0, False, "s: its correlation time"),
    "hold_s": (0.1, True, "s: sample-and-hold interval of the light readings"),
    "clock_trial_sd": (0.002, True, "relative sd of a clock's rate from trial to trial"),
    "clock_wander": (0.001, True, "relative sd of a clock rate's random walk after 100 s"),
    "led_flip_p": (0.003, True, "per-frame colour misclassification (capped at 1 %)"),
}
SHAPE_ONLY = {"kick_rate_hz", "leg_tau_s", "slip_tau_s", "glitch_m", "burst_s", "ambient_tau_s"}  # kept under --nuisance-scale
CAPS = {"kick_share": 0.9, "led_flip_p": 0.01, "camera_rate_err": CAM_ERR_MAX}


def draw_program(rng):
    """Kilobot defaults without a generator; with one, 0.6-1.6x the speed, 25-40 Hz, 10-60 ticks."""
    if rng is None:
        return {"commanded_speed_m_s": COMMANDED_SPEED_M_S, "tick_hz": TICK_HZ, "half_period_ticks": HALF_PERIOD_TICKS}
    return {"commanded_speed_m_s": float(COMMANDED_SPEED_M_S * np.exp(rng.uniform(np.log(0.6), np.log(1.6)))),
            "tick_hz": float(rng.uniform(25.0, 40.0)), "half_period_ticks": int(rng.integers(10, 61))}


def draw_nuisance(rng, scale=None):
    out = {}
    for name, (nom, zero_ok, _) in NOMINAL.items():
        f, zero = np.exp(rng.uniform(np.log(0.25), np.log(4.0))), rng.random() < 0.15  # always both draws
        v = (nom if name in SHAPE_ONLY else nom * scale) if scale is not None else (0.0 if zero_ok and zero else nom * f)
        out[name] = float(min(v, CAPS.get(name, np.inf)))
    return out


def draw_shape(rng, kind, fixed):
    if fixed:
        n, K, hz = (16, 4, 30.0) if kind == "blink" else (12, 4, 10.0)
        lead = np.zeros(K)
        lengths = np.full(K, {"motion": 60.0, "light_sweep": RAMP_S, "blink": 120.0}[kind])
        missing = []
    else:
        n, K, hz = int(rng.integers(6, 41)), int(rng.integers(3, 9)), float(rng.choice(FRAME_HZ))
        lead = np.round(rng.uniform(0.5, 3.0, K), 1) if kind == "light_sweep" else np.zeros(K)
        lengths = {"motion": rng.uniform(45, 60, K), "light_sweep": lead + RAMP_S + rng.uniform(0, 2, K),
                   "blink": rng.uniform(90, 120, K)}[kind]
        missing = []
        for i in range(n):  # now and then a robot misses a whole trial; each keeps two trials at least
            ks = np.flatnonzero(rng.random(K) < 0.04)[:K - 2]
            missing += [[int(k), i] for k in ks]
    return {"robots": n, "trials": K, "frame_hz": hz, "lengths_s": [round(float(x), 1) for x in lengths],
            "lead_s": [float(x) for x in lead], "missing": missing}


# --- random processes ---------------------------------------------------------------------------------

def ar1(rng, shape, a):
    """Unit-variance AR(1) along the last axis, x_j = a x_(j-1) + sqrt(1-a^2) z_j, stationary from x_0."""
    e = rng.standard_normal(shape)
    e[..., 1:] *= np.sqrt(1 - a * a)
    return lfilter([1.0], [1.0, -a], e, axis=-1)


def two_state(rng, t, p_on, mean_on, mean_off):
    """Markov on/off process (stationary start, exponential holding times) at times t (n, T): bool."""
    n, span = t.shape[0], float(t.max()) + 1.0
    on0 = rng.random(n) < p_on
    m = 2 * int(2 * span / (mean_on + mean_off)) + 60
    odd = (np.arange(m) % 2 == 1)[None, :]
    dur = rng.exponential(1.0, (n, m)) * np.where(on0[:, None] ^ odd, mean_on, mean_off)
    sw = np.cumsum(dur, axis=1)
    if (sw[:, -1] < span).any():  # practically impossible with this margin
        raise RuntimeError("two_state: too few switches drawn")
    count = np.stack([np.searchsorted(sw[r], t[r], side="right") for r in range(n)])
    return on0[:, None] ^ (count % 2 == 1)


def gilbert_elliott(rng, t, nz):
    """Lost samples at times t (n, T): drop_p in the good state, 90 % in bursts."""
    bad = np.zeros(t.shape, bool)
    if nz["burst_frac"] > 0:
        f = min(nz["burst_frac"], 0.5)
        bad = two_state(rng, t, f, nz["burst_s"], nz["burst_s"] * (1 - f) / f)
    return rng.random(t.shape) < np.where(bad, 0.9, nz["drop_p"])


def latency(rng, shape, nz, hz):
    return np.minimum(rng.exponential(nz["time_jitter_s"], shape), 0.45 / hz) if nz["time_jitter_s"] > 0 else np.zeros(shape)


# --- motion -------------------------------------------------------------------------------------------

def world_setup(rng, nz, n):
    """Per-dataset leg physics and camera geometry, per-robot marker offsets."""
    p = rng.uniform(0.1, 0.35)
    tau = nz["slip_tau_s"]
    c = nz["slip_noise"] / np.sqrt(2 * p * (1 - p) * tau)
    c = min(c, 1 / (1 - p))  # slip speed factor stays >= 0
    return {"axle_m": rng.uniform(0.025, 0.035), "slip_p": p, "slip_c": c,
            "slip_noise_realised": float(c * np.sqrt(2 * p * (1 - p) * tau)),
            "axis_m": rng.uniform(-0.05, 0.05, 2), "pixel_origin_m": rng.uniform(0, 1, 2) * nz["pixel_m"],
            "k1": nz["lens_k1"] * rng.choice([-1.0, 1.0]), "cam_err": nz["camera_rate_err"] * rng.choice([-1.0, 1.0]),
            "marker_r": nz["marker_offset_m"] * np.sqrt(rng.random(n)), "marker_phi": rng.uniform(-np.pi, np.pi, n)}


def move(rng, v, w, sig, start, t_end, nz, st, tilt=None):
    """Robots on the 200 Hz grid: returns (t, heading, x, y), each (n, N) but t (N,)."""
    n, N = len(v), int(np.ceil(t_end / H_S)) + 2
    t = np.arange(N) * H_S
    ramp = np.clip((t[None, :] - start[:, None]) / 0.2, 0, 1)
    moving = ramp > 0
    q, lam, ax = nz["kick_share"], nz["kick_rate_hz"], st["axle_m"]
    a = np.exp(-H_S / nz["leg_tau_s"]) if nz["leg_tau_s"] > 0 else 0.0
    s_g = sig[:, None] * np.sqrt((1 - q) * (1 - a) / (H_S * (1 + a)))
    d_turn, d_speed = s_g * ar1(rng, (n, N), a), s_g * ax / 2 * ar1(rng, (n, N), a)
    slip = two_state(rng, np.broadcast_to(t, (n, N)), st["slip_p"], nz["slip_tau_s"] / (1 - st["slip_p"]),
                     nz["slip_tau_s"] / st["slip_p"])
    m = 1 - st["slip_c"] * (slip - st["slip_p"])
    b = sig * np.sqrt(q / (2 * lam))
    kick = (rng.random((n, N)) < lam * H_S) * rng.laplace(0.0, 1.0, (n, N)) * b[:, None] * moving
    turn = ramp * w[:, None] * m + moving * d_turn
    th = rng.uniform(-np.pi, np.pi, (n, 1)) + np.concatenate([np.zeros((n, 1)), np.cumsum(turn * H_S + kick, 1)[:, :-1]], 1)
    u = ramp * np.maximum(v - lam * b * ax / 2, 0)[:, None] * m + moving * d_speed
    lat = np.zeros_like(u)
    if tilt:
        u = u + tilt[0] * v[:, None] * np.cos(th - tilt[1]) * moving
        lat = 0.3 * tilt[0] * v[:, None] * np.sin(tilt[1] - th) * moving
    c, s = np.cos(th), np.sin(th)
    vx, vy = u * c - lat * s, u * s + lat * c
    kf = ax / 2 * np.abs(kick)  # the pivot on one leg moves the centre forward
    dx = H_S / 2 * (vx[:, :-1] + vx[:, 1:]) + kf[:, :-1] * np.cos(th[:, :-1] + kick[:, :-1] / 2)
    dy = H_S / 2 * (vy[:, :-1] + vy[:, 1:]) + kf[:, :-1] * np.sin(th[:, :-1] + kick[:, :-1] / 2)
    r0, p0 = 0.35 * np.sqrt(rng.random((n, 1))), rng.uniform(-np.pi, np.pi, (n, 1))
    x = r0 * np.cos(p0) + np.concatenate([np.zeros((n, 1)), np.cumsum(dx, 1)], 1)
    y = r0 * np.sin(p0) + np.concatenate([np.zeros((n, 1)), np.cumsum(dy, 1)], 1)
    return t, th, x, y


def _at(arr, tt):
    """Linear interpolation of grid rows arr (n, N) at times tt (T,)."""
    j = np.minimum((tt / H_S).astype(int), arr.shape[1] - 2)
    f = tt / H_S - j
    return arr[:, j] * (1 - f) + arr[:, j + 1] * f


def camera_frames(rng, nz, st, L, hz):
    """Reported timestamps (one per frame, shared by all robots) and the true capture times."""
    frames = int(np.floor(L * hz)) + 1
    t_rep = np.arange(frames) / hz + latency(rng, frames, nz, hz)
    dup = rng.random(frames) < nz["dup_p"]
    dup[0] = False
    src = np.maximum.accumulate(np.where(dup, 0, np.arange(frames)))  # a re-delivered frame: same stamp
    t_rep = t_rep[src]
    return t_rep, t_rep / (1 + st["cam_err"])


def camera_positions(rng, nz, st, th, x, y, tt):
    n = x.shape[0]
    h, px, py = _at(th, tt), _at(x, tt), _at(y, tt)
    mx = px + st["marker_r"][:, None] * np.cos(h + st["marker_phi"][:, None])
    my = py + st["marker_r"][:, None] * np.sin(h + st["marker_phi"][:, None])
    dx, dy = mx - st["axis_m"][0], my - st["axis_m"][1]
    k = 1 + st["k1"] * (dx * dx + dy * dy)
    ox = st["axis_m"][0] + dx * k + nz["tracking_noise_m"] * rng.standard_normal(dx.shape)
    oy = st["axis_m"][1] + dy * k + nz["tracking_noise_m"] * rng.standard_normal(dx.shape)
    g = rng.random(ox.shape) < nz["glitch_p"]
    r, phi = nz["glitch_m"] * rng.uniform(0.3, 3.0, ox.shape), rng.uniform(-np.pi, np.pi, ox.shape)
    ox, oy = np.where(g, px + r * np.cos(phi), ox), np.where(g, py + r * np.sin(phi), oy)
    if nz["pixel_m"] > 0:
        o, p = st["pixel_origin_m"], nz["pixel_m"]
        ox, oy = o[0] + np.round((ox - o[0]) / p) * p, o[1] + np.round((oy - o[1]) / p) * p
    seen = (np.abs(px) < FIELD_M) & (np.abs(py) < FIELD_M)
    return ox, oy, seen & ~gilbert_elliott(rng, np.broadcast_to(tt, (n, len(tt))), nz)


def motion(rng, fx, st, shape, nz, hidden, s, program, pop_rng=None):
    n, K, hz = shape["robots"], shape["trials"], shape["frame_hz"]
    v_cmd = program["commanded_speed_m_s"]
    pr = rng if pop_rng is None else pop_rng  # the population's draws (the seed's in every realisation)
    v_pop, w_pop = v_cmd * pr.uniform(0.85, 1.15), pr.uniform(-0.003, 0.003)
    on = {e: float(e in hidden) * s for e in EFFECTS["motion"]}
    w_i = w_pop + on["heading_bias"] * 0.008 * fx["bias"]
    v_i = v_pop * np.clip(1 + on["speed_heterogeneity"] * 0.12 * fx["speed"], 0.3, 2.0)
    dw = on["bias_drift"] * 0.0045 * fx["drift"]
    sig = nz["heading_noise"] * np.exp(on["motion_noise"] * 0.6 * fx["noise"])
    tilt = (0.15 * s, float(fx["downhill"])) if "floor_tilt" in hidden else None
    cols, trial_w = [], []
    for k in range(K):
        L = shape["lengths_s"][k]
        w_k = w_i + dw * k + nz["turn_trial_sd"] * rng.standard_normal(n)
        sd = nz["speed_trial_sd"]
        v_k = v_i * np.exp(sd * rng.standard_normal(n) - sd * sd / 2)
        start = rng.uniform(0, nz["start_delay_s"], n)
        t_rep, tt = camera_frames(rng, nz, st, L, hz)
        _, th, x, y = move(rng, v_k, w_k, sig, start, tt.max() + 0.1, nz, st, tilt)
        ox, oy, keep = camera_positions(rng, nz, st, th, x, y, tt)
        trial_w.append(w_k.tolist())
        cols += _rows(k, shape, keep, t_rep, x_m=ox, y_m=oy)
    kbar2 = np.mean([(w_i + dw * k) ** 2 for k in range(K)], axis=0) + nz["turn_trial_sd"] ** 2
    truth = {"heading_bias": -w_i * AXLE_M / v_i, "speed_factor": v_i / v_cmd, "bias_drift": -dw * AXLE_M / v_i,
             "sigma_omega": np.sqrt(sig ** 2 + kbar2 * st["slip_noise_realised"] ** 2), "sigma_omega_drawn": sig,
             "turn_rate_rad_s": w_i, "speed_m_s": v_i, "marker_offset_m": st["marker_r"],
             "marker_left_m": st["marker_r"] * np.sin(st["marker_phi"])}  # tracked speed v - omega x this
    meta = {"behavior": "straight", "nominal_speed_m_s": float(v_cmd)}
    extra = {"population": {"speed_m_s": v_pop, "turn_rate_rad_s": w_pop}, "trial_turn_rates_rad_s": trial_w,
             "floor_tilt": {"amplitude": tilt[0], "downhill_rad": tilt[1]} if tilt else None}
    return cols, ("robot_id", "trial", "t_s", "y_m", "x_m"), meta, truth, extra


def _rows(k, shape, keep, t, **values):
    """Column blocks of one trial for the robots that took part; t is (T,) or (n, T)."""
    out = []
    for i in range(keep.shape[0]):
        if [k, i] in shape["missing"]:
            continue
        m = keep[i]
        ti = np.broadcast_to(t, keep.shape)[i]
        out.append({"trial": np.full(m.sum(), k), "robot_id": np.full(m.sum(), i), "t_s": ti[m],
                    **{c: v[i][m] for c, v in values.items()}})
    return out


# --- light sweep ------------------------------------------------------------------------------------

def light_sweep(rng, fx, st, shape, nz, hidden, s, program, pop_rng=None):
    n, K, hz = shape["robots"], shape["trials"], shape["frame_hz"]
    pr = rng if pop_rng is None else pop_rng
    g_pop, o_pop = 2.2 * np.exp(pr.uniform(np.log(0.6), np.log(1.5))), pr.uniform(0.0, 15.0)
    on = s * float("sensor_gain" in hidden)
    g, o = g_pop * np.exp(on * 0.25 * fx["gain"]), o_pop + on * 6.0 * fx["offset"]
    cols = []
    for k in range(K):
        L, lead = shape["lengths_s"][k], shape["lead_s"][k]
        frames = int(np.floor(L * hz)) + 1
        t = np.arange(frames) / hz + latency(rng, (n, frames), nz, hz)  # serial log times, per robot
        if nz["hold_s"] > 0:  # the robot samples every hold_s (random phase); the log repeats the held value
            step, phase = nz["hold_s"], -rng.uniform(0, nz["hold_s"], (n, 1))
            idx = np.floor((t - phase) / step).astype(int)
            t_smp = phase + idx * step
        else:
            step, idx, t_smp = 1 / hz, np.broadcast_to(np.arange(frames), (n, frames)), t
        S = int(idx.max()) + 1
        amb = nz["ambient_counts"] * ar1(rng, (n, S), np.exp(-step / nz["ambient_tau_s"]))
        noise = nz["sensor_noise"] * rng.standard_normal((n, S))
        r = np.arange(n)[:, None]
        raw = o[:, None] + g[:, None] * 1024.0 * _projected(t_smp, lead) + amb[r, idx] + noise[r, idx]
        reading = np.clip(np.floor(raw), 0, 1023)
        keep = ~gilbert_elliott(rng, t, nz)
        cols += _rows(k, shape, keep, t, stimulus=_projected(t, lead), reading=reading)
    truth = {"sensor_gain": g, "sensor_offset": o}
    meta = {"ramp_s": RAMP_S}
    return cols, ("reading", "t_s", "robot_id", "stimulus", "trial"), meta, truth, {"population": {"gain": g_pop, "offset": o_pop}}


def _projected(t, lead):
    return np.round(255 * np.clip((t - lead) / RAMP_S, 0, 1)) / 255  # the projector's 8-bit V-value


# --- blink ------------------------------------------------------------------------------------------

def blink(rng, fx, st, shape, nz, hidden, s, program, pop_rng=None):
    n, K, hz = shape["robots"], shape["trials"], shape["frame_hz"]
    tick_hz, half = program["tick_hz"], program["half_period_ticks"]
    f_pop = tick_hz * (rng if pop_rng is None else pop_rng).uniform(0.97, 1.03)
    f_i = f_pop * (1 + s * float("clock_drift" in hidden) * 0.015 * fx["clock"])
    cols, G = [], 0.1  # clock-rate grid step (s)
    for k in range(K):
        L = shape["lengths_s"][k]
        t_rep, tt = camera_frames(rng, nz, st, L, hz)
        f_k = f_i * (1 + nz["clock_trial_sd"] * rng.standard_normal(n))
        start = rng.uniform(0, nz["start_delay_s"], n)
        N = int(L / G) + 3
        rate = 1 + nz["clock_wander"] * np.sqrt(G / 100.0) * np.cumsum(rng.standard_normal((n, N)), 1)
        ticks_grid = f_k[:, None] * np.concatenate([np.zeros((n, 1)), np.cumsum(rate * G, 1)[:, :-1]], 1)

        def ticks(tq):  # ticks counted since the robot's start, at true times tq (T,)
            run = np.maximum(tq[None, :] - start[:, None], 0) / G
            j = np.minimum(run.astype(int), N - 2)
            r = np.arange(n)[:, None]
            return ticks_grid[r, j] + (run - j) * (ticks_grid[r, j + 1] - ticks_grid[r, j])

        k1, k0 = ticks(tt), ticks(tt - 0.4 / hz)  # end and start of the exposure
        s1, s0 = np.floor(k1 / half) % 2, np.floor(k0 / half) % 2
        after = (k1 - np.floor(k1 / half) * half) / np.maximum(k1 - k0, 1e-12)  # share of the exposure in s1
        led = np.where((s1 != s0) & (rng.random(s1.shape) >= after), s0, s1)
        led = np.where(rng.random(led.shape) < nz["led_flip_p"], 1 - led, led)
        keep = (tt[None, :] >= start[:, None]) & ~gilbert_elliott(rng, np.broadcast_to(tt, led.shape), nz)
        cols += _rows(k, shape, keep, t_rep, led=led)
    meta = {"half_period_ticks": int(half), "nominal_tick_hz": float(tick_hz)}
    truth = {"clock_rate": f_i / tick_hz, "frequency_hz": f_i}
    return cols, ("led", "robot_id", "trial", "t_s"), meta, truth, {"population": {"tick_hz": f_pop}}


# --- writing ----------------------------------------------------------------------------------------

FMT = {"trial": "%d", "robot_id": "%d", "t_s": "%.4f", "x_m": "%.5f", "y_m": "%.5f", "stimulus": "%.6f", "reading": "%d"}


def write_dataset(out, meta, order, blocks, rng):
    """meta.yaml (block YAML) and observations.csv: columns in ``order``, rows shuffled, repeated
    times of a (trial, robot) dropped."""
    cols = {c: np.concatenate([b[c] for b in blocks]) for c in blocks[0]}
    t = np.round(cols["t_s"], 4)
    idx = np.lexsort((t, cols["robot_id"], cols["trial"]))
    same = (np.diff(cols["trial"][idx]) == 0) & (np.diff(cols["robot_id"][idx]) == 0) & (np.diff(t[idx]) <= 0)
    idx = rng.permutation(idx[np.concatenate([[True], ~same])])
    text = [np.where(cols[c][idx] > 0.5, "blue", "red") if c == "led" else np.char.mod(FMT[c], cols[c][idx]) for c in order]
    out.mkdir(parents=True, exist_ok=True)
    (out / "meta.yaml").write_text(yaml.safe_dump({"format": FORMAT, **meta}, sort_keys=False, default_flow_style=False))
    with (out / "observations.csv").open("w") as f:
        f.write(",".join(order) + "\n" + "\n".join(map(",".join, zip(*text))) + "\n")


def _check(kind, hidden, seed, nuisance_scale, effect_scale, nuisance):
    if kind not in EFFECTS:
        raise ValueError(f"--kind: {kind!r} is not a kind (use {', '.join(EFFECTS)})")
    hidden = [h.strip() for h in (hidden.split(",") if isinstance(hidden, str) else hidden or [])]
    hidden = [h for h in hidden if h and h != "none"]
    for h in hidden:
        if h not in EFFECTS[kind]:
            raise ValueError(f"--hidden: {h} is not an effect of {kind} (use {', '.join(EFFECTS[kind])})")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"--seed: must be an integer >= 0, got {seed!r}")
    if not (np.isfinite(effect_scale) and effect_scale > 0):
        raise ValueError(f"--effect-scale: must be a number above 0, got {effect_scale!r}")
    if nuisance_scale is not None and not (np.isfinite(nuisance_scale) and nuisance_scale >= 0):
        raise ValueError(f"--nuisance-scale: must be a number >= 0, got {nuisance_scale!r}")
    for k, v in (nuisance or {}).items():
        if k not in NOMINAL or not (np.isfinite(float(v)) and (float(v) > 0 or (NOMINAL[k][1] and float(v) == 0))):
            raise ValueError(f"nuisance: {k}={v!r} is not a nuisance level, or not a valid value (use {', '.join(NOMINAL)}; "
                             f"values >= 0, > 0 where zero is not physical)")
    return hidden


def generate(kind, hidden, out, seed=0, nuisance_scale=None, effect_scale=1.0, fixed_shape=False, program=None,
             nuisance=None, realisation=0) -> dict:
    """Write one dataset to ``out`` (meta.yaml, observations.csv, truth.json) and return the truth.
    ``realisation`` > 0 draws the noise of the robots, the camera and the serial log afresh, with
    the world (shape, nuisance levels, robots, camera geometry) as ``seed`` draws it: a second
    dataset of the same swarm. At 0, datasets of the same seed share their noise whatever effects
    are hidden."""
    hidden = _check(kind, hidden, seed, nuisance_scale, effect_scale, nuisance)
    if isinstance(realisation, bool) or not isinstance(realisation, (int, np.integer)) or realisation < 0:
        raise ValueError(f"--realisation: must be an integer >= 0, got {realisation!r}")
    r_shape, r_nz, r_prog, r_world, r_fx, r_setup, r_write = (
        np.random.default_rng(c) for c in np.random.SeedSequence([int(seed), 0x57E55]).spawn(7))
    pop = None  # the population's draws: from the noise stream, the seed's own in every realisation
    if realisation:
        pop = r_world
        r_world, r_write = (np.random.default_rng(c)
                            for c in np.random.SeedSequence([int(seed), 0x57E55, int(realisation)]).spawn(2))
    program = draw_program(r_prog if program == "random" else None) | (program if isinstance(program, dict) else {})
    shape = draw_shape(r_shape, kind, fixed_shape)
    nz = draw_nuisance(r_nz, nuisance_scale) | {k: min(float(v), CAPS.get(k, 1e300)) for k, v in (nuisance or {}).items()}
    n = shape["robots"]
    fx = {e: r_fx.standard_normal(n) for e in ("bias", "speed", "drift", "noise", "gain", "offset", "clock")}
    fx["downhill"] = r_fx.uniform(-np.pi, np.pi)
    setup = world_setup(r_setup, nz, n)
    fn = {"motion": motion, "light_sweep": light_sweep, "blink": blink}[kind]
    blocks, order, meta, per_robot, extra = fn(r_world, fx, setup, shape, nz, hidden, effect_scale, program,
                                               pop_rng=pop)
    meta = {"kind": kind, "robots": list(range(n)), "trials": shape["trials"], "dt_s": 1.0 / shape["frame_hz"],
            "duration_s": float(max(shape["lengths_s"])), **meta}
    out = Path(out)
    write_dataset(out, meta, order, blocks, r_write)
    keep = ("axle_m", "slip_p", "slip_c", "slip_noise_realised", "k1", "cam_err") if kind == "motion" else ("cam_err",)
    truth = {"generator": "stress_world", "kind": kind, "hidden": hidden, "seed": int(seed), "realisation": int(realisation),
             "effect_scale": effect_scale,
             "nuisance": nz, "nuisance_scale": nuisance_scale, "shape": shape, "program": program,
             "setup": {k: setup[k] for k in keep}, **extra,
             "robots": {str(i): {k: float(np.broadcast_to(v, (n,))[i]) for k, v in per_robot.items()} for i in range(n)}}
    text = json.dumps(truth, indent=1, default=lambda o: o.tolist())
    (out / "truth.json").write_text(text)
    return json.loads(text)  # plain JSON types, as a reader of truth.json gets them


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line naming the option, exit 2
        print(f"error: {message}", file=sys.stderr)
        sys.exit(2)


def main(argv=None):
    ap = _Parser(description=__doc__.split("\n")[0])
    ap.add_argument("--kind", choices=tuple(EFFECTS), default="motion")
    ap.add_argument("--hidden", default="none")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", required=True)
    ap.add_argument("--nuisance-scale", type=float, default=None, help="all nuisances at X x nominal (default: random)")
    ap.add_argument("--effect-scale", type=float, default=1.0)
    ap.add_argument("--fixed-shape", action="store_true", help="12 robots x 4 trials at 10 Hz (blink 16 at 30 Hz)")
    ap.add_argument("--random-program", action="store_true", help="draw the commanded speed and the LED program")
    ap.add_argument("--realisation", type=int, default=0,
                    help="> 0: the same world (robots, nuisances, shape) with its noise drawn afresh")
    a = ap.parse_args(argv)
    try:
        truth = generate(a.kind, a.hidden, a.out, a.seed, a.nuisance_scale, a.effect_scale, a.fixed_shape,
                         "random" if a.random_program else None, realisation=a.realisation)
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    sh = truth["shape"]
    print(f"{a.out}: {truth['kind']} {sh['robots']} robots x {sh['trials']} trials at {sh['frame_hz']} Hz, "
          f"hidden {truth['hidden'] or 'nothing'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
