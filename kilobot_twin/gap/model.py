"""The twin under a dataset's conditions: simulate it through the same observation and summarise.

A :class:`Conditions` holds what the data fixes (robots, trials, duration, sampling, start poses,
which samples were observed); :func:`simulate` runs M replicates of a swarm model under them and
returns the same per-(trial, robot) summaries as the measured data, shaped (M, trials, robots).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..batch import engine
from ..core import sim
from ..core.scenario import with_overrides
from ..core.traits import SwarmTraits
from ..recording import measured
from . import observe, summaries, synth

#: Which summaries each kind compares (the detection/scoring components).
COMPONENTS = {
    "motion": ("turn_rate", "speed", "diffusion"),
    "light_sweep": ("gain", "offset"),
    "blink": ("toggle_rate",),
}


#: Frame rate (Hz) that tracks are thinned to, about (see :func:`measured_summaries`).
RATE_HZ = 10.0

#: Threads one :func:`simulate` call uses for the engine and the track summaries. The results do
#: not depend on it (tested); the workflow's own threads (folds) may call it at the same time.
THREADS = min(2, os.cpu_count() or 1)


@dataclass
class Conditions:
    kind: str
    robot_ids: np.ndarray  # (N,)
    trials: int
    duration_s: float
    dt_s: float
    observed: np.ndarray  # (K, N, T) bool
    start: tuple | None = None  # motion: (x0, y0, theta0) each (K, N)
    tracking_noise_m: float = 0.002
    #: A tracker whose errors persist from frame to frame: on top of ``tracking_noise_m`` (then the
    #: independent part), noise of this sd correlated over ``tracking_tau_s`` (Ornstein-Uhlenbeck;
    #: :func:`summaries.tracking_noise_correlation`). 0: independent frames.
    tracking_correlated_m: float = 0.0
    tracking_tau_s: float = 0.0
    #: The pixel grid the data's positions are reported on, ((step_x, origin_x), (step_y,
    #: origin_y)) in m (:func:`summaries.position_lattice`), or None: the twin is observed
    #: through the same grid, after its tracking noise.
    lattice: tuple | None = None
    #: The camera's residual radial distortion fitted to the data's tracks
    #: (:func:`summaries.lens_distortion`: ``k1_per_m2`` and ``centre_m``), or None. The data's
    #: positions are undistorted by it before they are summarised, so the twin, observed without
    #: a lens, is compared with positions on the floor.
    lens: dict | None = None
    #: What the robots were programmed to do, from the dataset's meta: the commanded speed
    #: (motion; per-robot speed factors are relative to it) and the LED program (blink: toggle
    #: every ``half_period_ticks`` of a clock at ``tick_hz``; clock rates are relative to it).
    forward_speed_m_s: float = synth.FORWARD_SPEED_M_S
    half_period_ticks: int = synth.HALF_PERIOD_TICKS
    tick_hz: float = synth.TICK_HZ
    #: light_sweep: how the sensors bend towards their ceiling (the twin's ``SensorModel.knee``;
    #: 0 a hard clip), fitted to the data (:func:`summaries.sensor_knee`).
    sensor_knee: float = synth.SENSOR_KNEE
    #: light_sweep: the stimulus each robot saw at each frame (K, N, T; NaN where none), at which
    #: the twin's sensors are read (None: the twin's own ramp over ``duration_s``).
    stimulus: np.ndarray | None = None

    @property
    def shape(self):
        return (self.trials, len(self.robot_ids))


def measured_summaries(ds: measured.Dataset) -> tuple[Conditions, dict]:
    """Conditions and summaries (each (K, N)) of a measured dataset."""
    kind = ds.kind
    # The summaries look at seconds (displacements, sweeps, toggle rates over minutes): frames
    # beyond ~10 Hz add little to them but cost the simulations in proportion. Tracks are
    # thinned to every q-th frame (after cleaning); the twin is simulated at that rate and
    # observed at the same frames.
    q = max(1, int(round(1.0 / (RATE_HZ * ds.dt_s))))
    dt_s = ds.dt_s * q
    if kind == "motion":
        _, x = ds.grid("x_m")
        _, y = ds.grid("y_m")
        # Nuisances of the tracker are fitted to the data, not taken from meta or nominal values:
        # its noise level, its glitches and the robots' late starts.
        # Positions reported in whole pixels: the twin is observed through the same grid, and the
        # tracker's own noise is what the grid leaves to explain (the median-based estimate reads
        # 0 there, whatever the noise).
        noise = summaries.tracking_noise(x, y)
        lattice = summaries.position_lattice(x, y, noise)
        pixel = summaries.lattice_sd(lattice)
        noise = float(np.hypot(noise, pixel))
        x, y, _ = summaries.reject_glitches(x, y, noise, dt_s=ds.dt_s)
        if lattice is None:
            noise = summaries.tracking_noise(x, y)
            # Whether the tracker's errors persist from frame to frame (at the recorded frame
            # rate): the simulations then reproduce them, since they bend a track over seconds as
            # the heading noise does and would otherwise be read as it.
            corr = summaries.tracking_noise_correlation(x, y, ds.dt_s, noise_m=noise)
        else:
            # On a grid the error of a slow robot's position is a sawtooth over frames, which the
            # correlated part's fit would take for a tracker that smooths: the grid itself is
            # simulated instead, and a correlated error besides it is not fitted.
            noise = summaries.lattice_noise(x, y, lattice, ds.dt_s)
            corr = {"white_m": noise, "correlated_m": 0.0, "tau_s": 0.0}
        # A robot at rest before its start seems to wander by the tracker's whole error, the part
        # that persists over frames too: its onset is read against all of it. Against the
        # independent part alone, a tracker correlated over 0.26 s (3 mm, beside 2.4 mm
        # independent) let a resting robot's frames into its track: its trial's speed read low by
        # up to its late start over the trial's length, and the speed's within-robot variance
        # came out 2.2x what it is without late starts (median over 30 realisations of
        # independent world 3098's levels: 3.3e-8 against 1.5e-8 m^2/s^2; read against the
        # whole error, 1.6e-8).
        x, y = summaries.mask_before_onset(x, y, whole_tracking_error(corr["white_m"], corr["correlated_m"], lattice))
        # A lens that stretches the field's edges lengthens a robot's chords there, so robots that
        # range farther seem faster than they are (fitted speed factors 7-13 % too spread at
        # k1 = 0.05-0.06 / m^2, third world 3204, 3210, 3213): the data's positions are
        # undistorted. (Observing the twin through the lens instead reproduced it along the twin's
        # own paths, not the data's: third world 3213's trial speeds then varied more within a
        # robot in the noiseless twin than in the data, the speed noise was fitted at 0, and the
        # null dataset's held-out gap was 15.4.) The tracker's noise and grid are read before:
        # a lens stretches them by a few per cent at most.
        lens = summaries.lens_distortion(x, y, ds.dt_s, axis_m=ds.meta.get("camera_axis_m"),
                                         axis_sd_m=ds.meta.get("camera_axis_sd_m"))
        x, y = summaries.lens_undistort(x, y, lens)
        x, y = x[..., ::q], y[..., ::q]
        observed = np.isfinite(x)
        cond = Conditions(kind, np.array(ds.robots), ds.trials, ds.span_s, dt_s, observed, _start_poses(x, y, dt_s),
                          corr["white_m"], corr["correlated_m"], corr["tau_s"], lattice=lattice, lens=lens,
                          forward_speed_m_s=float(ds.meta.get("nominal_speed_m_s", synth.FORWARD_SPEED_M_S)))
        s = summaries.motion(x, y, dt_s, wander_lags_s=summaries.wander_lags(total_tracking_noise(cond)))
        cond.start = _start_on_the_whole_track(cond.start, s, observed, dt_s)
    elif kind == "light_sweep":
        st, rd = ds.grid("stimulus")[1][..., ::q], ds.grid("reading")[1][..., ::q]
        observed = np.isfinite(rd)
        s = summaries.light_sweep(st, rd)
        knee = summaries.sensor_knee(st, rd, s["gain"], s["offset"])
        cond = Conditions(kind, np.array(ds.robots), ds.trials, ds.span_s, dt_s, observed,
                          sensor_knee=synth.SENSOR_KNEE if knee is None else knee, stimulus=st)
    else:
        led = ds.grid("led")[1][..., ::q]
        observed = np.isfinite(led)
        s = summaries.blink(led, dt_s)
        cond = Conditions(kind, np.array(ds.robots), ds.trials, ds.span_s, dt_s, observed,
                          half_period_ticks=int(ds.meta.get("half_period_ticks", synth.HALF_PERIOD_TICKS)),
                          tick_hz=float(ds.meta.get("nominal_tick_hz", synth.TICK_HZ)))
    return cond, s


def sweep_readings(sc, swarm: SwarmTraits, seed: int, runs, trials, stimulus) -> np.ndarray:
    """The twin's readings of robots that stand under a uniform light whose V-value was
    ``stimulus`` (R, N, T) at each frame: each run's sensors (``core.light.sense``: the trial's
    offset, the reading noise, the knee of ``sc.sensor``, the clip and the ADC's integer average)
    read at the data's own stimuli, not at the twin's ramp. The ramp's samples are evenly spaced,
    so a noiseless sensor's rounding runs as a regular sawtooth along it, which a line averages
    out; where another world's frames come at uneven times or its projector steps, its rounding
    is as good as white noise. The robots stand still, so nothing else of a step matters: at the
    twin's ramp (frame j at j dt) these are the engine's readings, draw for draw (tested)."""
    from ..core import light, rng

    st = sim.init_state(sc, swarm, seed, runs=runs, trials=trials)
    gain, noise, offset, keys = (a[..., None] for a in (st.traits["sensor_gain"], st.traits["sensor_noise"], st.offset,
                                                        st.keys[rng.SENSOR]))
    v = np.nan_to_num(np.asarray(stimulus, dtype=float), nan=0.0)
    out = np.empty(v.shape)
    for j in range(0, v.shape[-1], _FRAMES_AT_ONCE):  # frames in blocks: vectorised, in bounded memory
        f = slice(j, min(j + _FRAMES_AT_ONCE, v.shape[-1]))
        out[..., f] = light.sense(sc.light.peak * v[..., f], gain, offset, noise, keys, np.arange(f.start, f.stop),
                                  sc.sensor)
    return out


#: Frames :func:`sweep_readings` reads at once.
_FRAMES_AT_ONCE = 64


def whole_tracking_error(white_m: float, correlated_m: float, lattice=None) -> float:
    """The tracker's whole position noise sd: the independent and the correlated parts, and the
    pixel grid's."""
    return float(np.hypot(np.hypot(white_m, correlated_m), summaries.lattice_sd(lattice)))


def total_tracking_noise(cond: Conditions) -> float:
    """:func:`whole_tracking_error` of the tracker the conditions were fitted with."""
    return whole_tracking_error(cond.tracking_noise_m, cond.tracking_correlated_m, cond.lattice)


def _start_on_the_whole_track(start, s, observed, dt_s):
    """The start poses with each heading read off the whole track: its mean heading (the
    summary's, over the track's chords) less its turn rate times the time from the first observed
    frame to the track's centre. A robot's simulated heading follows from its start, and the data's
    direction over a 2 s chord is off by the tracker's error over a robot's 2 cm: 0.13 rad at 2 mm
    (twin's tilted floor, 12 robots: the tilt's speed per track predicted 2 % off, where its spread
    is 0.9 %). Only what depends on where a robot heads notices (a tilted floor; summaries of
    straight runs are the same in every direction). The chord's heading stays where the track has
    no turn rate (a slipped heading) or too few frames."""
    x0, y0, th0 = start
    t = np.arange(observed.shape[-1]) * dt_s
    with np.errstate(all="ignore"):
        n = observed.sum(-1)
        centre = (observed * t).sum(-1) / n
        first = np.argmax(observed, axis=-1) * dt_s
        th = s["heading"] - s["turn_rate"] * (centre - first)
    return x0, y0, np.where(np.isfinite(th) & (n > 0), np.angle(np.exp(1j * th)), th0)


def _start_poses(x, y, dt_s, lag_s=2.0):
    """First observed position and the heading of the first observed lagged displacement."""
    K, N, T = x.shape
    L = max(1, int(round(lag_s / dt_s)))
    x0 = np.zeros((K, N))
    y0 = np.zeros((K, N))
    th0 = np.zeros((K, N))
    for k in range(K):
        for i in range(N):
            ok = np.flatnonzero(np.isfinite(x[k, i]))
            if not ok.size:
                continue
            j = ok[0]
            x0[k, i], y0[k, i] = x[k, i, j], y[k, i, j]
            later = ok[ok >= j + L]
            if later.size:
                jj = later[0]
                th0[k, i] = np.arctan2(y[k, i, jj] - y[k, i, j], x[k, i, jj] - x[k, i, j])
    return x0, y0, th0


#: where a scenario field that an effect fitted came from, for its error message
_FITTED = "the scenario an effect's fit set (TwinModel.scenario)"


def simulate(cond: Conditions, swarm, M: int, seed: int, trials=None) -> dict:
    """M replicates of the swarm under the conditions; summaries shaped (M, K', N).

    ``swarm`` is a :class:`SwarmTraits` or a model carrying one (``.swarm``) and population
    nuisances the core does not model (``.speed_trial_sd``: a robot's speed jitters from trial
    to trial by this relative sd; applied by scaling each track's displacement from its start),
    and the scenario's fields that fitted effects set (``.scenario``: dotted keys of a scenario
    file, e.g. ``floor_tilt``), applied over the kind's scenario and checked as a scenario file is.
    ``trials`` restricts to a subset of trial indices (K' of them). Replicate m of trial k is
    global run ``m * K + k`` so that replicates are independent and reproducible.
    """
    speed_trial_sd = float(getattr(swarm, "speed_trial_sd", 0.0))
    frame_lead = getattr(swarm, "frame_lead", "aligned")
    fitted = dict(getattr(swarm, "scenario", None) or {})
    swarm = getattr(swarm, "swarm", swarm)
    trials = np.arange(cond.trials) if trials is None else np.asarray(trials)
    Kp = len(trials)
    runs = (np.arange(M)[:, None] * cond.trials + trials[None, :]).reshape(-1)
    trial_idx = np.tile(trials, M)
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(11, int(runs[0]), len(runs))))
    mask = np.tile(cond.observed[trials], (M, 1, 1))  # (M*K', N, T)
    if cond.kind == "motion":
        sc = with_overrides(synth.motion_scenario(cond.duration_s, cond.dt_s, None, cond.forward_speed_m_s), fitted, _FITTED)
        x0, y0, th0 = (np.tile(a[trials], (M, 1)) for a in cond.start)
        res = engine.simulate(sc, swarm, seed, runs=runs, trials=trial_idx, record_every=1, poses=(x0, y0, th0),
                              threads=THREADS, channels=("x", "y"))
        T = mask.shape[-1]
        x, y = res.traj["x"][..., :T], res.traj["y"][..., :T]
        f = 1.0 + speed_trial_sd * rng.standard_normal(x.shape[:-1] + (1,)) if speed_trial_sd > 0 else None
        # The speed's trial jitter, tracking noise, then the data's gaps; in place (the same values
        # as start + f (a - start) + noise * z, without temporaries the size of the tracks).
        hidden = ~mask
        tracks = []
        for axis, a in enumerate((x, y)):
            z = rng.standard_normal(mask.shape)
            z *= cond.tracking_noise_m
            if cond.tracking_correlated_m > 0:
                z += observe.correlated_noise(rng, mask.shape, cond.tracking_correlated_m, cond.tracking_tau_s, cond.dt_s)
            if f is not None:
                a0 = a[..., :1].copy()
                a -= a0
                a *= f
                a += a0
            z += a
            if cond.lattice is not None:  # reported in whole pixels, as the data are
                summaries.quantize(z, *cond.lattice[axis], out=z)
            z[hidden] = np.nan
            tracks.append(z)
        s = summaries.motion(*tracks, cond.dt_s, wander_lags_s=summaries.wander_lags(total_tracking_noise(cond)),
                              threads=THREADS)
    elif cond.kind == "light_sweep":
        sc = with_overrides(synth.light_scenario(cond.duration_s, cond.dt_s, cond.sensor_knee), fitted, _FITTED)
        T = mask.shape[-1]
        if cond.stimulus is None:
            stim = np.broadcast_to(sc.light.v_value(np.arange(T) * cond.dt_s), mask.shape)
        else:
            stim = np.tile(cond.stimulus[trials], (M, 1, 1))
        reading = sweep_readings(sc, swarm, seed, runs, trial_idx, stim)
        s = summaries.light_sweep(np.where(mask, stim, np.nan), np.where(mask, reading, np.nan))
    else:
        sc = with_overrides(synth.blink_scenario(cond.duration_s, cond.dt_s, cond.half_period_ticks, cond.tick_hz), fitted, _FITTED)
        T = mask.shape[-1]
        # Robots started apart from a free-running camera (``frame_lead`` random): each track
        # starts at a uniform point of the robot's LED cycle, so the timing error differs between
        # replicates too. Of the whole cycle, not of one frame: where a robot stands in its cycle
        # at the first frame sets which toggles fall inside the trial, and the frames' rounding of
        # the first and the last of them depends on how many periods lie between. Within one frame
        # every replicate counts the same periods, and where those span nearly a whole number of
        # frames the replicates tie (independent world blink 3254: robots started up to 3.5 s
        # late, 10.75 frames a toggle; in its 118 s trial the twin's replicates varied 0.03 %, the
        # data's robots 0.07 %, seven of them at 7-10 sd, and the null's gap was 1.60).
        phase = rng.uniform(0.0, 1.0, size=(len(runs), len(swarm))) if frame_lead == "random" else None
        led = blink_leds(sc, swarm, seed, runs, trial_idx, T, phase)
        s = summaries.blink(np.where(mask, led.astype(float), np.nan), cond.dt_s, threads=THREADS)
    return {k: v.reshape(M, Kp, -1) for k, v in s.items()}


def blink_leds(sc, swarm: SwarmTraits, seed: int, runs, trials, T: int, phase=None) -> np.ndarray:
    """LED states of uncoupled blinking robots at steps 0..T-1, without stepping the physics.

    Without coupling a robot's ticks grow linearly, ``ticks(k) = k * dt * tick_hz * rate``
    (``rate`` with its trial jitter, from the core's own ``init_state``), so its LED is the
    core's ``blink_led`` of that; identical to :func:`kilobot_twin.core.sim.simulate` (tested)
    and hundreds of times cheaper for long recordings. ``phase`` (runs, robots): where each
    robot's clock stands in its LED cycle (on and off, ``2 half_period_ticks``) at frame 0, as a
    fraction of the cycle (ticks start at ``phase * 2 half_period_ticks``); None: at its start.
    """
    from ..core import clocks

    st = sim.init_state(sc, swarm, seed, runs=runs, trials=trials)
    ticks = np.zeros(st.clock.shape + (T,))
    # Accumulate in the same order as the stepped simulation (float sums are order-sensitive).
    inc = (sc.tick_hz * sc.dt_s) * st.clock
    acc = np.zeros(st.clock.shape)
    if phase is not None:  # each robot's clock stands at that fraction of its cycle at the first frame
        acc = 2.0 * sc.behavior.half_period_ticks * np.asarray(phase, dtype=float)
        ticks[..., 0] = acc
    for k in range(1, T):
        acc = acc + inc
        ticks[..., k] = acc
    return clocks.blink_led(ticks, sc.behavior.half_period_ticks)
