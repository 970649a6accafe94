"""Clock individuality: switch counts scale with clock_rate; Kuramoto coupling."""

import math

import numpy as np
import pytest

from kilobot_twin.core import sim
from kilobot_twin.core.behaviors import Blink
from kilobot_twin.core.scenario import Scenario, StartSpec
from kilobot_twin.core.traits import SwarmTraits


def test_switch_counts_scale_with_clock_rate():
    """A clock at 31 Hz * c toggles every 30 ticks: floor(31 c T / 30) switches in T seconds."""
    rates = np.array([0.95, 0.98, 1.0, 1.01, 1.03, 1.05])
    T = 180.0
    sc = Scenario(behavior=Blink(half_period_ticks=30), dt_s=0.01, duration_s=T, start=StartSpec(kind="grid"))
    res = sim.simulate(sc, SwarmTraits.uniform(len(rates)).with_values(clock_rate=rates), seed=0)
    predicted = np.floor(31.0 * rates * T / 30)
    assert np.array_equal(res.summary["switches"][0], predicted)


def test_uncoupled_blinkers_drift_apart_and_coupled_ones_synchronise():
    rates = 1 + 0.015 * np.random.default_rng(0).standard_normal(49)
    traits = SwarmTraits.uniform(49).with_values(clock_rate=rates)
    base = Scenario(behavior=Blink(), dt_s=0.1, duration_s=600.0,
                    start=StartSpec(kind="grid", spacing_m=0.06, columns=7), neighbour_radius_m=0.1)
    free = sim.simulate(base, traits, seed=0)
    coupled = sim.simulate(base.replace(coupling_per_s=1.0), traits, seed=0)
    # Started in sync, free clocks dephase (order parameter well below 1 at the end) ...
    assert free.order[0, 0] == pytest.approx(1.0)
    assert free.order[0, -600:].mean() < 0.6
    # ... while coupled ones stay locked.
    assert coupled.order[0, -600:].mean() > 0.95


def test_kuramoto_correction_is_the_mean_sine_pull_of_each_robot_s_neighbours():
    """Against the update written out pair by pair: dphi_i = k dt mean_{j in N(i)} sin(phi_j - phi_i).

    Clocks that have run for a long time (1e6 ticks) are included: the pull depends on phases,
    not on how many ticks have passed. A robot with no neighbours gets no correction.
    """
    from kilobot_twin.core import clocks

    rng = np.random.default_rng(3)
    period, k, dt = 60.0, 2.0, 1 / 31
    ticks = rng.uniform(0, 1e6, (2, 9))
    adjacency = rng.random((2, 9, 9)) < 0.4
    adjacency = adjacency & adjacency.transpose(0, 2, 1)
    adjacency[:, np.arange(9), np.arange(9)] = False
    adjacency[:, 4, :] = adjacency[:, :, 4] = False  # robot 4 alone
    got = clocks.kuramoto_correction(ticks, adjacency, k, period, dt)
    want = np.zeros_like(ticks)
    for r in range(2):
        for i in range(9):
            pulls = [math.sin(2 * math.pi * (math.fmod(ticks[r, j], period) - math.fmod(ticks[r, i], period)) / period)
                     for j in range(9) if adjacency[r, i, j]]
            if pulls:
                want[r, i] = k * dt * sum(pulls) / len(pulls) * period / (2 * math.pi)
    assert np.all(want[:, 4] == 0) and np.all(got[:, 4] == 0)
    assert np.abs(want).max() > 0.05  # the pulls are not all negligible
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
