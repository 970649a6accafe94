"""Per-robot random streams that do not depend on who else is simulated.

Every random number a robot uses during a run is a pure function of
``(seed, run, robot, purpose, step, slot)``. We build it the way SplitMix64 does: a 64-bit
key per (seed, run, robot, purpose), a counter per (step, slot), and the SplitMix64 output
function ``mix64(key + counter * GOLDEN)``. The user's seed first goes through
:class:`numpy.random.SeedSequence`, which spreads any integer over 64 well-mixed bits.

Why counters instead of one ``numpy.random.Generator`` per robot: a robot's trajectory is then
identical whether it is simulated alone, inside a 10,000-robot batch, or in a batch split
across processes, by construction (nothing is shared and nothing is consumed in an order that
depends on the batch). A ROS node rebuilds its own stream from its key and step without
coordination. And it is cheap: 10,000 Generators cost about 0.2 s to create and need Python
loops to draw from, while here one vectorised expression serves the whole batch.

Draws that are not per step (drawing a population of traits, start poses) use ordinary
Generators from ``SeedSequence(seed).spawn``-style keys; see :func:`generator`.
"""

from __future__ import annotations

import numpy as np

from . import libm

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_S30, _S27, _S31 = np.uint64(30), np.uint64(27), np.uint64(31)
_TO_UNIT = 1.0 / float(1 << 53)
_S11 = np.uint64(11)
_S32 = np.uint64(32)
_LOW32 = np.uint64(0xFFFFFFFF)
_TO_UNIT32 = 1.0 / float(1 << 32)

#: Stream purposes: independent streams per robot for independent kinds of randomness, so
#: that adding (say) sensor noise does not change the motion noise a robot sees.
MOTION, WHEEL, SENSOR, BEHAVIOR, TRIAL = 1, 2, 3, 4, 5


_MASK64 = (1 << 64) - 1


def mix64(z: np.ndarray) -> np.ndarray:
    """SplitMix64 output function (Steele, Lea & Flood 2014) on uint64 arrays.

    Array arithmetic on uint64 wraps modulo 2^64 silently, which is what we want.
    """
    z = np.asarray(z, dtype=np.uint64)
    z = (z ^ (z >> _S30)) * _M1
    z = (z ^ (z >> _S27)) * _M2
    return z ^ (z >> _S31)


def _offset(counter) -> np.ndarray:
    """``counter * GOLDEN mod 2^64`` as a uint64 array: 0-d for an int (Python ints: no overflow
    warnings), of the counter's shape for an array of non-negative ints (uint64 arithmetic, which
    wraps mod 2^64 without a warning for arrays: the same values)."""
    if np.ndim(counter) == 0:
        return np.array((int(counter) * 0x9E3779B97F4A7C15) & _MASK64, dtype=np.uint64)
    return np.asarray(counter, dtype=np.uint64) * np.uint64(0x9E3779B97F4A7C15)


def root_key(seed: int) -> np.uint64:
    """64-bit root key from a user seed (any non-negative int), via SeedSequence."""
    return np.uint64(np.random.SeedSequence(int(seed)).generate_state(1, np.uint64)[0])


def robot_keys(seed: int, runs, robots, purpose: int) -> np.ndarray:
    """Keys for every (run, robot) pair and one purpose.

    Parameters
    ----------
    seed : int
        Root seed of the whole experiment.
    runs, robots : array_like of int, shapes (R,) and (N,)
        Global run indices and robot indices (not positions in this batch).
    purpose : int
        One of :data:`MOTION`, :data:`WHEEL`, :data:`SENSOR`, :data:`BEHAVIOR`, :data:`TRIAL`.

    Returns
    -------
    ndarray of uint64, shape (R, N)
    """
    runs = np.asarray(runs, dtype=np.uint64).reshape(-1, 1)
    robots = np.asarray(robots, dtype=np.uint64).reshape(1, -1)
    k = mix64(np.array(root_key(seed), dtype=np.uint64).reshape(1, 1) + _offset(purpose))
    k = mix64(k + (runs + np.uint64(1)) * _GOLDEN)
    return mix64(k ^ mix64((robots + np.uint64(1)) * _M1))


def uniform(keys: np.ndarray, counter) -> np.ndarray:
    """Uniform floats in [0, 1) for every key at one counter value (or an array of them,
    broadcast against ``keys``); shape of ``keys``."""
    z = mix64(keys + _offset(counter))
    return (z >> _S11).astype(np.float64) * _TO_UNIT


def normal_pair(keys: np.ndarray, counter) -> tuple[np.ndarray, np.ndarray]:
    """Two independent standard normals per key and counter (Box-Muller); ``counter`` an int or
    an array of them broadcast against ``keys`` (the values of one call per counter).

    One 64-bit hash gives both uniforms (its two 32-bit halves), which halves the hashing;
    the price is that tails are cut at sqrt(2 ln 2^32) = 6.66 sigma (probability 3e-11).
    """
    r, a = _radius_angle(keys, counter)
    return r * np.cos(a), r * np.sin(a)


def normal(keys: np.ndarray, counter) -> np.ndarray:
    """The first of :func:`normal_pair`'s two normals, bit for bit, without computing the second
    (a sine and a product fewer: the light sensor's reading noise, drawn for many frames at
    once, uses one)."""
    r, a = _radius_angle(keys, counter)
    return r * np.cos(a)


def _radius_angle(keys: np.ndarray, counter) -> tuple[np.ndarray, np.ndarray]:
    """Box-Muller's radius and angle from one 64-bit hash per key and counter (its two 32-bit
    halves as the two uniforms)."""
    z = mix64(keys + _offset(counter))
    u1 = ((z >> _S32).astype(np.float64) + 0.5) * _TO_UNIT32
    u2 = (z & _LOW32).astype(np.float64) * _TO_UNIT32
    return np.sqrt(-2.0 * libm.log(u1)), (2.0 * np.pi) * u2


def generator(seed: int, *spawn_key: int) -> np.random.Generator:
    """An ordinary Generator for one-off draws, keyed by (seed, *spawn_key)."""
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(int(seed), spawn_key=spawn_key)))


# Well-known spawn keys for one-off draws.
SPAWN_POPULATION = 1
