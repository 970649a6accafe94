"""Robot clocks: individual tick rates, the blink program and Kuramoto-style coupling.

Each robot's ``kilo_ticks`` counter advances at ``tick_hz * clock_rate`` (paper Fig. 9: the
natural frequencies differ by about 1.5 %). Ticks are kept as floats; the program sees
``floor(ticks)``, as the firmware sees its integer counter.
"""

from __future__ import annotations

import numpy as np

from .constants import LED_BLUE, LED_RED


def advance(ticks, clock_rate, tick_hz: float, dt_s: float):
    """Ticks after one step of ``dt_s`` for clocks running at ``tick_hz * clock_rate``."""
    return ticks + (tick_hz * dt_s) * clock_rate


_LED_OF_PARITY = np.array([LED_RED, LED_BLUE], dtype=np.int8)


def blink_led(ticks, half_period_ticks: int):
    """LED of the blink program: red for the first ``half_period_ticks`` of each period, then blue.

    The firmware counts ticks into a phase 0..2H-1 and shows red below H, blue from H: the colour
    is the parity of the whole half-periods counted, here in integers as the firmware's counter
    (4x faster than float floor division, which long recordings' LED grids spend most time in).
    """
    return _LED_OF_PARITY[(np.floor(ticks).astype(np.int64) // int(half_period_ticks)) & 1]


def neighbours(x, y, radius_m: float):
    """Boolean adjacency (..., N, N) of robots closer than ``radius_m`` (self excluded)."""
    dx = x[..., :, None] - x[..., None, :]
    dy = y[..., :, None] - y[..., None, :]
    adj = dx * dx + dy * dy < radius_m * radius_m
    n = adj.shape[-1]
    adj[..., np.arange(n), np.arange(n)] = False
    return adj


def kuramoto_correction(ticks, adjacency, coupling_per_s: float, period_ticks: float, dt_s: float):
    """Phase correction (in ticks) that pulls each robot toward its neighbours this step.

    Discrete Kuramoto update on phases ``phi = 2 pi ticks / period``:
    ``dphi_i = k dt mean_{j in N(i)} sin(phi_j - phi_i)``, converted back to ticks. Because it is
    applied once per step, the update overshoots when ``k dt`` is large (roughly above 1): the
    linearised correction then flips sign every step and the swarm does not settle. That is
    the "too strong" regime of paper Fig. 9f.

    Parameters
    ----------
    ticks : ndarray, shape (..., N)
    adjacency : ndarray of bool, shape (..., N, N)
    """
    # sum_j A_ij sin(phi_j - phi_i) = cos phi_i (A sin phi)_i - sin phi_i (A cos phi)_i: two
    # mat-vecs instead of N^2 sines. The phase is reduced to one period first, so a clock that
    # has run for hours keeps its digits.
    phi = (2 * np.pi / period_ticks) * np.mod(ticks, period_ticks)
    s, c = np.sin(phi), np.cos(phi)
    a = adjacency.astype(float)
    pulled = a @ np.stack([s, c, np.ones_like(s)], axis=-1)  # (..., N, 3)
    total = c * pulled[..., 0] - s * pulled[..., 1]
    count = pulled[..., 2]
    mean = np.where(count > 0, total / np.maximum(count, 1), 0.0)
    return coupling_per_s * dt_s * mean * (period_ticks / (2 * np.pi))
