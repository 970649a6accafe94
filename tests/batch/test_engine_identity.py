"""The compiled batch engine gives the core's arrays bit for bit.

The expected arrays come from a second implementation: the pure-NumPy core
(:func:`kilobot_twin.core.sim.simulate` over the whole batch, and :func:`~kilobot_twin.core.sim.step`
on a (1, 1) state, the path a ROS robot node takes). Every behaviour the kernel runs is covered,
with every noise source, individual clock rates, trials (bias drift and jitter), walls and
coverage, a tilted floor, the sensor's soft knee and the three light fields it knows.
"""

import numpy as np
import pytest

from kilobot_twin.batch import Campaign, engine, run_campaign
from kilobot_twin.batch import campaign as campaign_mod
from kilobot_twin.batch import kernel
from kilobot_twin.core import sim
from kilobot_twin.core.scenario import scenario_from_dict
from kilobot_twin.core.traits import draw_population

pytestmark = pytest.mark.skipif(not kernel.AVAILABLE or not kernel.math_matches_numpy(),
                                reason="no Numba, or NumPy's elementary functions differ from the C library's here")

# Every trait that draws or scales something, different per robot.
POP = {"heading_bias": {"dist": "uniform", "low": -0.04, "high": 0.04}, "wheel_noise": 0.3,
       "sigma_omega": 0.05, "sigma_v": 0.001, "sensor_noise": 5.0,
       "sensor_gain": {"dist": "normal", "mean": 1, "sd": 0.05}, "sensor_offset": {"dist": "normal", "mean": 0, "sd": 10},
       "clock_rate": {"dist": "normal", "mean": 1, "sd": 0.02}, "clock_trial_sd": 0.01, "bias_trial_sd": 0.005,
       "bias_drift": 0.001, "speed_factor": {"dist": "normal", "mean": 1, "sd": 0.03},
       "heading_noise_tau": {"dist": "uniform", "low": 0.0, "high": 2.0},
       "sensor_offset_trial_sd": {"dist": "uniform", "low": 0.0, "high": 20.0}}
BIAS = {"heading_bias": {"dist": "uniform", "low": -0.04, "high": 0.04}}

SCENARIOS = {
    "straight_gaussian": ({"preset": "paper", "behavior": "straight", "duration_s": 40}, {**BIAS, "sigma_omega": 0.05, "sigma_v": 0.001}),
    "straight_wheel": ({"preset": "argos-code", "behavior": "straight", "duration_s": 40}, {**BIAS, "wheel_noise": 0.5}),
    "straight_everything": ({"behavior": "straight", "duration_s": 30, "dt_s": 0.05}, POP),
    "straight_some_noiseless": ({"behavior": "straight", "duration_s": 20}, {"sigma_omega": {"dist": "uniform", "low": 0, "high": 0.1}}),
    # White and coloured turn-rate noise side by side (tau 0 for about half the robots).
    "straight_coloured": ({"behavior": "straight", "duration_s": 20},
                          {**BIAS, "sigma_omega": 0.05, "heading_noise_tau": {"dist": "list", "values": [0.0, 0.3, 0.0, 2.0, 0.0, 1.0, 5.0]}}),
    "random_walk_walls": ({"behavior": "random_walk", "duration_s": 60, "arena": {"walls": True, "width_m": 1.0, "height_m": 1.0},
                           "start": {"kind": "uniform", "half_width_m": 0.4, "heading_rad": None}}, POP),
    "random_walk_durations": ({"behavior": {"kind": "random_walk", "p_forward": 0.7, "forward_min_s": 0.5, "forward_max_s": 3.0,
                                            "turn_min_s": 0.2, "turn_max_s": 1.5}, "duration_s": 60, "tick_hz": 31,
                               "start": {"kind": "grid", "columns": 3}}, POP),
    "phototaxis": ({"preset": "paper", "duration_s": 120}, POP),
    "phototaxis_gaussian_walls_tilt_knee": (
        {"behavior": {"kind": "phototaxis", "p_right": 0.3, "reference": 900}, "duration_s": 120,
         "arena": {"walls": True, "width_m": 2.0, "height_m": 2.0}, "light": {"kind": "gaussian", "sigma_m": 0.6},
         "start": {"kind": "uniform", "half_width_m": 0.8, "heading_rad": None},
         "floor_tilt": 0.2, "floor_tilt_direction_rad": 0.7, "sensor": {"knee": 6.0}}, POP),
    "phototaxis_arrives": ({"behavior": {"kind": "phototaxis", "reference": 1000, "arrive_tolerance": 30}, "tick_hz": 31,
                            "dt_s": 0.03, "duration_s": 30, "start": {"kind": "uniform", "half_width_m": 0.3, "heading_rad": None}}, POP),
    "phototaxis_argos": ({"preset": "argos-code", "duration_s": 120}, POP),
    # Robots in the dark read a constant; a negative threshold makes every cycle a hold, so
    # the controllers' ties (d_new == d_old, diff == 0) happen all the time.
    "phototaxis_ties": ({"behavior": {"kind": "phototaxis", "change_threshold": -1}, "duration_s": 60,
                         "light": {"kind": "cone", "radius_m": 0.5}, "start": {"kind": "uniform", "half_width_m": 1.0}}, BIAS),
    "phototaxis_argos_ties": ({"behavior": {"kind": "phototaxis_argos", "reference": 0, "change_threshold": -1}, "duration_s": 60,
                               "light": {"kind": "cone", "radius_m": 0.5}, "start": {"kind": "uniform", "half_width_m": 1.0}}, BIAS),
    "phototaxis_argos_plain": ({"preset": "argos-code", "duration_s": 200}, {**BIAS, "wheel_noise": 0.5}),
    "still_sweep": ({"behavior": "still", "duration_s": 100, "light": {"kind": "sweep", "period_s": 20, "ramps": 3, "start_s": 10}}, POP),
}
N = 7
RUNS = np.arange(3, 7)
TRIALS = np.array([0, 1, 2, 5])


def _pair(name):
    doc, pop = SCENARIOS[name]
    return scenario_from_dict(doc), draw_population({"n": N, **pop}, seed=3)


def _assert_same(a: sim.Result, b: sim.Result):
    assert sorted(a.summary) == sorted(b.summary)
    for k in a.summary:
        assert a.summary[k].dtype == b.summary[k].dtype, k
        assert np.array_equal(a.summary[k], b.summary[k]), k
    assert (a.traj is None) == (b.traj is None)
    if a.traj is not None:
        assert sorted(a.traj) == sorted(b.traj)
        for k in a.traj:
            assert a.traj[k].dtype == b.traj[k].dtype, k
            assert np.array_equal(a.traj[k], b.traj[k]), k
        assert np.array_equal(a.t_s, b.t_s)


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_kernel_equals_core_bit_for_bit(name):
    sc, sw = _pair(name)
    assert engine.compiled(sc)
    fast = engine.simulate(sc, sw, 17, runs=RUNS, trials=TRIALS, record_every=1)
    core = sim.simulate(sc, sw, 17, runs=RUNS, trials=TRIALS, record_every=1)
    _assert_same(fast, core)
    # Summaries only, other runs and seed, progress reported in chunks.
    done = []
    fast = engine.simulate(sc, sw, 18, runs=[0, 9], progress=done.append)
    assert sum(done) == sc.n_steps
    _assert_same(fast, sim.simulate(sc, sw, 18, runs=[0, 9]))


@pytest.mark.parametrize("name", ["straight_gaussian", "phototaxis_argos", "random_walk_walls"])
def test_kernel_on_threads_equals_the_core(name):
    """Slots shared over three threads (the gap workflow's simulations): the core's arrays."""
    sc, sw = _pair(name)
    runs = np.arange(40)
    fast = engine.simulate(sc, sw, 5, runs=runs, trials=runs % 3, record_every=1, threads=3)
    _assert_same(fast, sim.simulate(sc, sw, 5, runs=runs, trials=runs % 3, record_every=1))


@pytest.mark.parametrize("channels", [("x", "y"), ("reading",), ("y", "theta", "motion"), ("led",)])
def test_kept_channels_are_the_full_recording(channels):
    """Recording fewer trajectories (the gap workflow keeps positions only) keeps exactly those,
    equal to the full recording's, and in the core and the kernel alike."""
    sc, sw = _pair("phototaxis")
    full = sim.simulate(sc, sw, 17, runs=RUNS, trials=TRIALS, record_every=3)
    for res in (engine.simulate(sc, sw, 17, runs=RUNS, trials=TRIALS, record_every=3, channels=channels, threads=2),
                sim.simulate(sc, sw, 17, runs=RUNS, trials=TRIALS, record_every=3, channels=channels)):
        assert sorted(res.traj) == sorted(channels)
        for k in channels:
            assert res.traj[k].dtype == full.traj[k].dtype and np.array_equal(res.traj[k], full.traj[k]), k
        assert np.array_equal(res.t_s, full.t_s)
        for k in full.summary:
            assert np.array_equal(res.summary[k], full.summary[k]), k


@pytest.mark.parametrize("channels", [(), ("x", "heading")])
def test_unknown_channels_are_refused(channels):
    sc, sw = _pair("straight_gaussian")
    with pytest.raises(ValueError, match="channels"):
        engine.simulate(sc, sw, 1, runs=[0], record_every=1, channels=channels)


def test_every_compiled_loop_is_compared_with_the_core(monkeypatch):
    """Each specialisation of the kernel's loop runs in at least one scenario above."""
    used = {}
    real = kernel.variant
    for name in SCENARIOS:
        monkeypatch.setattr(kernel, "variant", lambda ip, name=name: used.setdefault(name, real(ip)))
        sc, sw = _pair(name)
        engine.simulate(sc, sw, 17, runs=[0])
    assert set(used.values()) == set(kernel.LOOPS)
    assert used["straight_gaussian"] == "straight_gaussian"  # the paper's Monte Carlo case


def test_the_scenarios_exercise_the_controllers():
    """Guard against a vacuous comparison: turns, holds, arrivals and walls do happen."""
    sc, sw = _pair("phototaxis")
    m = engine.simulate(sc, sw, 17, runs=RUNS, record_every=1).traj["motion"]
    assert {0, 1, 2, 3} <= set(np.unique(m))
    sc, sw = _pair("phototaxis_arrives")
    t = engine.simulate(sc, sw, 17, runs=RUNS, record_every=1).traj
    arrived = np.abs(t["reading"] - 1000) <= 30
    assert arrived.mean() > 0.05 and np.all(t["motion"][arrived] == 0)
    sc, sw = _pair("random_walk_walls")
    res = engine.simulate(sc, sw, 17, runs=RUNS, record_every=1)
    assert np.abs(res.traj["x"]).max() == 0.5 - 0.0165  # robots slide along the walls
    assert res.summary["coverage_m2"].min() > 0


@pytest.mark.parametrize("name", ["phototaxis", "phototaxis_argos", "random_walk_walls"])
def test_single_robot_stepping_equals_the_kernel_batch(name):
    """A robot stepped alone by core.sim.step (as a ROS node steps it) follows the kernel's batch trajectory."""
    sc, sw = _pair(name)
    batch = engine.simulate(sc, sw, 9, runs=[2, 4], trials=[1, 3], record_every=1)
    table = sc.motors.wheel_table_m_s()
    for r, (run, trial), i in ((0, (2, 1), 0), (1, (4, 3), 6)):
        st = sim.init_state(sc, sw, 9, runs=[run], trials=[trial], robot_index=[i])
        for k in range(sc.n_steps):
            sim.step(st, sc, table)
            assert st.x[0, 0] == batch.traj["x"][r, i, k + 1], (run, i, k)
            assert st.theta[0, 0] == batch.traj["theta"][r, i, k + 1], (run, i, k)
            assert st.reading[0, 0] == batch.traj["reading"][r, i, k + 1], (run, i, k)


def test_campaign_on_threads_equals_the_core_on_processes(tmp_path, monkeypatch):
    """Thread pool + kernel (today's default) == process pool + core (the engine before it)."""
    sc = scenario_from_dict({"preset": "paper", "duration_s": 60})
    sw = draw_population({"n": 5, **POP}, seed=4)
    c = Campaign(sc, sw, seed=8, runs=5, grid={"behavior.p_right": [0.25, 1.0], "light.radius_m": [2.0, 2.83]},
                 record_every=5, trials_from_runs=True)
    fast = run_campaign(c, out=tmp_path / "fast.npz", workers=2, progress=False)
    monkeypatch.setattr(engine, "compiled", lambda scenario: False)
    core = run_campaign(c, out=tmp_path / "core.npz", workers=2, progress=False)
    for k, v in core["summary"].items():
        assert np.array_equal(v, fast["summary"][k]), k
    shards = sorted(p.name for p in (tmp_path / "core_traj").iterdir())
    assert shards == sorted(p.name for p in (tmp_path / "fast_traj").iterdir()) and shards
    for name in shards:
        with np.load(tmp_path / "core_traj" / name) as a, np.load(tmp_path / "fast_traj" / name) as b:
            assert a.files == b.files
            for k in a.files:
                assert np.array_equal(a[k], b[k]), (name, k)


def test_campaign_chooses_threads_for_the_kernel(monkeypatch):
    """The kernel's tasks run on threads (no process start), the core's on processes."""
    used = []
    real_threads, real_procs = campaign_mod.ThreadPoolExecutor, campaign_mod.ProcessPoolExecutor
    monkeypatch.setattr(campaign_mod, "ThreadPoolExecutor", lambda *a, **k: used.append("threads") or real_threads(*a, **k))
    monkeypatch.setattr(campaign_mod, "ProcessPoolExecutor", lambda *a, **k: used.append("processes") or real_procs(*a, **k))
    sw = draw_population({"n": 3}, seed=1)
    run_campaign(Campaign(scenario_from_dict({"behavior": "straight", "duration_s": 5}), sw, runs=4), workers=2, progress=False)
    run_campaign(Campaign(scenario_from_dict({"behavior": "blink", "duration_s": 5}), sw, runs=4), workers=2, progress=False)
    assert used == ["threads", "processes"]
