"""The core's log, exp and pow are the C library's: compared bit for bit with Python's math
module (which calls the C library itself), and the compiled kernel runs here because of it."""

import math

import numpy as np
import pytest

from kilobot_twin.batch import kernel
from kilobot_twin.core import libm


@pytest.mark.skipif(not libm.C_LIBRARY, reason="KILOBOT_TWIN_JIT=0 or no Numba: the core uses NumPy's functions")
def test_log_exp_pow_are_the_c_library_s_bit_for_bit():
    g = np.random.default_rng(5)
    v = np.concatenate([np.abs(g.normal(size=5000)) * s for s in (1e-6, 1e-3, 1.0, 30.0, 1e4)])
    assert np.array_equal(libm.log(v), [math.log(x) for x in v])
    assert np.array_equal(libm.exp(-v / 100), [math.exp(-x / 100) for x in v])
    for e in (6.0, 1.0 / 6.0, 0.3):
        assert np.array_equal(libm.power(v, e), [x**e for x in v]), e
    # the exponents for which NumPy's ** takes arithmetic shortcuts (the kernel's _pow too)
    assert np.array_equal(libm.power(v, 2.0), [x * x for x in v])
    assert np.array_equal(libm.power(v, 0.5), [math.sqrt(x) for x in v])
    assert np.array_equal(libm.power(v, -1.0), [1.0 / x for x in v])


def test_the_compiled_kernel_reproduces_the_core_here():
    """Where Numba is installed the kernel must run, not be skipped: its elementary functions give
    the core's bits (on this AVX-512 machine NumPy's own log, exp and power did not, and every
    compiled-engine identity test was skipped while the engine quietly ran the core)."""
    if not kernel.AVAILABLE:
        pytest.skip("no Numba or KILOBOT_TWIN_JIT=0: there is no kernel to run")
    assert kernel.math_matches_numpy()
