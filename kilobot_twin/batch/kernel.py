"""The compiled step loop of the batch engine: one (run, robot) slot at a time, all steps.

:func:`kilobot_twin.core.sim.step` advances a whole (runs, robots) array by one step with
NumPy; at a few hundred slots its cost is per-call overhead, not arithmetic. This module runs
the same physics as a Numba kernel over a flat (slots,) state: each slot is stepped through a
block of steps in registers, so the cost is per robot-step whatever the swarm size.

It mirrors the core expression by expression (same operations, same order, same constants;
no fast-math, no fused multiply-add), so its results are bit-identical to the core's: the
random numbers are the same keyed hashes (:mod:`kilobot_twin.core.rng`) and the elementary
functions are the C library's, as NumPy's are on this machine. :func:`math_matches_numpy`
checks the latter at run time and the engine falls back to the core where it does not hold
(NumPy builds that use SIMD versions of sin, cos, log or exp).

Numba is imported (and the kernel compiled, or loaded from its on-disk cache) on first use, so
importing this module costs nothing. Without Numba, or with ``KILOBOT_TWIN_JIT=0``,
:data:`AVAILABLE` is False and the engine uses the core.
"""

from __future__ import annotations

import importlib.util
import math
import os
import threading

import numpy as np

AVAILABLE = os.environ.get("KILOBOT_TWIN_JIT", "1") != "0" and importlib.util.find_spec("numba") is not None

# Behaviour kinds and light kinds the kernel knows (anything else runs on the core).
B_STRAIGHT, B_STILL, B_RANDOM_WALK, B_PHOTOTAXIS, B_PHOTOTAXIS_ARGOS = range(5)
L_CONE, L_GAUSSIAN, L_SWEEP = range(3)

# Layout of the float parameter vector ``fp``.
(F_DT, F_TICK_DT, F_TICK_HZ, F_DT_OVER_L, F_ROOT_DT, F_COST_CX, F_COST_CY, F_LCX, F_LCY, F_PEAK, F_LPARAM,
 F_CEIL, F_KNEE, F_INV_KNEE, F_SQRT_SAMPLES, F_TILT, F_TILT_DIR, F_HX, F_HY, F_COV_HALF_W, F_COV_HALF_H,
 F_COV_CELL, F_P_RIGHT, F_REF, F_THRESHOLD, F_TOLERANCE, F_MARGIN, F_P_FORWARD, F_FWD_MIN, F_FWD_SPAN,
 F_TURN_MIN, F_TURN_SPAN, N_FP) = range(33)
# Layout of the integer parameter vector ``ip``.
(I_BEHAVIOR, I_LIGHT, I_NEEDS_LIGHT, I_WALLS, I_WHEEL_NOISE, I_MOTION_NOISE, I_SENSOR_NOISE, I_KNEE, I_TILT,
 I_COVERAGE, I_NX, I_NY, I_T_HOLD, I_T_GOOD, I_T_STOP, I_T_TURN, I_T_AFTER_TURN, I_T_STEP, I_OVERHEAD,
 N_IP) = range(20)

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_S11, _S27, _S30, _S31, _S32 = (np.uint64(s) for s in (11, 27, 30, 31, 32))
_LOW32 = np.uint64(0xFFFFFFFF)
_TO_UNIT = 1.0 / float(1 << 53)
_TO_UNIT32 = 1.0 / float(1 << 32)
_TWO_PI = 2.0 * np.pi

# Motion and mode codes (core.constants / core.behaviors); repeated as plain ints for the kernel.
_STOP, _FORWARD, _LEFT, _RIGHT = 0, 1, 2, 3
_P_STEP, _P_HOLD, _P_GOOD, _P_STOP, _P_TURN, _P_AFTER_TURN, _P_ARRIVED = range(7)
_A_SETUP, _A_LOOP, _A_HOLD, _A_STOP, _A_TURN = range(5)


def _mix64(z):
    z = (z ^ (z >> _S30)) * _M1
    z = (z ^ (z >> _S27)) * _M2
    return z ^ (z >> _S31)


def _hash(key, counter):
    return _mix64(key + np.uint64(counter) * _GOLDEN)


def _uniform(key, counter):
    return np.float64(_hash(key, counter) >> _S11) * _TO_UNIT


def _normal_pair(key, counter):
    z = _hash(key, counter)
    u1 = (np.float64(z >> _S32) + 0.5) * _TO_UNIT32
    u2 = np.float64(z & _LOW32) * _TO_UNIT32
    r = math.sqrt(-2.0 * math.log(u1))
    a = _TWO_PI * u2
    return r * math.cos(a), r * math.sin(a)


def _pow(v, e):
    # ndarray ** python-float takes these shortcuts in NumPy (square, sqrt, reciprocal, ...).
    if e == 2.0:
        return v * v
    if e == 0.5:
        return math.sqrt(v)
    if e == 1.0:
        return v
    if e == -1.0:
        return 1.0 / v
    if e == 0.0:
        return 1.0
    return v ** e


def _clip(v, lo, hi):
    return min(max(v, lo), hi)


def _loop(spec):
    """The step loop as a Python function for Numba, specialised by ``spec``.

    ``spec`` None: the behaviour and the switches are read from ``ip`` at run time. A tuple
    ``(behaviour, needs_light, wheel_noise, motion_noise, tilt)``: they are constants (closure
    variables are compile-time constants to Numba, and part of its cache key), so the compiler
    drops the branches they rule out and the values those keep alive across the C library's
    calls.
    """
    generic = spec is None
    c_beh, c_light, c_wheel, c_motion, c_tilt = (B_STRAIGHT, False, False, False, False) if generic else spec

    def _advance(s0, s1, k0, k1, n, window, fp, ip, table, sweep,
                 x, y, th, ticks, motion, reading, mode, deadline, last, last_d, held,
                 bias, clock, speed, wheel_noise, sigma_v, turn_a, turn_c, turn_g, turn, gain, offset, noise,
                 kmot, kwheel, ksens, kbeh, path, cost, rsum, visited,
                 record_every, rec_x, rec_y, rec_th, rec_r, rec_mot):  # pragma: no cover - compiled
        """Advance slots ``[s0, s1)`` through steps ``[k0, k1)`` of ``n``, in place.

        Every array argument is flat over slots (``visited`` and ``rec_*`` are (slots, ...)).
        Per step and slot, in the order of :func:`kilobot_twin.core.sim.step` and the summary
        updates of :func:`kilobot_twin.core.sim.simulate`.
        """
        if generic:
            beh = ip[I_BEHAVIOR]
            needs_light = ip[I_NEEDS_LIGHT] != 0
            wheel_noisy = ip[I_WHEEL_NOISE] != 0
            motion_noisy = ip[I_MOTION_NOISE] != 0
            tilt = ip[I_TILT] != 0
        else:
            beh = c_beh
            needs_light = c_light
            wheel_noisy = c_wheel
            motion_noisy = c_motion
            tilt = c_tilt
        dt = fp[F_DT]
        tick_dt = fp[F_TICK_DT]
        dt_over_l = fp[F_DT_OVER_L]
        root_dt = fp[F_ROOT_DT]
        walls = ip[I_WALLS] != 0
        use_cov = ip[I_COVERAGE] != 0
        cost_from = n - window
        cost_cx, cost_cy = fp[F_COST_CX], fp[F_COST_CY]
        ceil_ = fp[F_CEIL]
        # Loop invariants read once: the arrays may alias as far as the compiler knows, so it
        # would load them again on every step.
        hx, hy = fp[F_HX], fp[F_HY]
        t0_l, t0_r = table[_FORWARD, 0], table[_FORWARD, 1]
        # Trajectories not asked for come as (slots, 0) arrays and are not written.
        keep_x, keep_y, keep_th = rec_x.shape[1] > 0, rec_y.shape[1] > 0, rec_th.shape[1] > 0
        keep_r, keep_mot = rec_r.shape[1] > 0, rec_mot.shape[1] > 0
        for s in range(s0, s1):
            xs, ys, ths, tk = x[s], y[s], th[s], ticks[s]
            mo, rd = motion[s], reading[s]
            md, dl, ls, ld, hd = mode[s], deadline[s], last[s], last_d[s], held[s]
            ps, cs, rss = path[s], cost[s], rsum[s]
            rate = tick_dt * clock[s]
            speed_s = speed[s]
            half_b = 0.5 * bias[s]
            f_left0 = speed_s * (1.0 + half_b)
            f_right0 = speed_s * (1.0 - half_b)
            amp = wheel_noise[s] * speed_s
            sv_root = sigma_v[s] * root_dt
            ta, tc, tg, zeta = turn_a[s], turn_c[s], turn_g[s], turn[s]
            kmot_s, kwheel_s = kmot[s], kwheel[s]
            phase = (k0 + 1) % record_every if record_every > 0 else 1  # (k + 1) % record_every, kept by counting
            for k in range(k0, k1):
                # Clocks tick.
                tk = tk + rate
                now = np.int64(math.floor(tk))
                # Sense at the current pose (light.sense).
                if needs_light:
                    lk = ip[I_LIGHT]
                    if lk == L_CONE:
                        r = math.hypot(xs - fp[F_LCX], ys - fp[F_LCY])
                        inten = _clip(fp[F_PEAK] * (1.0 - r / fp[F_LPARAM]), 0.0, fp[F_PEAK])
                    elif lk == L_GAUSSIAN:
                        ddx = xs - fp[F_LCX]
                        ddy = ys - fp[F_LCY]
                        r2 = ddx * ddx + ddy * ddy
                        inten = fp[F_PEAK] * math.exp(-0.5 * r2 / fp[F_LPARAM])
                    else:
                        inten = sweep[k + 1]
                    v = max(offset[s] + gain[s] * inten, 0.0)
                    if ip[I_KNEE] != 0:
                        v = v / _pow(1.0 + _pow(v / ceil_, fp[F_KNEE]), fp[F_INV_KNEE])
                    v = min(v, ceil_)
                    if ip[I_SENSOR_NOISE] != 0:
                        z, _ = _normal_pair(ksens[s], k + 1)
                        v = v + z * (noise[s] / fp[F_SQRT_SAMPLES])
                    rd = math.floor(_clip(v, 0.0, ceil_))
                # The behaviour picks a motion.
                if beh == B_STRAIGHT:
                    mo = _FORWARD
                elif beh == B_STILL:
                    mo = _STOP
                elif beh == B_RANDOM_WALK:
                    if now >= dl:
                        u_kind = _uniform(kbeh[s], 3 * k)
                        u_dur = _uniform(kbeh[s], 3 * k + 1)
                        u_dir = _uniform(kbeh[s], 3 * k + 2)
                        if u_kind < fp[F_P_FORWARD]:
                            dur_s = fp[F_FWD_MIN] + fp[F_FWD_SPAN] * u_dur
                            mo = _FORWARD
                        else:
                            dur_s = fp[F_TURN_MIN] + fp[F_TURN_SPAN] * u_dur
                            mo = _LEFT if u_dir < 0.5 else _RIGHT
                        dur = np.int64(math.floor(dur_s * fp[F_TICK_HZ] + 1e-9))
                        dl = now + max(dur, 1)
                elif beh == B_PHOTOTAXIS:
                    ref = fp[F_REF]
                    arrived = abs(rd - ref) <= fp[F_TOLERANCE]
                    if now >= dl and not arrived:
                        if md == _P_HOLD:
                            d_new = abs(rd - ref)
                            d_old = abs(ls - ref)
                            if d_new > d_old + fp[F_MARGIN]:
                                md, mo, dl = _P_STOP, _STOP, now + ip[I_T_STOP]
                            elif d_new < d_old:
                                md, mo, dl = _P_GOOD, _FORWARD, now + ip[I_T_GOOD]
                            else:
                                md, mo, dl = _P_STEP, _FORWARD, now + ip[I_T_STEP]
                            ls = rd
                        elif md == _P_STOP:
                            right = _uniform(kbeh[s], k) < fp[F_P_RIGHT]
                            md, mo, dl = _P_TURN, (_RIGHT if right else _LEFT), now + ip[I_T_TURN]
                        elif md == _P_TURN:
                            md, mo, dl = _P_AFTER_TURN, _FORWARD, now + ip[I_T_AFTER_TURN]
                        elif md == _P_STEP or md == _P_GOOD or md == _P_AFTER_TURN or md == _P_ARRIVED:
                            if abs(rd - ls) > fp[F_THRESHOLD]:
                                md, dl = _P_HOLD, now + ip[I_T_HOLD]
                            else:
                                md, mo, dl = _P_STEP, _FORWARD, now + ip[I_T_STEP]
                    if arrived:
                        md, mo = _P_ARRIVED, _STOP
                else:  # B_PHOTOTAXIS_ARGOS
                    if now >= dl:
                        o = ip[I_OVERHEAD]
                        if md == _A_LOOP or md == _A_SETUP:
                            if abs(rd - ls) > fp[F_THRESHOLD]:
                                hd = rd
                                md, dl = _A_HOLD, now + ip[I_T_HOLD]
                            else:
                                md, mo, dl = _A_LOOP, _FORWARD, now + ip[I_T_STEP] + o
                        elif md == _A_HOLD:
                            d = abs(hd - fp[F_REF])
                            diff = d - ld
                            ls, ld = hd, d
                            if diff > fp[F_MARGIN]:
                                md, mo, dl = _A_STOP, _STOP, now + ip[I_T_STOP]
                            elif diff < 0:
                                md, mo, dl = _A_LOOP, _FORWARD, now + ip[I_T_GOOD] + o
                            else:
                                md, dl = _A_LOOP, now + o
                        elif md == _A_STOP:
                            right = _uniform(kbeh[s], k) < fp[F_P_RIGHT]
                            md, mo, dl = _A_TURN, (_RIGHT if right else _LEFT), now + ip[I_T_TURN]
                        elif md == _A_TURN:
                            md, mo, dl = _A_LOOP, _FORWARD, now + ip[I_T_AFTER_TURN] + o
                # Wheels (kinematics.wheel_speeds).
                f_left = f_left0
                f_right = f_right0
                if wheel_noisy:
                    f_left = f_left + amp * (2.0 * _uniform(kwheel_s, 2 * k) - 1.0)
                    f_right = f_right + amp * (2.0 * _uniform(kwheel_s, 2 * k + 1) - 1.0)
                if mo == _FORWARD:
                    vl = t0_l * f_left
                    vr = t0_r * f_right
                else:
                    vl = table[mo, 0] * f_left
                    vr = table[mo, 1] * f_right
                if tilt:
                    slope = 1.0 + fp[F_TILT] * math.cos(ths - fp[F_TILT_DIR])
                    vl = vl * slope
                    vr = vr * slope
                # Pose (kinematics.integrate).
                ds = 0.5 * (vl + vr) * dt
                dth = (vr - vl) * dt_over_l
                if motion_noisy:
                    z_v, z_w = _normal_pair(kmot_s, k)
                    zeta = ta * zeta + tc * z_w  # kinematics.turn_noise_coefficients
                    if vl != 0 or vr != 0:
                        ds = ds + sv_root * z_v
                        dth = dth + tg * zeta
                    else:
                        ds = ds + 0.0
                        dth = dth + 0.0
                mid = ths + 0.5 * dth
                nx_ = xs + ds * math.cos(mid)
                ny_ = ys + ds * math.sin(mid)
                ths = ths + dth
                if walls:
                    nx_ = _clip(nx_, -hx, hx)
                    ny_ = _clip(ny_, -hy, hy)
                # Summaries (sim.simulate).
                ps = ps + math.hypot(nx_ - xs, ny_ - ys)
                xs, ys = nx_, ny_
                if needs_light:
                    rss = rss + rd
                if k >= cost_from:
                    cs = cs + math.hypot(xs - cost_cx, ys - cost_cy)
                if use_cov:
                    ix = min(max(np.int64((xs + fp[F_COV_HALF_W]) / fp[F_COV_CELL]), 0), ip[I_NX] - 1)
                    iy = min(max(np.int64((ys + fp[F_COV_HALF_H]) / fp[F_COV_CELL]), 0), ip[I_NY] - 1)
                    visited[s, ix * ip[I_NY] + iy] = True
                if record_every > 0:
                    if phase == 0:
                        j = (k + 1) // record_every
                        if keep_x:
                            rec_x[s, j] = xs
                        if keep_y:
                            rec_y[s, j] = ys
                        if keep_th:
                            rec_th[s, j] = ths
                        if keep_r:
                            rec_r[s, j] = rd
                        if keep_mot:
                            rec_mot[s, j] = mo
                    phase += 1
                    if phase == record_every:
                        phase = 0
            x[s], y[s], th[s], ticks[s], turn[s] = xs, ys, ths, tk, zeta
            motion[s], reading[s] = mo, rd
            mode[s], deadline[s], last[s], last_d[s], held[s] = md, dl, ls, ld, hd
            path[s], cost[s], rsum[s] = ps, cs, rss

    return _advance


# The specialised loops: the paper's Monte Carlo case (straight motion with Gaussian motion
# noise, Eq. 5; about a fifth faster than the generic loop), then the generic one.
LOOPS = {"straight_gaussian": (B_STRAIGHT, False, False, True, False), "generic": None}


def variant(ip) -> str:
    """The name (a key of ``LOOPS``) of the compiled loop :func:`advance` runs for ``ip``."""
    for name, spec in LOOPS.items():
        if spec is None or (ip[I_BEHAVIOR] == spec[0] and (ip[I_NEEDS_LIGHT] != 0) == spec[1]
                            and (ip[I_WHEEL_NOISE] != 0) == spec[2] and (ip[I_MOTION_NOISE] != 0) == spec[3]
                            and (ip[I_TILT] != 0) == spec[4]):
            return name
    raise AssertionError("LOOPS ends with the generic loop")


def _elementary(v, w, out):  # pragma: no cover - compiled
    for i in range(v.size):
        out[0, i] = math.cos(v[i])
        out[1, i] = math.sin(v[i])
        out[2, i] = math.log(abs(v[i]) + 1e-300)
        out[3, i] = math.exp(-abs(v[i]))
        out[4, i] = math.hypot(v[i], w[i])
        out[5, i] = abs(v[i]) ** 0.3


_HELPERS = ("_mix64", "_hash", "_uniform", "_normal_pair", "_pow", "_clip")
_COMPILED: dict = {}
_LOCK = threading.Lock()


def _compiled(name: str):
    """The Numba dispatcher of a loop of ``LOOPS`` or ``_elementary`` (wrapped once, on first use)."""
    if not _COMPILED:
        with _LOCK:
            if not _COMPILED:
                from numba import njit

                g = globals()
                for helper in _HELPERS:
                    g[helper] = njit(inline="always")(g[helper])
                _COMPILED["_elementary"] = njit(nogil=True, cache=True)(_elementary)
                for key, spec in LOOPS.items():
                    _COMPILED[key] = njit(nogil=True, cache=True)(_loop(spec))
    return _COMPILED[name]


_PASSES: dict = {}


def compiled(fn, fallback=None):
    """``fn`` (a loop over arrays) compiled with Numba, without the GIL and cached on disk, once per
    process on first use; where Numba is not (:data:`AVAILABLE`), ``fallback`` or ``fn`` itself in
    plain Python. For the gap workflow's per-track passes, which share none of the kernel's loops."""
    if fn not in _PASSES:
        with _LOCK:
            if fn not in _PASSES:
                if AVAILABLE:
                    from numba import njit

                    _PASSES[fn] = njit(nogil=True, cache=True)(fn)
                else:
                    _PASSES[fn] = fallback or fn
    return _PASSES[fn]


def advance(*args) -> None:
    """The compiled step loop (arguments as ``_loop(...)``'s ``_advance``), specialised for
    ``ip`` where a specialisation exists (:func:`variant`); releases the GIL while it runs."""
    _compiled(variant(args[7]))(*args)


_MATCH: bool | None = None


def math_matches_numpy() -> bool:
    """Do the kernel's cos, sin, log, exp, hypot and pow give the core's bits here? (cached)

    The kernel calls the C library. The core takes cos, sin and hypot from NumPy, which calls
    the C library for them on the builds we know, and log, exp and pow from
    :mod:`kilobot_twin.core.libm`, the C library's too (NumPy's own versions of these three are
    SIMD code on AVX-512 machines and round some results differently). Where anything differs
    the kernel would not reproduce the core bit for bit, and the engine runs the core instead.
    """
    global _MATCH
    if _MATCH is None:
        if not AVAILABLE:
            _MATCH = False
        else:
            g = np.random.Generator(np.random.PCG64(20231))
            v = np.concatenate([g.normal(size=20000) * s for s in (1e-3, 1.0, 30.0, 1e4)])
            w = g.normal(size=v.size)
            out = np.empty((6, v.size))
            _compiled("_elementary")(v, w, out)
            from ..core import libm

            ref = np.stack([np.cos(v), np.sin(v), libm.log(np.abs(v) + 1e-300), libm.exp(-np.abs(v)), np.hypot(v, w),
                            libm.power(np.abs(v), 0.3)])
            _MATCH = bool(np.array_equal(out, ref))
    return _MATCH
