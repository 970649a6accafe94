"""Checks of the core against expectations computed here, not by the code under test.

Each catches a deliberate bug that the suite once let through (issue 13): random streams keyed by
``run + robot`` instead of the pair, and the phototaxis cost measured to the origin instead of the
light centre.
"""

import numpy as np

from kilobot_twin.core import rng, sim
from kilobot_twin.core.scenario import scenario_from_dict
from kilobot_twin.core.traits import SwarmTraits, RobotTraits


def test_every_run_robot_pair_has_its_own_stream():
    """(run r, robot i+1) and (run r+1, robot i) must not share random numbers."""
    for purpose in (rng.MOTION, rng.WHEEL, rng.SENSOR, rng.BEHAVIOR, rng.TRIAL):
        keys = rng.robot_keys(7, np.arange(6), np.arange(6), purpose)
        assert len(np.unique(keys)) == keys.size, purpose
    # The same at the level of trajectories: identical robots, noisy motion, one batch.
    sc = scenario_from_dict({"behavior": "straight", "duration_s": 5.0, "start": {"kind": "origin", "heading_rad": 0.0}})
    traits = SwarmTraits.from_robots([RobotTraits(sigma_omega=0.05, sigma_v=0.001)] * 4, ids=[0, 1, 2, 3])
    res = sim.simulate(sc, traits, seed=3, runs=[0, 1, 2, 3])
    theta = res.summary["theta"]  # (run, robot)
    for r in range(3):
        for i in range(3):
            assert theta[r, i + 1] != theta[r + 1, i], (r, i)


def test_phototaxis_cost_is_the_mean_distance_to_the_light_centre():
    """Cost (README: mean distance to the light centre over the last cost_window_steps steps),
    recomputed from the recorded trajectory with the centre written here, off the origin."""
    centre = (0.4, -0.3)
    sc = scenario_from_dict({"behavior": {"kind": "phototaxis"}, "duration_s": 20.0, "cost_window_steps": 50,
                             "light": {"kind": "cone", "center": list(centre), "radius_m": 2.8284, "peak": 1024.0},
                             "start": {"kind": "uniform", "half_width_m": 0.5, "heading_rad": None, "shared": False}})
    traits = SwarmTraits.from_robots([RobotTraits(heading_bias=b) for b in (-0.02, 0.0, 0.03)], ids=[0, 1, 2])
    res = sim.simulate(sc, traits, seed=5, runs=[0, 1], record_every=1)
    x, y = res.traj["x"], res.traj["y"]  # (run, robot, T), T = steps + 1 (the start included)
    want = np.hypot(x[..., -50:] - centre[0], y[..., -50:] - centre[1]).mean(axis=-1)
    np.testing.assert_allclose(res.summary["cost_m"], want, rtol=1e-12)
    assert np.all(np.abs(want - np.hypot(x[..., -50:], y[..., -50:]).mean(axis=-1)) > 1e-3)  # origin differs
