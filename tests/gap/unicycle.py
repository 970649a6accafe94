"""A unicycle of the tests' own (none of the twin's code): the independent generator that the
motion summaries' theory tests drive. Headings are a Brownian motion; positions integrate a
constant speed (plus white speed noise along the path) and carry white tracking noise."""

import numpy as np


def brownian_headings(rng, R: int, T: int, dt: float, sig2: float) -> np.ndarray:
    """(R, T) headings starting at 0, diffusing with intensity sig2 (rad^2/s)."""
    return np.cumsum(np.sqrt(sig2 * dt) * rng.standard_normal((R, T)), axis=-1)


def tracks(rng, th, v: float, dt: float, e: float, speed_noise: float = 0.0):
    """Positions x, y (R, T) along headings ``th`` at speed v (m/s), speed noise of intensity
    ``speed_noise`` (m/sqrt(s)) and tracking noise of sd e (m) per coordinate."""
    step = v * dt
    if speed_noise > 0:
        step = step + speed_noise * np.sqrt(dt) * rng.standard_normal(th.shape)
    x = np.cumsum(step * np.cos(th), -1) + e * rng.standard_normal(th.shape)
    y = np.cumsum(step * np.sin(th), -1) + e * rng.standard_normal(th.shape)
    return x, y


def ou_noise(rng, R: int, T: int, dt: float, sd: float, tau: float) -> np.ndarray:
    """(R, T) tracking errors that persist from frame to frame: an Ornstein-Uhlenbeck process of
    sd ``sd`` and correlation time ``tau`` (s), sampled every dt, stepped exactly frame by frame."""
    e = np.empty((R, T))
    e[:, 0] = sd * rng.standard_normal(R)
    c = np.exp(-dt / tau)
    for j in range(1, T):
        e[:, j] = c * e[:, j - 1] + sd * np.sqrt(1 - c * c) * rng.standard_normal(R)
    return e
