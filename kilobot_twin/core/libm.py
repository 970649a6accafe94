"""The C library's ``log``, ``exp`` and ``pow`` as NumPy ufuncs, for the core's random numbers,
light fields and sensor.

NumPy may replace these with SIMD versions of its own (on AVX-512 machines it does, for float64
``log``, ``exp`` and ``power``), which round some results differently from the C library in the
last bit. The compiled batch kernel (:mod:`kilobot_twin.batch.kernel`) calls the C library, and it
reproduces the core bit for bit only where both round alike; with NumPy's versions in the core
it found they did not and ran nothing. So the core calls the C library too: through ufuncs
compiled with Numba (whose ``math.log`` is the C library's), or NumPy's own functions where
Numba is not installed or is switched off (``KILOBOT_TWIN_JIT=0``), in which case the kernel
does not run either. Compiled on first use, cached on disk where the package is writable.
"""

from __future__ import annotations

import importlib.util
import math
import os
import threading

import numpy as np

#: Whether the core's log, exp and pow are the C library's (else NumPy's).
C_LIBRARY = os.environ.get("KILOBOT_TWIN_JIT", "1") != "0" and importlib.util.find_spec("numba") is not None

def _log(x):  # pragma: no cover - compiled
    return math.log(x)


def _exp(x):  # pragma: no cover - compiled
    return math.exp(x)


def _pow(x, y):  # pragma: no cover - compiled
    return x**y


_UFUNCS: dict = {}
_LOCK = threading.Lock()


def _ufuncs() -> dict:
    if not _UFUNCS:
        with _LOCK:
            if not _UFUNCS:
                if C_LIBRARY:
                    from numba import vectorize

                    made = {"log": vectorize(["float64(float64)"], cache=True)(_log),
                            "exp": vectorize(["float64(float64)"], cache=True)(_exp),
                            "pow": vectorize(["float64(float64, float64)"], cache=True)(_pow)}
                else:
                    made = {"log": np.log, "exp": np.exp, "pow": np.power}
                # all three at once: a thread that finds the dict filled (outside the lock) must
                # find every one of them, not "log" alone while "exp" compiles
                _UFUNCS.update(made)
    return _UFUNCS


def log(x):
    """Natural logarithm, elementwise (the C library's)."""
    return _ufuncs()["log"](np.asarray(x, dtype=np.float64))


def exp(x):
    """Exponential, elementwise (the C library's)."""
    return _ufuncs()["exp"](np.asarray(x, dtype=np.float64))


def power(v, e: float):
    """``v ** e`` for a scalar exponent ``e``, elementwise, with the shortcuts NumPy's ``**``
    takes for a scalar exponent (square, square root, identity, reciprocal, one), the C library's
    ``pow`` otherwise. The kernel's ``_pow`` takes the same steps."""
    v = np.asarray(v, dtype=np.float64)
    e = float(e)
    if e == 2.0:
        return v * v
    if e == 0.5:
        return np.sqrt(v)
    if e == 1.0:
        return v.copy()
    if e == -1.0:
        return 1.0 / v
    if e == 0.0:
        return np.ones_like(v)
    return _ufuncs()["pow"](v, e)
