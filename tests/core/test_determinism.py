"""Same seed -> same output; a robot alone == in a batch == in a split batch."""

import numpy as np
import pytest

from kilobot_twin.batch import Campaign, run_campaign
from kilobot_twin.core import sim
from kilobot_twin.core.scenario import scenario_from_dict
from kilobot_twin.core.traits import draw_population

SCENARIOS = {
    "straight": {"preset": "paper", "behavior": "straight", "duration_s": 30},
    "phototaxis": {"preset": "argos-code", "duration_s": 60, "behavior": {"kind": "phototaxis", "p_right": 0.5, "reference": 2000}},
    "random_walk": {"behavior": "random_walk", "duration_s": 60, "arena": {"walls": True, "width_m": 1.0, "height_m": 1.0},
                    "start": {"kind": "uniform", "half_width_m": 0.4, "heading_rad": None}},
}
POP = {"n": 12, "heading_bias": {"dist": "uniform", "low": -0.04, "high": 0.04}, "wheel_noise": 0.3,
       "sigma_omega": 0.05, "sigma_v": 0.001, "sensor_noise": 5.0, "clock_rate": {"dist": "normal", "mean": 1, "sd": 0.02},
       "bias_trial_sd": 0.005}


@pytest.fixture(scope="module")
def swarm():
    return draw_population(POP, seed=11)


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_same_seed_same_output_and_different_seed_differs(name, swarm):
    sc = scenario_from_dict(SCENARIOS[name])
    a = sim.simulate(sc, swarm, seed=5, runs=[0, 1, 2], record_every=7)
    b = sim.simulate(sc, swarm, seed=5, runs=[0, 1, 2], record_every=7)
    c = sim.simulate(sc, swarm, seed=6, runs=[0, 1, 2], record_every=7)
    for k in ("x", "y", "theta", "motion"):
        assert np.array_equal(a.traj[k], b.traj[k])
    assert not np.array_equal(a.traj["x"], c.traj["x"])


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_robot_alone_equals_robot_in_batch(name, swarm):
    sc = scenario_from_dict(SCENARIOS[name])
    batch = sim.simulate(sc, swarm, seed=3, runs=np.arange(4), record_every=1)
    for run in (0, 3):
        for i in (0, 5, 11):
            alone = sim.simulate(sc, swarm, seed=3, runs=[run], robot_index=[i], record_every=1)
            for k in ("x", "y", "theta", "reading", "motion"):
                assert np.array_equal(alone.traj[k][0, 0], batch.traj[k][run, i]), (k, run, i)


def test_step_function_single_robot_matches_batch(swarm):
    """Stepping a (1, 1) state by hand (as a ROS node does) gives the batch trajectory."""
    sc = scenario_from_dict(SCENARIOS["phototaxis"])
    batch = sim.simulate(sc, swarm, seed=9, runs=[2], record_every=1)
    st = sim.init_state(sc, swarm, 9, runs=[2], robot_index=[7])
    table = sc.motors.wheel_table_m_s()
    for k in range(sc.n_steps):
        sim.step(st, sc, table)
        assert st.x[0, 0] == batch.traj["x"][0, 7, k + 1]
        assert st.theta[0, 0] == batch.traj["theta"][0, 7, k + 1]


def test_split_campaign_equals_single_process(swarm):
    sc = scenario_from_dict(SCENARIOS["phototaxis"])
    grid = {"behavior.p_right": [0.25, 1.0]}
    one = run_campaign(Campaign(sc, swarm, seed=4, runs=6, grid=grid), workers=1, progress=False)
    two = run_campaign(Campaign(sc, swarm, seed=4, runs=6, grid=grid), workers=2, progress=False)
    for k, v in one["summary"].items():
        assert np.array_equal(v, two["summary"][k]), k
    # And each run equals a direct simulation of that run alone.
    sc_p = sc.replace(behavior=sc.behavior.__class__(p_right=1.0, reference=2000.0))
    direct = sim.simulate(sc_p, swarm, seed=4, runs=[5])
    assert np.array_equal(direct.summary["cost_m"][0], one["summary"]["cost_m"][1, 5])


def test_trial_bias_drift_and_jitter(swarm):
    """bias in trial k = heading_bias + k * bias_drift + a per-(trial, robot) jitter."""
    tr = swarm.with_values(bias_drift=0.01, bias_trial_sd=0.0)
    sc = scenario_from_dict(SCENARIOS["straight"])
    st = sim.init_state(sc, tr, 0, runs=[0, 1, 2], trials=[0, 1, 5])
    np.testing.assert_allclose(st.bias[2] - st.bias[0], 0.05)
    st2 = sim.init_state(sc, swarm, 0, runs=np.arange(2000), robot_index=[0])
    jitter = st2.bias[:, 0] - swarm.heading_bias[0]
    # sd estimate within 4 standard errors (relative SE of an sd ~ 1/sqrt(2(n-1))).
    assert abs(jitter.std(ddof=1) / 0.005 - 1) < 4 / np.sqrt(2 * 1999)


def test_grid_start_of_a_robot_does_not_depend_on_the_batch():
    sc = scenario_from_dict({"behavior": "blink", "start": {"kind": "grid", "spacing_m": 0.06, "columns": 7}})
    x, y, _ = sim.start_poses(sc, 0, [0], np.arange(49))
    for rid in (0, 24, 48):
        xa, ya, _ = sim.start_poses(sc, 0, [0], [rid])
        assert (xa[0, 0], ya[0, 0]) == (x[0, rid], y[0, rid])
    # The 7x7 lattice is centred: robot 24 sits at the origin.
    assert x[0, 24] == 0 and y[0, 24] == 0


def test_counters_given_as_an_array_draw_what_one_call_per_counter_draws():
    """``rng.normal_pair`` / ``rng.uniform`` with an array of counters (broadcast against the
    keys) must give, draw for draw, the values of one call per counter, up to counters past 2^32
    (the uint64 product wraps mod 2^64 as the Python ints' product is reduced)."""
    from kilobot_twin.core import rng

    keys = rng.robot_keys(5, np.arange(3), np.arange(4), rng.SENSOR)[..., None]  # (3, 4, 1)
    counters = np.array([0, 1, 7, 1000, 2**33 + 5])
    z1, z2 = rng.normal_pair(keys, counters)
    u = rng.uniform(keys, counters)
    for j, c in enumerate(counters):
        a, b = rng.normal_pair(keys[..., 0], int(c))
        assert np.array_equal(z1[..., j], a) and np.array_equal(z2[..., j], b)
        assert np.array_equal(u[..., j], rng.uniform(keys[..., 0], int(c)))
        # the one-normal draw (the light sensor's) is the pair's first, bit for bit
        assert np.array_equal(rng.normal(keys[..., 0], int(c)), a)
    assert np.array_equal(rng.normal(keys, counters), z1)
