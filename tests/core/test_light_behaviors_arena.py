"""Light fields, the sensor, behaviours and the arena against their definitions."""

import numpy as np
import pytest

from kilobot_twin.core import light, sim
from kilobot_twin.core.arena import Arena
from kilobot_twin.core.behaviors import RandomWalk, Straight, ms_to_ticks
from kilobot_twin.core.constants import FORWARD, STOP, TURN_LEFT, TURN_RIGHT
from kilobot_twin.core.scenario import Scenario, StartSpec, scenario_from_dict
from kilobot_twin.core.traits import SwarmTraits
from kilobot_twin.errors import ConfigError


def test_cone_field_matches_authors_formula():
    f = light.ConeField(radius_m=0.7071 * 4)
    r = np.array([0.0, 1.0, 2.0, 2.8284, 3.5])
    expected = np.clip(1024 * (1 - r / (0.7071 * 4)), 0, 1024)
    np.testing.assert_allclose(f.intensity(r, 0 * r), expected)
    np.testing.assert_allclose(f.intensity(0 * r, r), expected)  # radially symmetric


def test_gaussian_and_sweep_fields():
    g = light.GaussianField(sigma_m=0.5)
    assert g.intensity(0.5, 0.0) == pytest.approx(1024 * np.exp(-0.5))
    s = light.UniformSweepField(period_s=10, ramps=4)
    t = np.array([0, 2.5, 9.99, 10, 39.99, 40, 50])
    np.testing.assert_allclose(s.v_value(t), [0, 0.25, 0.999, 0, 0.999, 0, 0], atol=1e-9)
    assert s.intensity(np.zeros(3), np.zeros(3), 5.0).tolist() == [512.0] * 3


def test_image_field_interpolates_and_orients_like_a_picture():
    img = np.zeros((2, 2))
    img[0, 1] = 1.0  # top-right pixel bright
    f = light.ImageField(img, extent_m=(-1, 1, -1, 1), peak=100.0)
    assert f.intensity(0.5, 0.5) == pytest.approx(100.0)   # top right
    assert f.intensity(-0.5, -0.5) == pytest.approx(0.0)   # bottom left
    assert f.intensity(0.0, 0.5) == pytest.approx(50.0)    # halfway along the top row
    assert f.intensity(2.0, 0.0) == 0.0                    # outside


def test_sensor_gain_offset_saturation_and_noise():
    I = np.array([0.0, 100.0, 400.0, 1000.0])
    y = light.sensor_response(I, gain=2.0, offset=5.0)
    np.testing.assert_allclose(y, [5, 205, 805, 1023])
    soft = light.sensor_response(I, 2.0, 5.0, light.SensorModel(knee=6))
    assert np.all(np.diff(soft) > 0) and soft[-1] < 1023 and soft[1] == pytest.approx(205, rel=0.01)
    # Averaging 10 samples: reading sd = noise / sqrt(10).
    from kilobot_twin.core import rng

    keys = rng.robot_keys(0, np.arange(20000), [0], rng.SENSOR)
    r = light.sense(np.full((20000, 1), 300.0), 1.0, 0.0, 30.0, keys, 1)
    assert abs(r.std() / (30 / np.sqrt(10)) - 1) < 4 * np.sqrt(1 / (2 * 20000)) + 0.01  # + floor()
    assert np.all(r == np.floor(r))


def test_sensor_offset_trial_jitter_is_fixed_within_a_trial_and_spread_across_trials():
    """Trait ``sensor_offset_trial_sd``: every run reads with its own offset, N(offset, sd^2),
    the same all trial long; other robots' streams are not moved by it. Expected values from
    theory: a noiseless sensor in a constant field reads floor(offset + z sd + gain I)."""
    sc = scenario_from_dict({"behavior": "phototaxis", "duration_s": 3, "light": {"kind": "sweep", "period_s": 1e6},
                             "start": {"kind": "origin"}})
    sc = sc.replace(light=light.UniformSweepField(period_s=1e6, ramps=1, peak=0.0))  # a dark screen: I = 0
    R, sd = 4000, 30.0
    sw = SwarmTraits.uniform(2).with_values(sensor_offset=np.array([100.0, 100.0]),
                                            sensor_offset_trial_sd=np.array([sd, 0.0]))
    res = sim.simulate(sc, sw, seed=5, runs=np.arange(R), record_every=1, channels=("reading",))
    r = res.traj["reading"]  # (R, 2, T)
    assert np.all(r == r[..., :1])  # fixed within a trial
    first = r[:, 0, 0]
    # floor() of N(100, sd^2): mean 99.5, variance sd^2 + 1/12; the sample sd's se is sd / sqrt(2R).
    assert abs(first.mean() - 99.5) < 4 * sd / np.sqrt(R)
    assert abs(first.std(ddof=1) / np.sqrt(sd**2 + 1 / 12) - 1) < 4 / np.sqrt(2 * R)
    assert np.all(r[:, 1] == 100.0)  # the robot without the trait reads its offset
    # The jitter is the trial's: a new trial (run) draws a new one, uncorrelated with the last.
    assert abs(np.corrcoef(first[:-1], first[1:])[0, 1]) < 4 / np.sqrt(R)


def test_bad_light_config():
    with pytest.raises(ConfigError, match="light.kind"):
        scenario_from_dict({"light": {"kind": "laser"}})
    with pytest.raises(ConfigError, match="light.sigma_m"):
        scenario_from_dict({"light": {"kind": "gaussian", "sigma_m": -1}})


@pytest.mark.parametrize("light, field", [
    ({"kind": "gaussian", "center": [float("nan"), 0.0]}, "light.center"),  # was taken
    ({"kind": "gaussian", "center": [0.0]}, "light.center"),  # was a traceback
    ({"kind": "gaussian", "center": "ab"}, "light.center"),  # was a traceback
    ({"kind": "image", "path": "image.npy", "extent_m": [1.0, -1.0, -1.0, 1.0]}, "light.extent_m"),
    ({"kind": "image", "path": "not_an_image.png"}, "light.path"),  # was Pillow's traceback
    ({"kind": "image", "path": "nan.npy"}, "light.path"),  # was taken
    ({"kind": "image", "path": "row.npy"}, "light.path"),  # one row of numbers: no image
])
def test_a_light_field_that_is_not_one_names_its_key(light, field, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    np.save("image.npy", np.array([[0.1, 0.5], [0.2, 0.3]]))
    np.save("nan.npy", np.array([[0.1, np.nan], [0.2, 0.3]]))
    np.save("row.npy", np.array([0.1, 0.2]))
    (tmp_path / "not_an_image.png").write_text("robots: {}\n")
    with pytest.raises(ConfigError) as e:
        scenario_from_dict({"light": light})
    assert str(e.value).startswith(field + ":") and "\n" not in str(e.value), e.value
    assert scenario_from_dict({"light": {"kind": "image", "path": "image.npy"}}).light.image.shape == (2, 2)


@pytest.mark.parametrize("key, value", [("cost_window_steps", 2.5), ("cost_window_steps", 0),
                                        ("coupling_per_s", float("inf")), ("floor_tilt", float("nan")),
                                        ("dt_s", float("nan"))])
def test_a_scenario_number_that_is_not_finite_or_not_whole_names_its_key(key, value):
    """A window of 2.5 steps was cut to 2 and one of 0 divided by zero; .inf and .nan were taken."""
    with pytest.raises(ConfigError) as e:
        scenario_from_dict({key: value})
    assert str(e.value).startswith(key + ":"), e.value


def test_ms_to_ticks_quantises_like_kilo_ticks():
    assert ms_to_ticks(2100, 10) == 21
    assert ms_to_ticks(50, 10) == 0  # the authors' delay(50) does nothing at 10 ticks/s
    assert ms_to_ticks(200, 31) == 6


def _photo(p_right=0.5, radius_m=0.7071, **kw):
    return scenario_from_dict({
        "behavior": {"kind": "phototaxis", "p_right": p_right, **kw}, "dt_s": 0.1, "duration_s": 600,
        "light": {"kind": "cone", "radius_m": radius_m},
        "start": {"kind": "uniform", "half_width_m": 0.4, "heading_rad": None},
    })


def test_phototaxis_climbs_the_gradient():
    """On the authors' cone (0 at 0.707 m) robots end nearer the light; with a flat field
    (nothing to climb) the same controller drifts away instead."""
    res = sim.simulate(_photo(reference=2000.0), SwarmTraits.uniform(40), seed=1, record_every=10)
    d = np.hypot(res.traj["x"][0], res.traj["y"][0])  # (robots, T)
    assert d[:, -100:].mean() < 0.7 * d[:, 0].mean()
    assert np.median(d[:, -100:].mean(axis=1)) < 0.25
    flat = _photo(reference=2000.0).replace(light=light.GaussianField(sigma_m=1000.0))
    res = sim.simulate(flat, SwarmTraits.uniform(40), seed=1, record_every=10)
    d = np.hypot(res.traj["x"][0], res.traj["y"][0])
    assert d[:, -100:].mean() > 2 * d[:, 0].mean()


@pytest.mark.parametrize("reference, stops", [(1023.0, True), (1021.0, True), (1030.0, False)])
def test_phototaxis_stops_within_two_counts_of_reference(reference, stops):
    """A near-flat field reads 1023 everywhere: the robot stops iff |1023 - reference| <= 2."""
    sc = _photo(reference=reference).replace(light=light.GaussianField(sigma_m=1000.0))
    res = sim.simulate(sc, SwarmTraits.uniform(3), seed=1, record_every=1)
    assert np.all(res.traj["reading"][0] == 1023)
    moving = res.traj["motion"][0, :, 1:] != STOP
    assert (not moving.any()) if stops else moving.all(axis=0).mean() > 0.5


@pytest.mark.parametrize("p_right, allowed", [(1.0, {TURN_RIGHT}), (0.0, {TURN_LEFT})])
def test_phototaxis_turn_direction_follows_p_right(p_right, allowed):
    res = sim.simulate(_photo(p_right, reference=2000.0), SwarmTraits.uniform(10), seed=2, record_every=1)
    turns = set(np.unique(res.traj["motion"])) & {TURN_LEFT, TURN_RIGHT}
    assert turns == allowed


def test_phototaxis_turn_fraction_matches_p_right():
    res = sim.simulate(_photo(0.25, reference=2000.0), SwarmTraits.uniform(60), seed=3, record_every=1)
    m = res.traj["motion"][0]
    starts = (m[:, 1:] != m[:, :-1]) & np.isin(m[:, 1:], [TURN_LEFT, TURN_RIGHT])
    right = (starts & (m[:, 1:] == TURN_RIGHT)).sum()
    n = starts.sum()
    assert n > 200
    assert abs(right / n - 0.25) < 4 * np.sqrt(0.25 * 0.75 / n)


def test_phototaxis_turn_lasts_21_ticks_at_10hz():
    sc = _photo(1.0, reference=2000.0).replace(tick_hz=10.0)
    res = sim.simulate(sc, SwarmTraits.uniform(5), seed=4, record_every=1)
    m = res.traj["motion"][0, 0]
    runs, count = [], 0
    for v in m:
        if v == TURN_RIGHT:
            count += 1
        elif count:
            runs.append(count)
            count = 0
    assert runs and set(runs) == {21}


def test_random_walk_alternates_and_walls_confine():
    arena = Arena(width_m=0.5, height_m=0.5, walls=True, coverage_cell_m=0.02)
    sc = Scenario(behavior=RandomWalk(), dt_s=0.1, duration_s=600, arena=arena,
                  start=StartSpec(kind="uniform", half_width_m=0.2, heading_rad=None))
    res = sim.simulate(sc, SwarmTraits.uniform(10), seed=5, record_every=1)
    lim = 0.25 - 0.0165 + 1e-12
    assert np.abs(res.traj["x"]).max() <= lim and np.abs(res.traj["y"]).max() <= lim
    assert {FORWARD, TURN_LEFT, TURN_RIGHT} <= set(np.unique(res.traj["motion"]))
    assert np.all(res.summary["coverage_m2"] > 0) and np.all(res.summary["coverage_m2"] <= 0.25)


def test_coverage_of_a_straight_line_counts_cells_crossed():
    arena = Arena(width_m=4, height_m=4, walls=True, coverage_cell_m=0.02)
    sc = Scenario(behavior=Straight(), dt_s=0.1, duration_s=100, arena=arena,
                  start=StartSpec(kind="origin", heading_rad=0.0))
    res = sim.simulate(sc, SwarmTraits.uniform(1), seed=0)
    length = sc.motors.forward_speed_m_s * 100
    cells = res.summary["coverage_m2"][0, 0] / 0.02**2
    assert cells == pytest.approx(np.floor(length / 0.02) + 1, abs=1)


def test_campaign_streams_trajectories(tmp_path):
    from kilobot_twin.batch import Campaign, run_campaign

    sc = Scenario(behavior=Straight(), dt_s=0.1, duration_s=10)
    c = Campaign(sc, SwarmTraits.uniform(3).with_values(heading_bias=[-0.02, 0, 0.02]), seed=1, runs=5, record_every=10)
    res = run_campaign(c, out=tmp_path / "r.npz", workers=2, progress=False)
    shards = sorted((tmp_path / "r_traj").glob("*.npz"))
    assert shards
    runs = np.concatenate([np.load(s)["runs"] for s in shards])
    assert sorted(runs.tolist()) == list(range(5))
    with np.load(shards[0]) as z:
        assert z["x"].shape[1:] == (3, 11)
        np.testing.assert_array_equal(z["x"][:, :, -1], res["summary"]["x"][0, z["runs"]])


def test_random_walk_choice_probabilities_and_durations():
    """Authors' walk: forward 2 s w.p. 0.5, else turn 1 s left/right 50/50 (at 10 ticks/s)."""
    sc = Scenario(behavior=RandomWalk(), dt_s=0.1, duration_s=2000, tick_hz=10.0)
    res = sim.simulate(sc, SwarmTraits.uniform(20), seed=8, record_every=1)
    m = res.traj["motion"][0, :, 1:]  # column 0 is the state before the first step
    counts = {FORWARD: 0, TURN_LEFT: 0, TURN_RIGHT: 0}
    for row in m:
        segments = np.split(row, np.flatnonzero(np.diff(row)) + 1)
        for j, seg in enumerate(segments):
            per = 20 if seg[0] == FORWARD else 10  # steps per decision
            n, rem = divmod(len(seg), per)
            # A run of one motion is a whole number of decisions (the last may be cut short).
            assert rem == 0 or j == len(segments) - 1
            counts[int(seg[0])] += n
    total = sum(counts.values())
    for k, p in ((FORWARD, 0.5), (TURN_LEFT, 0.25), (TURN_RIGHT, 0.25)):
        assert abs(counts[k] / total - p) < 4 * np.sqrt(p * (1 - p) / total)


def test_preset_override_with_another_kind_replaces_instead_of_merging():
    sc = scenario_from_dict({"preset": "argos-code", "behavior": "straight",
                             "light": {"kind": "sweep", "period_s": 10}})
    assert sc.behavior.name == "straight" and sc.light.kind == "sweep"
    same = scenario_from_dict({"preset": "argos-code", "behavior": {"kind": "phototaxis_argos", "p_right": 1.0}})
    assert same.behavior.reference == 2000.0 and same.behavior.p_right == 1.0  # merged


def test_phototaxis_argos_follows_the_authors_loop_tick_by_tick():
    """setup delay(1000) = 10 steps standing still; the first decision is always a turn
    (last_dist starts at 0); a turn is 21 steps; the forward after it 15 steps (1400 ms + return)."""
    sc = scenario_from_dict({"preset": "argos-code", "behavior": {"kind": "phototaxis_argos", "p_right": 1.0},
                             "duration_s": 300})
    res = sim.simulate(sc, SwarmTraits.uniform(4), seed=1, record_every=1)
    m = res.traj["motion"][0, :, 1:]
    # The clock ticks before each decision, so the 10-tick setup fills steps 0-8; then the
    # hold (2 steps, motors still off) and the stop (1 step): the turn starts at step 12.
    assert np.all(m[:, :12] == STOP)
    assert np.all(m[:, 12:33] == TURN_RIGHT)            # 2.1 s = 21 steps
    assert np.all(m[:, 33:48] == FORWARD)               # delay(1400) + loop return = 15 steps
    assert not np.isin(m, [TURN_LEFT]).any()            # p_right = 1


def test_phototaxis_argos_delay_rules():
    from kilobot_twin.core.behaviors import delay_ticks

    assert delay_ticks(50, 10) == 0      # shorter than a tick: no-op
    assert delay_ticks(100, 10) == 1
    assert delay_ticks(2000, 10) == 20
    assert delay_ticks(150, 10) == 2     # countdown runs until <= one tick


def test_image_field_survives_the_world_document(tmp_path, monkeypatch):
    """Robot nodes rebuild the scenario from the world's JSON document: an image field travels
    by its (absolute) path, relative paths are read next to the scenario file."""
    from kilobot_twin.core.scenario import scenario_from_dict
    from kilobot_twin.core.traits import load_yaml
    from kilobot_twin.errors import ConfigError
    from kilobot_twin.core.scenarios import parse_world_document, scenario_from_document, world_document

    img = np.random.default_rng(0).random((8, 12))
    (tmp_path / "fields").mkdir()
    np.save(tmp_path / "fields" / "spot.npy", img)
    (tmp_path / "sc.yaml").write_text("light: {kind: image, path: fields/spot.npy, extent_m: [-1, 1, -1, 1]}\n")
    monkeypatch.chdir("/")  # the path is relative to the scenario file, not the working directory
    sc = scenario_from_dict(load_yaml(tmp_path / "sc.yaml"), source=str(tmp_path / "sc.yaml"))
    back = scenario_from_document(parse_world_document(world_document(sc, 1, 0, 3, "lockstep")))
    x, y = np.meshgrid(np.linspace(-1.2, 1.2, 9), np.linspace(-1.2, 1.2, 7))
    np.testing.assert_array_equal(back.light.intensity(x, y), sc.light.intensity(x, y))
    assert np.ptp(sc.light.intensity(x, y)) > 0
    # An image given as an array has no file: its document says so in one line when loaded.
    doc = light.field_to_dict(light.ImageField(img))
    with pytest.raises(ConfigError, match="path"):
        light.field_from_dict(doc)
