"""Clock individuality: switch counts scale with clock_rate; Kuramoto coupling."""

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
