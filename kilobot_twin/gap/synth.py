"""``kilobot-twin synth``: measured-v1 datasets written by the twin, with named effects hidden in
them, realistic tracking noise, sample jitter and dropped frames, plus ``truth.json``.

Effect sizes are the paper's where it gives them: a heading-bias spread of about 0.008 rad/s in
turn rate (b sd 0.0177 at 1.13 cm/s), clock rates 1.5 % apart, sensor gains spread 2:1 (Fig. 8).
The others are our choices, documented in ``HIDDEN``.
"""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

import numpy as np

from ..recording import measured
from ..core import sim
from ..core.constants import WHEEL_SEPARATION_M
from ..core.kinematics import MotorConfig
from ..core.scenario import MAX_FLOOR_TILT, scenario_from_dict
from ..core.traits import SwarmTraits
from ..errors import ConfigError, is_number
from .observe import Observation, correlated_noise, jittered_times, noisy_positions

# The twin's nominal robot (what the base model assumes where it does not fit the data).
NOMINAL_MOTION_NOISE = {"sigma_omega": 0.01, "sigma_v": 0.0005}
#: The twin's sensor bend towards its ceiling (``SensorModel.knee``; p = 6 matches the paper's
#: Fig. 8b by eye).
SENSOR_KNEE = 6.0
#: (a robot's offset also shifts from trial to trial, by 4 counts: ambient light and temperature)
NOMINAL_SENSOR = {"sensor_gain": 2.2, "sensor_offset": 5.0, "sensor_noise": 8.0, "sensor_offset_trial_sd": 4.0}
FORWARD_SPEED_M_S = 0.06 * 48 / 255
TURN_RATE_SD_RAD_S = 0.008  # paper: heading-bias spread in turn rate
NOMINAL_CLOCK_TRIAL_SD = 0.002
HALF_PERIOD_TICKS, TICK_HZ = 30, 31.0  # the twin's blink program: toggle every 30 ticks of a 31 Hz clock

#: effect -> (data kind, description). ``floor_tilt`` is deliberately outside the gap library.
HIDDEN = {
    "heading_bias": ("motion", f"b ~ N(0, {TURN_RATE_SD_RAD_S * WHEEL_SEPARATION_M / FORWARD_SPEED_M_S:.4f}) "
                               f"({TURN_RATE_SD_RAD_S} rad/s turn-rate sd)"),
    "speed_heterogeneity": ("motion", "speed_factor ~ N(1, 0.08), clipped to [0.75, 1.25]"),
    "bias_drift": ("motion", "bias_drift ~ N(0, 0.01) per trial (over 4 trials the bias moves ~1.7 population sds, "
                             "like Fig. 1f's robot going from straight to clearly curving)"),
    "motion_noise": ("motion", "robots differ in noise intensity: sigma_omega x exp(N(0, 0.8)) per robot"),
    "floor_tilt": ("motion", "speed x (1 + 0.15 cos(heading - phi)), phi uniform: not in the gap library"),
    "sensor_gain": ("light_sweep", "sensor_gain ~ U(1.5, 3.0), sensor_offset ~ N(5, 6) counts"),
    "clock_drift": ("blink", "clock_rate ~ N(1, 0.015)"),
}
DEFAULTS = {"motion": {"robots": 12, "trials": 4, "duration_s": 60.0, "dt_s": 0.1},
            "light_sweep": {"robots": 12, "trials": 4, "duration_s": 60.0, "dt_s": 0.1},
            "blink": {"robots": 16, "trials": 4, "duration_s": 120.0, "dt_s": 1 / 30}}


def parse_hidden(text: str, kind: str) -> list[str]:
    names = [h.strip() for h in (text or "").split(",") if h.strip() and h.strip() != "none"]
    for h in names:
        if h not in HIDDEN:
            raise ConfigError("--hidden", f"unknown effect {h!r}", f"use none or a comma list of {', '.join(HIDDEN)}")
        if HIDDEN[h][0] != kind:
            raise ConfigError("--hidden", f"{h} is an effect of {HIDDEN[h][0]} data, not {kind}",
                              f"use --kind {HIDDEN[h][0]}")
    return names


def check_effect_scale(value) -> float:
    """``effect_scale`` as a float, or a :class:`ConfigError`: a number above 0."""
    if not (is_number(value) and value > 0):
        raise ConfigError("--effect-scale", f"must be a finite number above 0, got {value!r}",
                          "give the factor on the hidden effects' spread, e.g. 0.5 or 2")
    return float(value)


def synth(kind: str, hidden: str | list[str], out: str | Path, robots: int | None = None, trials: int | None = None,
          seed: int = 0, duration_s: float | None = None, obs: Observation = Observation(),
          nuisance: dict | None = None, heading_noise_tau_s: float = 0.0, effect_scale: float = 1.0) -> dict:
    """Write a dataset to ``out`` and return its truth (also written to ``out/truth.json``).

    ``nuisance`` multiplies the nominal noise levels of the world (keys ``sigma_omega``,
    ``sigma_v``, ``sensor_noise``, ``sensor_offset_trial_sd``, ``clock_trial_sd``; tracking noise
    goes through ``obs``):
    the workflow fits them, so evaluations randomise them. ``heading_noise_tau_s`` gives every
    robot's turn-rate noise that correlation time (the trait ``heading_noise_tau``; 0: white).
    ``effect_scale`` multiplies every hidden effect's size: its spread over the robots (``HIDDEN``'s
    sds; the sensor gains' and offsets' spread about their middle) and the tilted floor's slope
    (0.15 x the scale, at most 0.9, what a scenario allows): power studies set an effect to a given
    size. At 1 the robots and the floor are drawn exactly as without it.
    """
    effect_scale = check_effect_scale(effect_scale)
    if kind not in DEFAULTS:
        raise ConfigError("--kind", f"unknown kind {kind!r}", f"use one of {', '.join(DEFAULTS)}")
    effects = parse_hidden(hidden, kind) if isinstance(hidden, str) else list(hidden)
    d = DEFAULTS[kind]
    n = robots or d["robots"]
    K = trials or d["trials"]
    T = duration_s or d["duration_s"]
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(7,)))
    ids = np.arange(n)
    traits, truth_extra = _hidden_traits(kind, effects, n, rng, effect_scale)
    for k, f in (nuisance or {}).items():
        traits[k] = traits[k] * f
    if heading_noise_tau_s:
        traits["heading_noise_tau"] = np.full(n, float(heading_noise_tau_s))
    swarm = SwarmTraits(ids, traits)
    if kind == "motion":
        tracks, meta = _motion(swarm, K, T, d["dt_s"], seed, truth_extra.get("floor_tilt"), obs, rng)
    elif kind == "light_sweep":
        tracks, meta = _light_sweep(swarm, K, T, d["dt_s"], seed, obs, rng)
    else:
        tracks, meta = _blink(swarm, K, T, d["dt_s"], seed, obs, rng)
    meta.update({"robots": [int(i) for i in ids], "trials": K, "duration_s": T})
    out = Path(out)
    measured.write(out, meta, tracks)
    truth = {"kind": kind, "hidden": effects, "seed": seed, "effect_scale": effect_scale,
             "observation": asdict(obs), "nuisance": nuisance or {},
             **truth_extra,
             "descriptions": {h: HIDDEN[h][1] for h in effects},
             "robots": {str(int(i)): {k: float(v[j]) for k, v in swarm.values.items()} for j, i in enumerate(ids)}}
    (out / "truth.json").write_text(json.dumps(truth, indent=1))
    return truth


def _hidden_traits(kind, effects, n, rng, s: float = 1.0):
    from ..core.traits import TRAIT_DEFAULTS

    tr = {k: np.full(n, v) for k, v in TRAIT_DEFAULTS.items()}
    extra = {}
    if kind == "motion":
        for k, v in NOMINAL_MOTION_NOISE.items():
            tr[k][:] = v
        if "heading_bias" in effects:
            tr["heading_bias"] = rng.normal(0, TURN_RATE_SD_RAD_S * WHEEL_SEPARATION_M / FORWARD_SPEED_M_S * s, n)
        if "speed_heterogeneity" in effects:
            tr["speed_factor"] = np.clip(rng.normal(1.0, 0.08 * s, n), 0.75, 1.25)
        if "bias_drift" in effects:
            tr["bias_drift"] = rng.normal(0, 0.01 * s, n)
        if "motion_noise" in effects:
            tr["sigma_omega"] = tr["sigma_omega"] * np.exp(rng.normal(0, 0.8 * s, n))
        if "floor_tilt" in effects:
            extra["floor_tilt"] = {"amplitude": min(0.15 * s, MAX_FLOOR_TILT), "direction_rad": float(rng.uniform(-np.pi, np.pi))}
    elif kind == "light_sweep":
        for k, v in NOMINAL_SENSOR.items():
            tr[k][:] = v
        if "sensor_gain" in effects:
            tr["sensor_gain"] = rng.uniform(1.5, 3.0, n)
            tr["sensor_offset"] = rng.normal(5.0, 6.0 * s, n)
            if s != 1.0:  # the same draws at 1 (2.25 + (g - 2.25) would round)
                tr["sensor_gain"] = np.maximum(2.25 + (tr["sensor_gain"] - 2.25) * s, 0.1)  # gains > 0
    else:
        # Real clocks also wander between repetitions (paper Fig. 9b: counts differ by 1-3).
        tr["clock_trial_sd"][:] = NOMINAL_CLOCK_TRIAL_SD
        if "clock_drift" in effects:
            tr["clock_rate"] = rng.normal(1.0, 0.015 * s, n)
    return tr, extra


def _tracks(ids, t, keep, **columns) -> dict:
    """Per-(trial, robot) tracks of the observed samples.

    ``keep`` is (K, N, T); ``t`` and each column are (K, N, T) or (T,) (the same for all).
    """
    K, N, T = keep.shape
    full = {name: np.broadcast_to(v, keep.shape) for name, v in columns.items()}
    t = np.broadcast_to(t, keep.shape)
    return {(k, int(rid)): measured.Track(t[k, j, keep[k, j]], {c: v[k, j, keep[k, j]] for c, v in full.items()})
            for k in range(K) for j, rid in enumerate(ids)}


def motion_scenario(duration_s: float, dt_s: float, floor_tilt: dict | None = None,
                    forward_speed_m_s: float = FORWARD_SPEED_M_S):
    """Robots driving straight; ``forward_speed_m_s`` is the commanded speed (a dataset's
    ``nominal_speed_m_s``), set through the motors' top wheel speed."""
    doc = {"behavior": "straight", "dt_s": dt_s, "duration_s": duration_s, "tick_hz": 31.0}
    if forward_speed_m_s != FORWARD_SPEED_M_S:
        m = MotorConfig()
        doc["motors"] = {"wheel_speed_max_m_s": forward_speed_m_s * 255.0 * 2 / (m.straight_left + m.straight_right)}
    if floor_tilt:
        doc.update(floor_tilt=floor_tilt["amplitude"], floor_tilt_direction_rad=floor_tilt["direction_rad"])
    return scenario_from_dict(doc)


def _motion(swarm, K, T, dt, seed, tilt, obs, rng):
    sc = motion_scenario(T, dt, tilt)
    n = len(swarm)
    heading0 = rng.uniform(-np.pi, np.pi, (K, n))
    res = sim.simulate(sc, swarm, seed, runs=np.arange(K), trials=np.arange(K), record_every=1,
                       poses=(0.0, 0.0, heading0))
    x, y = noisy_positions(res.traj["x"], res.traj["y"], obs, rng)
    shape = x.shape
    keep = obs.mask(shape, dt, rng)
    t = jittered_times(res.t_s, shape, obs, rng)
    if obs.tracking_correlated_m > 0:  # drawn last: every other draw is as without it
        x = x + correlated_noise(rng, shape, obs.tracking_correlated_m, obs.tracking_tau_s, dt)
        y = y + correlated_noise(rng, shape, obs.tracking_correlated_m, obs.tracking_tau_s, dt)
    tracks = _tracks(swarm.ids, t, keep, x_m=x, y_m=y)
    meta = {"kind": "motion", "dt_s": dt, "behavior": "straight", "nominal_speed_m_s": FORWARD_SPEED_M_S,
            "tracking_noise_m": obs.tracking_noise_m}
    return tracks, meta


def light_scenario(duration_s: float, dt_s: float, knee: float = SENSOR_KNEE):
    return scenario_from_dict({"behavior": "still", "dt_s": dt_s, "duration_s": duration_s, "tick_hz": 31.0,
                               "light": {"kind": "sweep", "period_s": duration_s, "ramps": 1},
                               "sensor": {"knee": float(knee)}, "start": {"kind": "origin"}})


def _light_sweep(swarm, K, T, dt, seed, obs, rng):
    sc = light_scenario(T, dt)
    res = sim.simulate(sc, swarm, seed, runs=np.arange(K), trials=np.arange(K), record_every=1)
    t = res.t_s
    stim = sc.light.v_value(t)
    keep = rng.random(res.traj["reading"].shape) >= obs.drop_p
    keep[..., 0] = True
    tracks = _tracks(swarm.ids, t, keep, stimulus=stim, reading=res.traj["reading"])
    return tracks, {"kind": "light_sweep", "dt_s": dt, "sweep": "one ramp of V from 0 to 1 per trial"}


def blink_scenario(duration_s: float, dt_s: float, half_period_ticks: int = HALF_PERIOD_TICKS, tick_hz: float = TICK_HZ):
    """Uncoupled blinking robots; the LED program (toggle every ``half_period_ticks`` of a clock at
    ``tick_hz``) is a dataset's ``half_period_ticks`` and ``nominal_tick_hz``."""
    return scenario_from_dict({"behavior": {"kind": "blink", "half_period_ticks": int(half_period_ticks)}, "dt_s": dt_s,
                               "duration_s": duration_s, "tick_hz": float(tick_hz),
                               "start": {"kind": "grid", "spacing_m": 0.06, "columns": 4}})


def _blink(swarm, K, T, dt, seed, obs, rng):
    sc = blink_scenario(T, dt)
    res = sim.simulate(sc, swarm, seed, runs=np.arange(K), trials=np.arange(K), record_every=1)
    t = res.t_s
    keep = rng.random(res.traj["led"].shape) >= obs.drop_p
    keep[..., 0] = True
    tracks = _tracks(swarm.ids, t, keep, led=res.traj["led"].astype(float))
    meta = {"kind": "blink", "dt_s": dt, "half_period_ticks": HALF_PERIOD_TICKS, "nominal_tick_hz": TICK_HZ}
    return tracks, meta
