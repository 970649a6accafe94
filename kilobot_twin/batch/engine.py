"""The batch engine's simulate: the compiled kernel where it applies, the core elsewhere.

:func:`simulate` takes the arguments of :func:`kilobot_twin.core.sim.simulate` and returns
the same :class:`~kilobot_twin.core.sim.Result`, bit for bit. The initial state comes from
the core (:func:`~kilobot_twin.core.sim.init_state`); the steps run in
:func:`.kernel.advance` on the state flattened to (runs x robots,) slots. Scenarios the kernel
does not cover (the blink program, whose robots are coupled; image light fields) and
installations without Numba, or whose NumPy rounds elementary functions differently, run on
the core as before.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..core import behaviors as B
from ..core import kinematics, rng, sim
from ..core.arena import Coverage
from ..core.light import ConeField, GaussianField, UniformSweepField
from ..core.scenario import Scenario
from ..core.traits import SwarmTraits
from . import kernel as K

_BEHAVIORS = {B.Straight: K.B_STRAIGHT, B.Still: K.B_STILL, B.RandomWalk: K.B_RANDOM_WALK,
              B.Phototaxis: K.B_PHOTOTAXIS, B.PhototaxisArgos: K.B_PHOTOTAXIS_ARGOS}
_LIGHTS = {ConeField: K.L_CONE, GaussianField: K.L_GAUSSIAN, UniformSweepField: K.L_SWEEP}


def compiled(scenario: Scenario) -> bool:
    """Will :func:`simulate` run this scenario on the compiled kernel?"""
    return (K.AVAILABLE and type(scenario.behavior) in _BEHAVIORS and type(scenario.light) in _LIGHTS
            and K.math_matches_numpy())


def share(fn, n: int, threads: int, least: int = 64) -> None:
    """Call ``fn(i0, i1)`` over contiguous ranges covering ``[0, n)``, in up to ``threads``
    threads with at least ``least`` items each (one call, in this thread, when that is one range).
    For compiled work that releases the GIL and writes disjoint parts of its outputs."""
    parts = max(1, min(threads, n // least))
    if parts == 1:
        fn(0, n)
        return
    bounds = np.linspace(0, n, parts + 1).astype(int)
    with ThreadPoolExecutor(parts) as pool:
        list(pool.map(fn, bounds[:-1], bounds[1:]))


def simulate(scenario: Scenario, traits: SwarmTraits, seed: int, runs=None, trials=None, robot_index=None,
             record_every: int = 0, poses=None, progress=None, coverage: bool | None = None,
             threads: int = 1, channels=sim.TRAJ_CHANNELS) -> sim.Result:
    """:func:`kilobot_twin.core.sim.simulate`, on the compiled kernel where :func:`compiled` says so
    (there in up to ``threads`` threads, each a share of the (run, robot) slots)."""
    if not compiled(scenario):
        return sim.simulate(scenario, traits, seed, runs=runs, trials=trials, robot_index=robot_index,
                            record_every=record_every, poses=poses, progress=progress, coverage=coverage,
                            channels=channels)
    st = sim.init_state(scenario, traits, seed, runs, trials, robot_index, poses)
    R, N = st.shape
    S = R * N
    n = scenario.n_steps
    window = min(scenario.cost_window_steps, n)
    fp, ip, sweep = _parameters(scenario, st)
    table = np.ascontiguousarray(scenario.motors.wheel_table_m_s(), dtype=np.float64)

    def flat(a, dtype=np.float64):
        return np.array(np.broadcast_to(a, (R, N)), dtype=dtype, order="C").reshape(S)  # a writable copy

    tr = st.traits
    beh = st.behavior
    x, y, th, ticks, reading = (flat(a) for a in (st.x, st.y, st.theta, st.ticks, st.reading))
    motion = flat(beh.get("motion", st.motion), np.int8)
    mode = flat(beh.get("mode", 0), np.int8)
    deadline = flat(beh.get("deadline", 0), np.int64)
    last = flat(beh.get("last", 0.0))
    last_d = flat(beh.get("last_d", 0.0))
    held = flat(beh.get("a", 0.0))
    bias, clock, offset = flat(st.bias), flat(st.clock), flat(st.offset)
    speed, wheel_noise, sigma_v, gain, noise = (
        flat(tr[k]) for k in ("speed_factor", "wheel_noise", "sigma_v", "sensor_gain", "sensor_noise"))
    # The turn-rate noise's coefficients from the core's own function (the same bits), and its state.
    turn_a, turn_c, turn_g = (flat(a) for a in kinematics.turn_noise_coefficients(tr["sigma_omega"], tr["heading_noise_tau"],
                                                                                  scenario.dt_s))
    turn = flat(st.turn_noise)
    kmot, kwheel, ksens, kbeh = (flat(st.keys[p], np.uint64) for p in (rng.MOTION, rng.WHEEL, rng.SENSOR, rng.BEHAVIOR))
    path, cost, rsum = np.zeros(S), np.zeros(S), np.zeros(S)

    use_cov = scenario.arena.walls if coverage is None else coverage
    cov = None
    visited = np.zeros((0, 0), dtype=bool)
    if use_cov:
        cov = Coverage(scenario.arena, (R, N))
        cov.mark(st.x, st.y)
        visited = cov.visited
        nx, ny = scenario.arena.grid_shape
        ip[K.I_COVERAGE], ip[K.I_NX], ip[K.I_NY] = 1, nx, ny

    empty_f, empty_i = np.zeros((0, 0)), np.zeros((0, 0), dtype=np.int8)
    rec_args = (0, empty_f, empty_f, empty_f, empty_f, empty_i)
    rec = sim.start_record(st, n, record_every, channels)
    if rec is not None:
        if "led" in rec:
            rec["led"][...] = st.led[..., None]  # no behaviour here drives the LED
        # Channels not kept go to the kernel as (slots, 0) arrays, which it does not write.
        rec_args = (int(record_every),) + tuple(rec[k].reshape(S, -1) if k in rec else np.zeros((S, 0), sim.TRAJ_DTYPES[k])
                                                for k in ("x", "y", "theta", "reading", "motion"))

    # Report progress about 100 times a run, but give each kernel call at least ~1e5 robot-steps
    # (a call costs some tens of microseconds of argument checking).
    chunk = max(1, n // 100, -(-100_000 // S)) if progress is not None else n

    def slots(s0, s1):
        for k0 in range(0, n, chunk):
            k1 = min(n, k0 + chunk)
            K.advance(s0, s1, k0, k1, n, window, fp, ip, table, sweep,
                      x, y, th, ticks, motion, reading, mode, deadline, last, last_d, held,
                      bias, clock, speed, wheel_noise, sigma_v, turn_a, turn_c, turn_g, turn, gain, offset, noise,
                      kmot, kwheel, ksens, kbeh, path, cost, rsum, visited, *rec_args)
            if progress is not None:
                progress(k1 - k0)

    # Slots are independent and the kernel releases the GIL: split them over threads (the
    # results do not depend on how). Progress is reported from one thread only.
    share(slots, S, 1 if progress is not None else threads)

    x, y, th, cost, path, rsum = (a.reshape(R, N) for a in (x, y, th, cost, path, rsum))
    return sim.result(st, scenario, (x, y, th), cost, path, np.zeros((R, N), dtype=np.int64), rsum, cov, rec,
                      record_every)


def _parameters(scenario: Scenario, st: sim.SimState):
    """The kernel's float and integer parameter vectors and the sweep field's intensity per step.

    Every constant is computed here with the same Python/NumPy expression the core uses, so
    the kernel sees the same bits.
    """
    fp = np.zeros(K.N_FP)
    ip = np.zeros(K.N_IP, dtype=np.int64)
    dt = scenario.dt_s
    tr = st.traits
    beh = scenario.behavior
    light = scenario.light
    sensor = scenario.sensor
    fp[K.F_DT] = dt
    fp[K.F_TICK_DT] = scenario.tick_hz * dt
    fp[K.F_TICK_HZ] = scenario.tick_hz
    fp[K.F_DT_OVER_L] = dt / scenario.motors.wheel_separation_m
    fp[K.F_ROOT_DT] = np.sqrt(dt)
    fp[K.F_COST_CX], fp[K.F_COST_CY] = light.center
    fp[K.F_LCX], fp[K.F_LCY] = light.center
    fp[K.F_PEAK] = light.peak
    ip[K.I_LIGHT] = _LIGHTS[type(light)]
    sweep = np.zeros(1)
    if isinstance(light, ConeField):
        fp[K.F_LPARAM] = light.radius_m
    elif isinstance(light, GaussianField):
        fp[K.F_LPARAM] = light.sigma_m**2
    elif beh.needs_light:  # sweep: the same intensity everywhere, a function of time only
        t = np.arange(scenario.n_steps + 1) * dt
        sweep = np.array(light.intensity(np.zeros_like(t), np.zeros_like(t), t), dtype=np.float64)
    fp[K.F_CEIL] = sensor.ceiling
    fp[K.F_KNEE] = sensor.knee
    fp[K.F_INV_KNEE] = 1.0 / sensor.knee if sensor.knee > 0 else 0.0
    fp[K.F_SQRT_SAMPLES] = np.sqrt(sensor.samples)
    ip[K.I_KNEE] = int(sensor.knee > 0)
    ip[K.I_NEEDS_LIGHT] = int(beh.needs_light)
    ip[K.I_SENSOR_NOISE] = int(np.any(tr["sensor_noise"] > 0))
    ip[K.I_WHEEL_NOISE] = int(np.any(tr["wheel_noise"] > 0))
    ip[K.I_MOTION_NOISE] = int(np.any(tr["sigma_v"] > 0) or np.any(tr["sigma_omega"] > 0))
    if scenario.floor_tilt:
        ip[K.I_TILT] = 1
        fp[K.F_TILT] = scenario.floor_tilt
        fp[K.F_TILT_DIR] = scenario.floor_tilt_direction_rad
    arena = scenario.arena
    if arena.walls:
        from ..core.constants import BODY_RADIUS_M

        ip[K.I_WALLS] = 1
        fp[K.F_HX] = 0.5 * arena.width_m - BODY_RADIUS_M
        fp[K.F_HY] = 0.5 * arena.height_m - BODY_RADIUS_M
    fp[K.F_COV_HALF_W] = 0.5 * arena.width_m
    fp[K.F_COV_HALF_H] = 0.5 * arena.height_m
    fp[K.F_COV_CELL] = arena.coverage_cell_m

    ip[K.I_BEHAVIOR] = _BEHAVIORS[type(beh)]
    hz = scenario.tick_hz
    if isinstance(beh, B.RandomWalk):
        fp[K.F_P_FORWARD] = beh.p_forward
        fp[K.F_FWD_MIN], fp[K.F_FWD_SPAN] = beh.forward_min_s, beh.forward_max_s - beh.forward_min_s
        fp[K.F_TURN_MIN], fp[K.F_TURN_SPAN] = beh.turn_min_s, beh.turn_max_s - beh.turn_min_s
    elif isinstance(beh, B.Phototaxis):
        t = {k: B.ms_to_ticks(getattr(beh, k), hz) for k in
             ("hold_ms", "forward_good_ms", "stop_ms", "turn_ms", "forward_after_turn_ms", "step_ms")}
        fp[K.F_P_RIGHT], fp[K.F_REF] = beh.p_right, beh.reference
        fp[K.F_THRESHOLD], fp[K.F_TOLERANCE], fp[K.F_MARGIN] = beh.change_threshold, beh.arrive_tolerance, beh.worse_margin
        ip[K.I_T_HOLD], ip[K.I_T_GOOD], ip[K.I_T_STOP] = t["hold_ms"], t["forward_good_ms"], t["stop_ms"]
        ip[K.I_T_TURN], ip[K.I_T_AFTER_TURN], ip[K.I_T_STEP] = t["turn_ms"], t["forward_after_turn_ms"], t["step_ms"]
    elif isinstance(beh, B.PhototaxisArgos):
        def d(ms):
            return B.delay_ticks(ms, hz)

        fp[K.F_P_RIGHT], fp[K.F_REF] = beh.p_right, beh.reference
        fp[K.F_THRESHOLD], fp[K.F_MARGIN] = beh.change_threshold, beh.worse_margin
        ip[K.I_T_HOLD], ip[K.I_T_STEP], ip[K.I_T_STOP] = d(beh.hold_ms), d(beh.step_ms), d(beh.stop_ms)
        ip[K.I_T_GOOD] = d(100) + d(beh.good_ms - 100)
        ip[K.I_T_TURN] = d(100) + d(beh.turn_ms - 100)
        ip[K.I_T_AFTER_TURN] = d(beh.forward_after_turn_ms)
        ip[K.I_OVERHEAD] = beh.loop_overhead_ticks
    return fp, ip, sweep

