"""The measurement model: what a tracker or camera makes of the true trajectories.

Used both to write synthetic datasets and, inside the gap workflow, to pass simulated runs
through the same observation as the measured ones (same sampling, same noise, same gaps), so
that measured and simulated summaries are comparable.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..batch import kernel
from ..core import kinematics


@dataclass(frozen=True)
class Observation:
    """Tracker properties.

    tracking_noise_m : Gaussian position noise per sample (sd, m).
    jitter_s : sample times jitter uniformly by +-jitter_s around the nominal grid.
    drop_p : probability that a single frame is missing.
    gap_rate_per_s, gap_s : tracking losses start at this rate and last up to gap_s seconds.
    tracking_correlated_m, tracking_tau_s : on top of ``tracking_noise_m``, an error that persists
        from frame to frame (a tracker that smooths): Ornstein-Uhlenbeck noise of this sd and
        correlation time (:func:`correlated_noise`); 0: independent frames.
    """

    tracking_noise_m: float = 0.002
    jitter_s: float = 0.003
    drop_p: float = 0.02
    gap_rate_per_s: float = 1 / 60
    gap_s: float = 2.0
    tracking_correlated_m: float = 0.0
    tracking_tau_s: float = 0.0

    def mask(self, shape, dt_s: float, rng: np.random.Generator) -> np.ndarray:
        """Boolean 'observed' mask (..., T): dropped frames and tracking-loss gaps removed."""
        keep = rng.random(shape) >= self.drop_p
        T = shape[-1]
        flat = keep.reshape(-1, T)
        starts = rng.random(flat.shape) < self.gap_rate_per_s * dt_s
        for i, j in zip(*np.nonzero(starts)):
            length = int(np.ceil(rng.uniform(0.2, 1.0) * self.gap_s / dt_s))
            flat[i, j:j + length] = False
        flat[:, 0] = True  # every track has its first sample (the start is known)
        return flat.reshape(shape)


def noisy_positions(x, y, obs: Observation, rng: np.random.Generator):
    """Add tracking noise to true positions (same shape)."""
    return (x + obs.tracking_noise_m * rng.standard_normal(np.shape(x)),
            y + obs.tracking_noise_m * rng.standard_normal(np.shape(y)))


def correlated_noise(rng, shape, sd: float, tau_s: float, dt_s: float):
    """Ornstein-Uhlenbeck noise of sd ``sd`` sampled every ``dt_s`` along the last axis, in its
    stationary law from the first sample: the unit AR(1) sequence of the core's coloured turn-rate
    noise (:func:`kinematics.turn_noise_coefficients`: e[j] = a e[j-1] + c z[j]), times ``sd``.
    The recursion runs in place, compiled where Numba is (a third of a fit's simulation time went
    to ``scipy.signal.lfilter`` and its temporaries), with the same values either way."""
    a, c, _ = (float(v) for v in kinematics.turn_noise_coefficients(1.0, tau_s, dt_s))
    u = rng.standard_normal(shape)
    kernel.compiled(_ar1_rows, _vectorised_ar1)(u.reshape(-1, u.shape[-1]), a, c, float(sd))
    return u


def _ar1_rows(u, a, c, sd):  # pragma: no cover - compiled
    """In place, each row: e[0] = u[0], e[j] = c u[j] + a e[j-1]; then u = sd e (the operations of
    ``lfilter``'s recursion, so the values are the same to the last bit)."""
    R, T = u.shape
    for r in range(R):
        prev = u[r, 0]
        u[r, 0] = prev * sd
        for j in range(1, T):
            prev = c * u[r, j] + a * prev
            u[r, j] = prev * sd


def _vectorised_ar1(u, a, c, sd):
    """:func:`_ar1_rows` without Numba: the same recursion by ``scipy.signal.lfilter``."""
    from scipy.signal import lfilter

    u[:, 1:] *= c
    u[:] = lfilter([1.0], [1.0, -a], u, axis=-1)
    u *= sd


def jittered_times(t_s, shape, obs: Observation, rng: np.random.Generator):
    """Sample times with jitter (first sample stays at 0)."""
    t = np.broadcast_to(t_s, shape) + rng.uniform(-obs.jitter_s, obs.jitter_s, shape)
    t[..., 0] = 0.0
    return np.maximum(t, 0.0)
