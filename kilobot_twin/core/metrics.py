"""Swarm metrics, each defined once, on arrays whose last axis is the robots, NaN-aware.

A robot whose value is NaN (not heard from, a tracking gap) is left out of that sample; a sample
without any robot gives NaN. Used by the analysis node (one snapshot), the viewer (every sample
of a recording) and the batch engine's blink order parameter (every step).
"""

from __future__ import annotations

import numpy as np

from .constants import LED_BLUE, LED_RED

#: The metrics of a swarm snapshot, by name (also the analysis node's topic names).
METRICS = ("led_red_fraction", "led_blue_fraction", "order_parameter", "mean_distance_to_light_m", "covered_area_m2")


def _mean_over_robots(a: np.ndarray, known: np.ndarray) -> np.ndarray:
    n = known.sum(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, np.where(known, a, 0.0).sum(axis=-1) / np.maximum(n, 1), np.nan)


def led_fraction(led, code: int) -> np.ndarray:
    """Fraction of the robots with a known LED that show ``code`` (LED_RED, LED_BLUE)."""
    led = np.asarray(led, dtype=np.float64)
    return _mean_over_robots((led == code).astype(np.float64), np.isfinite(led))


def mean_distance(x, y, center) -> np.ndarray:
    """Mean distance (m) of the robots to ``center`` (x_m, y_m), e.g. the light centre."""
    d = np.hypot(np.asarray(x, dtype=np.float64) - center[0], np.asarray(y, dtype=np.float64) - center[1])
    return _mean_over_robots(d, np.isfinite(d))


def order_parameter(ticks, period_ticks: float) -> np.ndarray:
    """Kuramoto order parameter ``|mean exp(i 2 pi ticks / period)|`` of the robots' blink phases."""
    ticks = np.asarray(ticks, dtype=np.float64)
    known = np.isfinite(ticks)
    z = np.exp(1j * (2 * np.pi / period_ticks) * np.where(known, ticks, 0.0))
    n = known.sum(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, np.abs(np.where(known, z, 0).sum(axis=-1)) / np.maximum(n, 1), np.nan)


def swarm_metrics(x, y, led, ticks, light_center, period_ticks: float | None, covered_area_m2=np.nan) -> dict:
    """Every metric of :data:`METRICS` (arrays (..., N) -> (...)); ``order_parameter`` is NaN
    without a blink program (``period_ticks`` None); ``covered_area_m2`` is passed through."""
    x = np.asarray(x, dtype=np.float64)
    nan = np.full(x.shape[:-1], np.nan)
    return {
        "led_red_fraction": led_fraction(led, LED_RED),
        "led_blue_fraction": led_fraction(led, LED_BLUE),
        "order_parameter": order_parameter(ticks, period_ticks) if period_ticks else nan,
        "mean_distance_to_light_m": mean_distance(x, y, light_center),
        "covered_area_m2": np.broadcast_to(np.asarray(covered_area_m2, dtype=np.float64), nan.shape).copy(),
    }
