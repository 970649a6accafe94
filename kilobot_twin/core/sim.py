"""One step function for one robot or a (runs, robots) batch, and a run loop around it.

The state is a :class:`SimState` of arrays shaped (runs, robots). :func:`step` advances it by
one ``dt_s``; a ROS robot node calls the same function on a (1, 1) state. Because every random
number is keyed by (seed, run, robot) (see :mod:`.rng`), a robot's trajectory does not depend
on which other robots share its batch. The only couplings between robots are the ones the
physics has: Kuramoto neighbours in the blink program.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import clocks, kinematics, light, metrics, rng
from .behaviors import Blink
from .constants import LED_OFF
from .scenario import Scenario
from .traits import SwarmTraits


@dataclass
class SimState:
    """Mutable state of a batch; every array is shaped (runs, robots) unless noted."""

    step: int
    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray
    ticks: np.ndarray
    bias: np.ndarray  # effective heading bias this trial (trait + drift * trial + trial jitter)
    clock: np.ndarray  # effective clock rate this trial
    motion: np.ndarray
    led: np.ndarray
    reading: np.ndarray
    behavior: dict
    keys: dict  # purpose -> uint64 keys
    runs: np.ndarray  # (R,) global run indices
    robot_ids: np.ndarray  # (N,)
    trials: np.ndarray  # (R,) trial index of each run
    adjacency: np.ndarray | None = None  # (R, N, N) Kuramoto neighbours
    traits: dict = field(default_factory=dict)  # trait arrays broadcast to (1, N)
    turn_noise: np.ndarray | None = None  # state of the coloured turn-rate noise (unit variance)
    offset: np.ndarray | None = None  # effective sensor offset this trial (trait + trial jitter)

    @property
    def shape(self):
        return self.x.shape


def start_poses(scenario: Scenario, seed: int, runs, robot_ids):
    """Start (x, y, theta), each (R, N), keyed by (seed, run, robot) or (seed, run) if shared."""
    runs = np.asarray(runs)
    robot_ids = np.asarray(robot_ids)
    R, N = len(runs), len(robot_ids)
    s = scenario.start
    key_robots = np.zeros(N, dtype=np.int64) if s.shared else robot_ids
    keys = rng.robot_keys(seed, runs, key_robots, rng.TRIAL + 100)
    given = None
    if s.kind == "poses":  # where the real robots stood (per robot id, per run if given)
        x, y, given = s.pose_table(runs, robot_ids)
    elif s.kind == "origin":
        x = np.zeros((R, N))
        y = np.zeros((R, N))
    elif s.kind == "uniform":
        x = (2 * rng.uniform(keys, 0) - 1) * s.half_width_m
        y = (2 * rng.uniform(keys, 1) - 1) * s.half_width_m
    else:  # grid: robot id k sits at row k // columns, column k % columns of a square
        # columns x columns lattice centred on the origin (rows beyond it continue downwards).
        # A robot's place depends on its id only, never on which other robots are simulated.
        col = robot_ids % s.columns
        row = robot_ids // s.columns
        centre = (s.columns - 1) / 2
        x = np.broadcast_to((col - centre) * s.spacing_m, (R, N)).copy()
        y = np.broadcast_to((centre - row) * s.spacing_m, (R, N)).copy()
    if s.heading_rad is None:
        theta = (2 * rng.uniform(keys, 2) - 1) * np.pi
    else:
        theta = np.full((R, N), float(s.heading_rad))
    if given is not None:
        theta = np.where(np.isnan(given), theta, given)
    return x, y, theta


def init_state(scenario: Scenario, traits: SwarmTraits, seed: int, runs=None, trials=None,
               robot_index=None, poses=None) -> SimState:
    """Initial state for the given global runs and a swarm's robots.

    Parameters
    ----------
    runs : array_like of int, shape (R,), optional
        Global Monte Carlo run indices (default ``[0]``); they key the random streams.
    trials : array_like of int, shape (R,), optional
        Trial index of each run (for ``bias_drift``); defaults to 0.
    robot_index : array_like of int, optional
        Positions in ``traits`` to simulate (default: all). Robot ids key the streams.
    poses : tuple of (R, N) arrays, optional
        Start (x, y, theta) to use instead of ``scenario.start``.
    """
    runs = np.arange(1) if runs is None else np.asarray(runs, dtype=np.int64).reshape(-1)
    if robot_index is not None:
        traits = traits.subset(robot_index)
    ids = traits.ids
    R, N = len(runs), len(ids)
    trials = np.zeros(R, dtype=np.int64) if trials is None else np.asarray(trials, dtype=np.int64).reshape(-1)
    keys = {p: rng.robot_keys(seed, runs, ids, p) for p in (rng.MOTION, rng.WHEEL, rng.SENSOR, rng.BEHAVIOR, rng.TRIAL)}
    tr = {k: v.reshape(1, N) for k, v in traits.values.items()}

    bias, clock, offset = _trial_rates(tr, keys[rng.TRIAL], trials)

    if poses is None:
        x, y, theta = start_poses(scenario, seed, runs, ids)
    else:
        x, y, theta = (np.broadcast_to(np.asarray(p, dtype=np.float64), (R, N)).copy() for p in poses)
    x, y = scenario.arena.confine(x, y)
    st = SimState(
        step=0, x=x, y=y, theta=theta, ticks=np.zeros((R, N)), bias=bias, clock=clock,
        motion=np.zeros((R, N), dtype=np.int8), led=np.full((R, N), LED_OFF, dtype=np.int8),
        reading=np.zeros((R, N)), behavior={}, keys=keys, runs=runs, robot_ids=ids, trials=trials, traits=tr,
        # The turn-rate noise starts in its stationary state (N(0, 1)); white noise ignores it.
        turn_noise=rng.normal_pair(keys[rng.TRIAL], 2)[0], offset=offset,
    )
    reading0 = _sense(scenario, st, 0.0, 0) if scenario.behavior.needs_light else np.zeros((R, N))
    st.reading = reading0
    st.behavior = scenario.behavior.init_state((R, N), reading0, scenario.tick_hz)
    if isinstance(scenario.behavior, Blink):
        if scenario.start.random_phase:
            period = 2 * scenario.behavior.half_period_ticks
            st.ticks = period * rng.uniform(keys[rng.TRIAL], 1)
        st.led = clocks.blink_led(st.ticks, scenario.behavior.half_period_ticks)
        if scenario.coupling_per_s > 0:
            st.adjacency = clocks.neighbours(x, y, scenario.neighbour_radius_m)
    return st


def _trial_rates(tr: dict, trial_keys, trials: np.ndarray):
    """Effective heading bias (trait + drift x trial + trial-to-trial jitter, Eq. 6), clock rate
    and sensor offset of each (run, robot) in this trial, each (R, N); the jitters are keyed by
    (seed, run, robot). (The offset's jitter is the second normal of the pair whose first starts
    the turn-rate noise: drawn where nothing else was, so no other stream moves.)"""
    jitter, clock_jitter = rng.normal_pair(trial_keys, 0)
    bias = tr["heading_bias"] + tr["bias_drift"] * trials.reshape(-1, 1) + tr["bias_trial_sd"] * jitter
    clock = tr["clock_rate"] * np.maximum(1.0 + tr["clock_trial_sd"] * clock_jitter, 0.05)
    offset = tr["sensor_offset"] + tr["sensor_offset_trial_sd"] * rng.normal_pair(trial_keys, 2)[1]
    return bias, clock, offset


def set_traits(st: SimState, traits: SwarmTraits) -> None:
    """Give the robots of ``st`` new traits (same robots, same order) from the next step on.

    The trial's effective bias, clock rate and sensor offset are derived again with the same keyed jitters,
    so the result equals a state initialised with these traits, up to the steps already taken.
    """
    st.traits = {k: v.reshape(1, -1) for k, v in traits.values.items()}
    st.bias, st.clock, st.offset = _trial_rates(st.traits, st.keys[rng.TRIAL], st.trials)


def restart_behavior(st: SimState, scenario: Scenario) -> None:
    """Start ``scenario.behavior``'s program afresh on every robot of ``st`` (at its current pose,
    clock and reading), from the next step on."""
    st.behavior = scenario.behavior.init_state(st.shape, st.reading, scenario.tick_hz)


def _sense(scenario: Scenario, st: SimState, t_s: float, counter: int):
    intensity = scenario.light.intensity(st.x, st.y, t_s)
    tr = st.traits
    return light.sense(intensity, tr["sensor_gain"], st.offset, tr["sensor_noise"],
                       st.keys[rng.SENSOR], counter, scenario.sensor)


def step(st: SimState, scenario: Scenario, table: np.ndarray | None = None) -> SimState:
    """Advance the state by one step of ``scenario.dt_s`` in place and return it.

    Order within a step: clocks tick (and couple), the robot senses at its current pose, the
    behaviour picks a motion, the wheels move the robot, walls confine it.
    """
    k = st.step
    dt = scenario.dt_s
    tr = st.traits
    st.ticks = clocks.advance(st.ticks, st.clock, scenario.tick_hz, dt)
    beh = scenario.behavior
    if isinstance(beh, Blink):
        if st.adjacency is not None:
            period = 2 * beh.half_period_ticks
            st.ticks = st.ticks + clocks.kuramoto_correction(st.ticks, st.adjacency, scenario.coupling_per_s, period, dt)
        st.led = clocks.blink_led(st.ticks, beh.half_period_ticks)
    now = np.floor(st.ticks).astype(np.int64)
    if beh.needs_light:
        st.reading = _sense(scenario, st, (k + 1) * dt, k + 1)
    st.motion = beh.decide(st.behavior, now, st.reading, st.keys[rng.BEHAVIOR], k, scenario.tick_hz)
    vl, vr = kinematics.wheel_speeds(st.motion, st.bias, tr["speed_factor"], tr["wheel_noise"], st.keys[rng.WHEEL],
                                     k, scenario.motors, table)
    if scenario.floor_tilt:
        slope = 1.0 + scenario.floor_tilt * np.cos(st.theta - scenario.floor_tilt_direction_rad)
        vl, vr = vl * slope, vr * slope
    x, y, th, st.turn_noise = kinematics.integrate(st.x, st.y, st.theta, vl, vr, tr["sigma_v"], tr["sigma_omega"],
                                                   st.keys[rng.MOTION], k, dt, scenario.motors.wheel_separation_m,
                                                   tr["heading_noise_tau"], st.turn_noise)
    st.x, st.y = scenario.arena.confine(x, y)
    st.theta = th
    st.step = k + 1
    return st


@dataclass
class Result:
    """What a run returns: per-(run, robot) summaries and, if asked, trajectories.

    Summaries (each (R, N)): ``x, y, theta`` final pose; ``cost_m`` mean distance to the light
    centre over the last ``cost_window_steps`` steps; ``path_m`` path length; ``switches`` LED
    toggles; ``coverage_m2`` area of visited coverage cells (walled arenas); ``reading_mean``.
    Trajectories (each (R, N, T)) at times ``t_s`` (T,): ``x, y, theta, led, reading, motion``, or
    those of the run's ``channels``.
    """

    summary: dict
    t_s: np.ndarray | None = None
    traj: dict | None = None
    runs: np.ndarray | None = None
    robot_ids: np.ndarray | None = None
    order: np.ndarray | None = None  # (R, T') Kuramoto order parameter per step, blink only


#: The trajectories a run can record, and their dtypes.
TRAJ_DTYPES = {"x": np.float64, "y": np.float64, "theta": np.float64, "reading": np.float64, "led": np.int8,
               "motion": np.int8}
TRAJ_CHANNELS = tuple(TRAJ_DTYPES)


def simulate(scenario: Scenario, traits: SwarmTraits, seed: int, runs=None, trials=None, robot_index=None,
             record_every: int = 0, poses=None, progress=None, coverage: bool | None = None,
             channels=TRAJ_CHANNELS) -> Result:
    """Run a batch for ``scenario.n_steps`` steps.

    Parameters
    ----------
    record_every : int
        Keep trajectories every this many steps (0: summaries only, memory O(R N)).
    channels : tuple of str
        Which trajectories to keep (of :data:`TRAJ_CHANNELS`; fewer cost less memory).
    progress : callable(int) or None
        Called with the number of steps done since the last call (for progress bars).
    coverage : bool, optional
        Track covered area; defaults to True in a walled arena.
    """
    st = init_state(scenario, traits, seed, runs, trials, robot_index, poses)
    R, N = st.shape
    n = scenario.n_steps
    table = scenario.motors.wheel_table_m_s()
    cx, cy = scenario.light.center
    window = min(scenario.cost_window_steps, n)
    cost = np.zeros((R, N))
    path = np.zeros((R, N))
    switches = np.zeros((R, N), dtype=np.int64)
    reading_sum = np.zeros((R, N))
    use_cov = scenario.arena.walls if coverage is None else coverage
    cov = None
    if use_cov:
        from .arena import Coverage

        cov = Coverage(scenario.arena, (R, N))
        cov.mark(st.x, st.y)
    rec = start_record(st, n, record_every, channels)
    is_blink = isinstance(scenario.behavior, Blink)
    needs_light = scenario.behavior.needs_light
    order = np.empty((R, n + 1)) if is_blink else None
    if is_blink:
        order[:, 0] = metrics.order_parameter(st.ticks, 2 * scenario.behavior.half_period_ticks)
    chunk = max(1, n // 100)
    done = 0
    for k in range(n):
        px, py, led0 = st.x, st.y, st.led
        step(st, scenario, table)
        path += np.hypot(st.x - px, st.y - py)
        if is_blink:
            switches += st.led != led0
        if needs_light:
            reading_sum += st.reading
        if k >= n - window:
            cost += np.hypot(st.x - cx, st.y - cy)
        if cov is not None:
            cov.mark(st.x, st.y)
        if rec is not None and (k + 1) % record_every == 0:
            _record(rec, st, (k + 1) // record_every)
        if is_blink:
            order[:, k + 1] = metrics.order_parameter(st.ticks, 2 * scenario.behavior.half_period_ticks)
        if progress is not None and (k + 1) % chunk == 0:
            progress(k + 1 - done)
            done = k + 1
    if progress is not None and done < n:
        progress(n - done)
    return result(st, scenario, (st.x, st.y, st.theta), cost, path, switches, reading_sum, cov, rec, record_every, order)


def start_record(st: SimState, n_steps: int, record_every: int, channels=TRAJ_CHANNELS) -> dict | None:
    """Trajectory arrays of ``channels``, each (R, N, T), with sample 0 taken; None when
    ``record_every`` is 0."""
    if not record_every:
        return None
    unknown = sorted(set(channels) - set(TRAJ_CHANNELS))
    if unknown or not channels:
        raise ValueError(f"channels: {unknown or 'none'} (choose one or more of {TRAJ_CHANNELS})")
    R, N = st.shape
    T = n_steps // record_every + 1
    rec = {k: np.empty((R, N, T), dtype=TRAJ_DTYPES[k]) for k in TRAJ_CHANNELS if k in channels}
    _record(rec, st, 0)
    return rec


def result(st: SimState, scenario: Scenario, pose, cost_sum, path, switches, reading_sum, cov, rec, record_every: int,
           order=None) -> Result:
    """The :class:`Result` of a finished run: final ``pose`` (x, y, theta), sums over the cost window
    and over the run (turned into means here), the coverage grid and the trajectories."""
    n = scenario.n_steps
    summary = {"x": pose[0], "y": pose[1], "theta": pose[2], "cost_m": cost_sum / min(scenario.cost_window_steps, n),
               "path_m": path, "switches": switches, "reading_mean": reading_sum / n, "bias": st.bias}
    if cov is not None:
        summary["coverage_m2"] = cov.area_m2()
    t_s = None if rec is None else np.arange(next(iter(rec.values())).shape[-1]) * record_every * scenario.dt_s
    return Result(summary=summary, t_s=t_s, traj=rec, runs=st.runs, robot_ids=st.robot_ids, order=order)


def _record(rec, st, i):
    for k, a in rec.items():
        a[..., i] = getattr(st, k)
