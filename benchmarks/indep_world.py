"""An independent world for the gap workflow: measured-v1 datasets from another code base.

Shares no code with ``kilobot_twin`` (no import from it): its own continuous-time unicycle
(exact chord integration on a fine internal grid, parametrised by turn rate in rad/s and speed
in m/s, not by wheel factors), its own noise (white or Ornstein-Uhlenbeck coloured turn-rate
noise, white speed noise, trial-to-trial speed and turn-rate jitter), its own tracker (Gaussian
position noise, errors that persist over frames as a smoothing tracker's do (Ornstein-Uhlenbeck at
the jittered frame times), heavy-tailed glitches of centimetres, dropped frames, tracking losses, jittered
frame times, robots starting late, robots missing a whole trial, uneven trial lengths), its own
light sensor (soft saturation with another knee, offsets that shift from trial to trial, ADC quantisation) and its own blinking clocks
(frequency offset, trial jitter, tick phase diffusion, late starts). The CSV and YAML are
written here from ``shared/formats/measured-v1.md``.

Hidden effects (``truth.json`` lists them under the gap library's names, and gives every
robot's true parameters in the twin's units so that recovered parameters can be checked for
slope and intercept):

====================  ============================================================================
heading_bias          per-robot turn rate ~ N(0, 0.008 rad/s) (the paper's spread)
speed_heterogeneity   per-robot speed x (1 + N(0, 0.12))
bias_drift            per-robot turn rate changes by N(0, 0.0045 rad/s) per trial
motion_noise          robots differ in noise intensity: heading-noise sd x exp(N(0, 0.6))
floor_tilt            a sloped floor: speed + 0.15 v cos(heading - downhill) (not in the library)
sensor_gain           sensor gain x exp(N(0, 0.25)), offset + N(0, 6) counts
clock_drift           clock frequency x (1 + N(0, 0.015))
====================  ============================================================================

``--effect-scale`` multiplies every effect size (for power curves). Nuisances (``NOMINAL``) are
drawn per dataset log-uniformly over 0.25x..4x nominal, each zero with probability 0.15 where
zero is physical; ``--nuisance-scale X`` instead sets all of them to X times nominal.

    python benchmarks/indep_world.py --kind motion --hidden heading_bias --seed 3 --out /tmp/w
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from scipy.signal import lfilter

FORMAT = "kilobot-twin/measured-v1"
AXLE_M = 0.025  # only to express truth in the twin's heading-bias units (b = -omega L / v)
COMMANDED_SPEED_M_S = 0.06 * 48 / 255
TICK_HZ = 31.0
HALF_PERIOD_TICKS = 30
ADC_MAX = 1023.0

#: Nuisance levels, nominal (the twin's nominal where it has one). ``zero_ok``: zero is physical.
NOMINAL = {
    # name: (nominal, zero_ok, unit / meaning)
    "heading_noise": (0.01, False, "rad/sqrt(s): long-run heading diffusion intensity"),
    "heading_noise_tau_s": (0.5, True, "s: correlation time of the turn-rate noise (0 = white)"),
    "speed_noise": (0.0005, True, "m/sqrt(s): white noise on the forward speed"),
    "speed_trial_sd": (0.02, True, "relative sd of a robot's speed from trial to trial"),
    "turn_trial_sd": (0.002, True, "rad/s: sd of a robot's turn rate from trial to trial (Eq. 6)"),
    "tracking_noise_m": (0.002, True, "m: Gaussian position noise per frame"),
    "glitch_p": (0.002, True, "probability that a frame's position is a glitch"),
    "glitch_m": (0.02, False, "m: scale of a glitch (Student t, 2 dof)"),
    "drop_p": (0.02, True, "probability a frame is missing"),
    "time_jitter_s": (0.003, True, "s: sample time jitter (uniform +-)"),
    "start_delay_s": (1.0, True, "s: robots start moving/blinking uniformly within this delay"),
    "sensor_noise": (8.0, True, "ADC counts: reading noise sd"),
    "clock_trial_sd": (0.002, True, "relative sd of a clock's rate from trial to trial"),
    "tick_diffusion": (0.05, True, "ticks^2/s: phase diffusion of a clock"),
    # Last, so that the levels above draw as they did before these two were added.
    "tracking_correlated_m": (0.0015, True, "m: tracking error that persists over frames (sd per axis; a smoothing tracker)"),
    "tracking_tau_s": (0.2, False, "s: correlation time of that error (Ornstein-Uhlenbeck)"),
    # Last again, for the same reason.
    "sensor_offset_trial_sd": (4.0, True, "ADC counts: sd of a robot's sensor offset from trial to trial"),
}
EFFECTS = {"motion": ("heading_bias", "speed_heterogeneity", "bias_drift", "motion_noise", "floor_tilt"),
           "light_sweep": ("sensor_gain",), "blink": ("clock_drift",)}
FRAME_HZ = (5.0, 7.5, 10.0, 12.5, 15.0, 20.0, 25.0, 30.0)


def draw_nuisance(rng: np.random.Generator, scale: float | None = None) -> dict:
    """Nuisance levels: ``scale`` x nominal, or per level log-uniform in [0.25, 4] x nominal and
    zero with probability 0.15 where zero is physical."""
    out = {}
    for name, (nom, zero_ok, _) in NOMINAL.items():
        if scale is not None:
            out[name] = nom * scale if name != "glitch_m" else nom
            continue
        f = float(np.exp(rng.uniform(np.log(0.25), np.log(4.0))))
        out[name] = 0.0 if (zero_ok and rng.random() < 0.15) else nom * f
    return out


def draw_shape(rng: np.random.Generator, kind: str, fixed: bool) -> dict:
    """Robots, trials, frame rate, trial lengths, who misses which trial."""
    base_s = 120.0 if kind == "blink" else 60.0
    if fixed:  # the earlier issue's layout: 12 robots x 4 trials at 10 Hz, nothing missing
        n, K, hz = (16 if kind == "blink" else 12), 4, (30.0 if kind == "blink" else 10.0)
        lengths = np.full(K, base_s)
        missing = []
    else:
        n, K = int(rng.integers(6, 41)), int(rng.integers(3, 9))
        hz = float(rng.choice(FRAME_HZ))
        lengths = np.round(base_s * rng.uniform(0.75, 1.0, K), 1)
        missing = []
        for i in range(n):  # a robot misses a whole trial now and then (never more than one)
            if rng.random() < 0.1:
                missing.append((int(rng.integers(K)), i))
    return {"robots": n, "trials": K, "frame_hz": hz, "lengths_s": [float(x) for x in lengths], "missing": missing}


# --- motion -----------------------------------------------------------------------------------------

def _ou(z, h, tau):
    """Turn-rate noise on the internal grid, whose heading integral has unit diffusion
    (Var heading = t for t >> tau): white (tau = 0) or Ornstein-Uhlenbeck with correlation time tau."""
    if tau <= 0:
        return z / np.sqrt(h)
    a = np.exp(-h / tau)
    sd = np.sqrt(1.0 / (2.0 * tau))  # stationary sd: long-run diffusion 2 sd^2 tau = 1
    out = lfilter([np.sqrt(1 - a * a) * sd], [1.0, -a], z, axis=-1)
    return out + (a ** np.arange(1, z.shape[-1] + 1)) * sd * z[..., :1]  # start in the stationary law


def _ou_at(rng, t, sd, tau):
    """Ornstein-Uhlenbeck noise of stationary sd ``sd`` and correlation time ``tau`` sampled exactly
    at the times ``t`` (..., frames): x_j = a_j x_(j-1) + sd sqrt(1 - a_j^2) z_j with
    a_j = exp(-|t_j - t_(j-1)| / tau), started in the stationary law."""
    z = rng.standard_normal(t.shape)
    a = np.exp(-np.abs(np.diff(t, axis=-1)) / tau)
    b = sd * np.sqrt(1 - a * a)
    out = np.empty(t.shape)
    out[..., 0] = sd * z[..., 0]
    for j in range(1, t.shape[-1]):
        out[..., j] = a[..., j - 1] * out[..., j - 1] + b[..., j - 1] * z[..., j]
    return out


def motion(rng, shape, nz, hidden, effect_scale, program, track_rng=None):
    n, K, hz = shape["robots"], shape["trials"], shape["frame_hz"]
    v_cmd = program["commanded_speed_m_s"]
    v_pop = v_cmd * rng.uniform(0.85, 1.15)
    w_pop = rng.uniform(-0.003, 0.003)
    s = effect_scale
    w_i = w_pop + (rng.normal(0, 0.008 * s, n) if "heading_bias" in hidden else 0.0)
    v_i = v_pop * np.clip(1 + (rng.normal(0, 0.12 * s, n) if "speed_heterogeneity" in hidden else 0.0), 0.3, 2.0)
    dw_i = rng.normal(0, 0.0045 * s, n) if "bias_drift" in hidden else np.zeros(n)
    noise_i = nz["heading_noise"] * (np.exp(rng.normal(0, 0.6 * s, n)) if "motion_noise" in hidden else np.ones(n))
    tilt = {"amplitude": 0.15 * s, "downhill_rad": float(rng.uniform(-np.pi, np.pi))} if "floor_tilt" in hidden else None
    sub = int(np.ceil(100.0 / hz))  # internal steps per frame (>= 100 Hz)
    h = 1.0 / (hz * sub)
    rows = []
    truth_trials = []
    for k in range(K):
        L = shape["lengths_s"][k]
        steps = int(np.floor(L * hz)) * sub + sub
        w_k = w_i + dw_i * (k - (K - 1) / 2) + nz["turn_trial_sd"] * rng.standard_normal(n)
        v_k = v_i * (1 + nz["speed_trial_sd"] * rng.standard_normal(n))
        truth_trials.append(w_k.tolist())
        t = np.arange(steps) * h
        start = rng.uniform(0, nz["start_delay_s"], n) if nz["start_delay_s"] > 0 else np.zeros(n)
        moving = t[None, :] >= start[:, None]
        eta = noise_i[:, None] * _ou(rng.standard_normal((n, steps)), h, nz["heading_noise_tau_s"])
        xi = nz["speed_noise"] * rng.standard_normal((n, steps)) / np.sqrt(h)
        th0 = rng.uniform(-np.pi, np.pi, n)
        x = np.zeros((n, steps + 1))
        y = np.zeros((n, steps + 1))
        x[:, 0] = rng.uniform(-0.5, 0.5, n)
        y[:, 0] = rng.uniform(-0.5, 0.5, n)
        th = np.empty((n, steps + 1))
        th[:, 0] = th0
        # Heading first (independent of position), then exact chords: over a step of constant
        # turn rate w and speed v the robot moves 2 v/w sin(w h/2) along the mid-step heading.
        w = np.where(moving, w_k[:, None] + eta, 0.0)
        th[:, 1:] = th0[:, None] + np.cumsum(w * h, axis=1)
        mid = th[:, :-1] + 0.5 * w * h
        v = v_k[:, None] + xi
        if tilt:
            v = v + tilt["amplitude"] * v_pop * np.cos(mid - tilt["downhill_rad"])
        v = np.where(moving, v, 0.0)
        chord = v * h * np.sinc(w * h / (2 * np.pi))  # np.sinc(x) = sin(pi x)/(pi x)
        x[:, 1:] = x[:, :1] + np.cumsum(chord * np.cos(mid), axis=1)
        y[:, 1:] = y[:, :1] + np.cumsum(chord * np.sin(mid), axis=1)
        # The tracker: frames at jittered times, the position there by the chord from the last
        # internal step, Gaussian noise, heavy-tailed glitches, drops and tracking losses.
        frames = int(np.floor(L * hz)) + 1
        tf = np.arange(frames) / hz
        if nz["time_jitter_s"] > 0:
            tf = tf + rng.uniform(-nz["time_jitter_s"], nz["time_jitter_s"], (n, frames))
            tf[:, 0] = 0.0
        tf = np.clip(np.broadcast_to(tf, (n, frames)), 0, (steps - 1) * h)
        j = np.minimum((tf / h).astype(int), steps - 1)
        r = np.arange(n)[:, None]
        tau = tf - j * h
        wj, vj = w[r, j], v[r, j]
        a0 = th[r, j]
        c = vj * tau * np.sinc(wj * tau / (2 * np.pi))
        px = x[r, j] + c * np.cos(a0 + 0.5 * wj * tau)
        py = y[r, j] + c * np.sin(a0 + 0.5 * wj * tau)
        px = px + nz["tracking_noise_m"] * rng.standard_normal(px.shape)
        py = py + nz["tracking_noise_m"] * rng.standard_normal(py.shape)
        if nz["tracking_correlated_m"] > 0:  # from its own stream: the rest draws as before
            e = _ou_at(track_rng, np.broadcast_to(tf, (2,) + tf.shape), nz["tracking_correlated_m"], nz["tracking_tau_s"])
            px, py = px + e[0], py + e[1]
        g = rng.random(px.shape) < nz["glitch_p"]
        px[g] += nz["glitch_m"] * rng.standard_t(2, g.sum())
        py[g] += nz["glitch_m"] * rng.standard_t(2, g.sum())
        keep = _keep(rng, (n, frames), hz, nz["drop_p"])
        for i in range(n):
            if (k, i) in shape["missing"]:
                continue
            m = keep[i]
            rows.append(np.column_stack([np.full(m.sum(), k), np.full(m.sum(), i), tf[i, m], px[i, m], py[i, m]]))
    meta = {"kind": "motion", "dt_s": 1.0 / hz, "behavior": "straight", "nominal_speed_m_s": v_cmd}
    # Truth in the twin's units: b = -omega L / v (clockwise positive), speed factor against
    # the commanded speed, drift of b per trial; per-robot heading-noise intensity.
    truth = {"heading_bias": -w_i * AXLE_M / v_i, "speed_factor": v_i / v_cmd,
             "bias_drift": -dw_i * AXLE_M / v_i, "sigma_omega": noise_i, "turn_rate_rad_s": w_i, "speed_m_s": v_i}
    extra = {"floor_tilt": tilt, "population": {"speed_m_s": v_pop, "turn_rate_rad_s": w_pop},
             "trial_turn_rates_rad_s": truth_trials}
    return np.concatenate(rows), ("trial", "robot_id", "t_s", "x_m", "y_m"), meta, truth, extra


def _keep(rng, shape, hz, drop_p, loss_rate_per_s=1 / 60, loss_s=2.0):
    keep = rng.random(shape) >= drop_p
    starts = np.argwhere(rng.random(shape) < loss_rate_per_s / hz)
    for i, j in starts:
        keep[i, j:j + int(np.ceil(rng.uniform(0.2, 1.0) * loss_s * hz))] = False
    keep[:, 0] = True
    return keep


# --- light sweep --------------------------------------------------------------------------------------

def light_sweep(rng, shape, nz, hidden, effect_scale, program, offset_rng=None):
    n, K, hz = shape["robots"], shape["trials"], shape["frame_hz"]
    g_pop = 2.2 * rng.uniform(0.6, 1.5)
    o_pop = rng.uniform(0.0, 15.0)
    s = effect_scale
    g = g_pop * (np.exp(rng.normal(0, 0.25 * s, n)) if "sensor_gain" in hidden else np.ones(n))
    o = o_pop + (rng.normal(0, 6.0 * s, n) if "sensor_gain" in hidden else np.zeros(n))
    rows = []
    for k in range(K):
        L = shape["lengths_s"][k]
        frames = int(np.floor(L * hz)) + 1
        t = np.arange(frames) / hz
        if nz["time_jitter_s"] > 0:
            t = np.clip(t + rng.uniform(-nz["time_jitter_s"], nz["time_jitter_s"], frames), 0, None)
            t[0] = 0.0
        v_value = np.clip(t / L, 0, 1)  # one ramp of the projector's V per trial
        # This trial's offsets (their own stream, so the draws above and below are as before).
        o_k = o + (nz.get("sensor_offset_trial_sd", 0.0) * offset_rng.standard_normal(n) if offset_rng is not None else 0.0)
        raw = o_k[:, None] + g[:, None] * 1024.0 * v_value[None, :] + nz["sensor_noise"] * rng.standard_normal((n, frames))
        p = 9.0  # soft ceiling (another knee than any simulator's)
        sat = np.sign(raw) * np.abs(raw) / (1 + (np.abs(raw) / ADC_MAX) ** p) ** (1 / p)
        reading = np.clip(np.round(sat), 0, ADC_MAX)
        keep = rng.random((n, frames)) >= nz["drop_p"]
        keep[:, 0] = True
        for i in range(n):
            if (k, i) in shape["missing"]:
                continue
            m = keep[i]
            rows.append(np.column_stack([np.full(m.sum(), k), np.full(m.sum(), i), t[m], v_value[m], reading[i, m]]))
    meta = {"kind": "light_sweep", "dt_s": 1.0 / hz, "sweep": "one ramp of V from 0 to 1 per trial"}
    truth = {"sensor_gain": g, "sensor_offset": o}
    return np.concatenate(rows), ("trial", "robot_id", "t_s", "stimulus", "reading"), meta, truth, {
        "population": {"gain": g_pop, "offset": o_pop}}


# --- blink ------------------------------------------------------------------------------------------------

def blink(rng, shape, nz, hidden, effect_scale, program):
    n, K, hz = shape["robots"], shape["trials"], shape["frame_hz"]
    tick_hz, half = program["tick_hz"], program["half_period_ticks"]
    f_pop = tick_hz * rng.uniform(0.97, 1.03)
    f_i = f_pop * (1 + (rng.normal(0, 0.015 * effect_scale, n) if "clock_drift" in hidden else np.zeros(n)))
    rows = []
    for k in range(K):
        L = shape["lengths_s"][k]
        frames = int(np.floor(L * hz)) + 1
        t = np.arange(frames) / hz
        if nz["time_jitter_s"] > 0:
            t = np.clip(t + rng.uniform(-nz["time_jitter_s"], nz["time_jitter_s"], (n, frames)), 0, None)
            t[:, 0] = 0.0
        t = np.broadcast_to(t, (n, frames))
        f_k = f_i * np.maximum(1 + nz["clock_trial_sd"] * rng.standard_normal(n), 0.5)
        start = rng.uniform(0, nz["start_delay_s"], n) if nz["start_delay_s"] > 0 else np.zeros(n)
        run = np.maximum(t - start[:, None], 0.0)
        # Tick phase diffusion: a Wiener process in ticks sampled at the frame times.
        dW = np.diff(run, axis=1, prepend=0.0)
        phase = np.cumsum(np.sqrt(nz["tick_diffusion"] * dW) * rng.standard_normal((n, frames)), axis=1)
        ticks = f_k[:, None] * run + phase
        led = np.where(t >= start[:, None], (np.floor(np.maximum(ticks, 0) / half) % 2), 0.0)
        keep = rng.random((n, frames)) >= nz["drop_p"]
        keep[:, 0] = True
        for i in range(n):
            if (k, i) in shape["missing"]:
                continue
            m = keep[i]
            tt = t[i, m]
            order = np.argsort(tt, kind="stable")
            rows.append(np.column_stack([np.full(m.sum(), k), np.full(m.sum(), i), tt[order], led[i, m][order]]))
    meta = {"kind": "blink", "dt_s": 1.0 / hz, "half_period_ticks": half, "nominal_tick_hz": tick_hz}
    truth = {"clock_rate": f_i / tick_hz}
    return np.concatenate(rows), ("trial", "robot_id", "t_s", "led"), meta, truth, {"population": {"tick_hz": f_pop}}


# --- writing ----------------------------------------------------------------------------------------------

def _write(out: Path, meta: dict, columns, rows: np.ndarray):
    out.mkdir(parents=True, exist_ok=True)
    # JSON is YAML: the format allows JSON-compatible YAML.
    (out / "meta.yaml").write_text(json.dumps({"format": FORMAT, **meta}, indent=1) + "\n")
    # Times must increase within a (trial, robot); jitter can swap neighbours: drop those rows.
    rows = rows[np.lexsort((rows[:, 2], rows[:, 1], rows[:, 0]))]
    same = (rows[1:, 0] == rows[:-1, 0]) & (rows[1:, 1] == rows[:-1, 1])
    dup = np.concatenate([[False], same & (rows[1:, 2] <= rows[:-1, 2])])
    rows = rows[~dup]
    with (out / "observations.csv").open("w") as f:
        f.write(",".join(columns) + "\n")
        if columns[-1] == "led":
            colour = np.where(rows[:, 3] > 0.5, "blue", "red")
            lines = [f"{int(a)},{int(b)},{c:.4f},{d}" for a, b, c, d in zip(rows[:, 0], rows[:, 1], rows[:, 2], colour)]
        else:
            lines = [f"{int(r[0])},{int(r[1])},{r[2]:.4f}," + ",".join(f"{v:.6g}" for v in r[3:]) for r in rows]
        f.write("\n".join(lines) + "\n")


def draw_program(rng: np.random.Generator | None) -> dict:
    """What the robots were programmed to do: the commanded speed and the LED program. Without a
    generator, the Kilobot defaults; with one, commanded speeds of 0.6x-1.6x, toggling every 10-60
    ticks of a 25-40 Hz clock (measured-v1's ``nominal_speed_m_s``, ``half_period_ticks``,
    ``nominal_tick_hz``)."""
    if rng is None:
        return {"commanded_speed_m_s": COMMANDED_SPEED_M_S, "tick_hz": TICK_HZ, "half_period_ticks": HALF_PERIOD_TICKS}
    return {"commanded_speed_m_s": float(COMMANDED_SPEED_M_S * np.exp(rng.uniform(np.log(0.6), np.log(1.6)))),
            "tick_hz": float(rng.uniform(25.0, 40.0)), "half_period_ticks": int(rng.integers(10, 61))}


def generate(kind: str, hidden, out, seed: int = 0, nuisance_scale: float | None = None, effect_scale: float = 1.0,
             fixed_shape: bool = False, program: dict | str | None = None, nuisance: dict | None = None,
             design: tuple | None = None) -> dict:
    """Write one dataset to ``out`` (meta.yaml, observations.csv, truth.json); return the truth.
    ``program``: the commanded speed and LED program (:func:`draw_program`'s keys), ``"random"``
    to draw them per dataset, or None for the Kilobot defaults. ``nuisance``: levels that replace
    the drawn ones (keys of :data:`NOMINAL`), the rest drawn as before. ``design``: (robots,
    trials) in place of the fixed shape's (with ``fixed_shape``: trials of its length, none missed)."""
    hidden = [h for h in (hidden.split(",") if isinstance(hidden, str) else hidden) if h and h != "none"]
    for h in hidden:
        if h not in EFFECTS[kind]:
            raise ValueError(f"--hidden: {h} is not an effect of {kind} (use {', '.join(EFFECTS[kind])})")
    root = np.random.SeedSequence([seed, 0x1D3])
    # (spawned children are keyed by their index: the first ones are as they were before more were spawned)
    s_shape, s_nuis, s_world, s_prog, s_track, s_offset = (np.random.default_rng(s) for s in root.spawn(6))
    program = draw_program(s_prog if program == "random" else None) | (program if isinstance(program, dict) else {})
    shape = draw_shape(s_shape, kind, fixed_shape)
    if design is not None:
        if not fixed_shape:
            raise ValueError("design: only with fixed_shape (trials of one length, nobody missing)")
        shape |= {"robots": int(design[0]), "trials": int(design[1]), "lengths_s": shape["lengths_s"][:1] * int(design[1])}
    nz = draw_nuisance(s_nuis, nuisance_scale)
    for k, v in (nuisance or {}).items():
        if k not in NOMINAL:
            raise ValueError(f"nuisance: {k} is not a nuisance level (use {', '.join(NOMINAL)})")
        nz[k] = float(v)
    fn = {"motion": motion, "light_sweep": light_sweep, "blink": blink}[kind]
    rows, columns, meta, per_robot, extra = fn(s_world, shape, nz, hidden, effect_scale, program,
                                               **({"track_rng": s_track} if kind == "motion" else {}),
                                               **({"offset_rng": s_offset} if kind == "light_sweep" else {}))
    meta.update({"robots": list(range(shape["robots"])), "trials": shape["trials"],
                 "duration_s": float(max(shape["lengths_s"]))})
    out = Path(out)
    _write(out, meta, columns, rows)
    truth = {"generator": "indep_world", "kind": kind, "hidden": hidden, "seed": seed, "effect_scale": effect_scale,
             "nuisance": nz, "nuisance_scale": nuisance_scale, "shape": shape, "program": program, **extra,
             "robots": {str(i): {k: float(np.broadcast_to(v, (shape["robots"],))[i]) for k, v in per_robot.items()} for i in range(shape["robots"])}}
    (out / "truth.json").write_text(json.dumps(truth, indent=1))
    return truth


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--kind", choices=tuple(EFFECTS), default="motion")
    ap.add_argument("--hidden", default="none")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", required=True)
    ap.add_argument("--nuisance-scale", type=float, default=None, help="all nuisances at X x nominal (default: random)")
    ap.add_argument("--effect-scale", type=float, default=1.0)
    ap.add_argument("--fixed-shape", action="store_true", help="12 robots x 4 trials at 10 Hz (blink 16 at 30 Hz)")
    ap.add_argument("--random-program", action="store_true", help="draw the commanded speed and the LED program")
    ap.add_argument("--heading-noise-tau", type=float, default=None, help="s: force the turn-rate noise's correlation time")
    a = ap.parse_args(argv)
    try:
        truth = generate(a.kind, a.hidden, a.out, a.seed, a.nuisance_scale, a.effect_scale, a.fixed_shape,
                         "random" if a.random_program else None,
                         None if a.heading_noise_tau is None else {"heading_noise_tau_s": a.heading_noise_tau})
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(f"{a.out}: {truth['kind']} {truth['shape']['robots']} robots x {truth['shape']['trials']} trials at "
          f"{truth['shape']['frame_hz']} Hz, hidden {truth['hidden'] or 'nothing'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
