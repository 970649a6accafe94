"""`start: {kind: poses}`: robots start exactly where the file says, per robot id and per run."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from kilobot_twin.config import config_from_dict
from kilobot_twin.core import sim
from kilobot_twin.core.scenario import scenario_from_dict
from kilobot_twin.core.traits import SwarmTraits
from kilobot_twin.errors import ConfigError

ROOT = Path(__file__).resolve().parents[2]

# Values with many digits: "exactly" means bit for bit, also after a trip through YAML and JSON.
POSES = {3: [0.123456789012345, -0.987654321098765, 2.718281828459045],
         7: [-1.1, 0.3333333333333333, -0.5],
         11: {"x_m": 0.25, "y_m": 0.5, "heading_rad": 1.0}}
PER_RUN = {1: {3: [0.5, 0.5, 0.0], 7: [0.6, 0.6, 0.1], 11: [0.7, 0.7, 0.2]}}


def _scenario(**start):
    return scenario_from_dict(yaml.safe_load(yaml.safe_dump(
        {"preset": "argos-code", "behavior": "straight", "duration_s": 1.0,
         "start": {"kind": "poses", "poses": POSES, **start}})))


def _expected(table, ids):
    rows = [table[i] if isinstance(table[i], list) else [table[i]["x_m"], table[i]["y_m"], table[i]["heading_rad"]]
            for i in ids]
    return np.array(rows).T  # (3, N)


def test_start_poses_are_reproduced_exactly_per_robot_and_per_run():
    sc = _scenario(runs=PER_RUN)
    ids = [11, 3, 7]  # the file's order does not matter: poses go by robot id
    sw = SwarmTraits(np.array(ids), SwarmTraits.uniform(3).values)
    res = sim.simulate(sc, sw, seed=4, runs=[0, 1, 2], record_every=1)
    x0, y0, th0 = res.traj["x"][..., 0], res.traj["y"][..., 0], res.traj["theta"][..., 0]
    for r, table in ((0, POSES), (1, PER_RUN[1]), (2, POSES)):  # run 2 is not listed: the poses for all runs
        ex = _expected(table, ids)
        assert np.array_equal(x0[r], ex[0]) and np.array_equal(y0[r], ex[1]) and np.array_equal(th0[r], ex[2]), r


def test_noise_free_straight_robot_leaves_its_start_pose_on_the_theory_line():
    """Zero bias, no noise: after t the robot is at start + v t (cos, sin)(heading) (hand computation)."""
    sc = _scenario()
    sw = SwarmTraits(np.array([3, 7, 11]), SwarmTraits.uniform(3).values)
    res = sim.simulate(sc, sw, seed=0, runs=[0], record_every=1)
    ex = _expected(POSES, [3, 7, 11])
    v = 0.06 * 48 / 255  # README: wheel speed 6 cm/s x motor/255, straight 48/48
    t = res.t_s[-1]
    np.testing.assert_allclose(res.traj["x"][0, :, -1], ex[0] + v * t * np.cos(ex[2]), rtol=0, atol=1e-12)
    np.testing.assert_allclose(res.traj["y"][0, :, -1], ex[1] + v * t * np.sin(ex[2]), rtol=0, atol=1e-12)


def test_poses_travel_through_the_world_document_exactly():
    from kilobot_twin.core.scenarios import parse_world_document, scenario_from_document, world_document

    sc = _scenario(runs=PER_RUN)
    back = scenario_from_document(parse_world_document(world_document(sc, 1, 0, 3, "lockstep")))
    assert back == sc
    assert back.start.poses == sc.start.poses and back.start.runs == sc.start.runs


def test_heading_falls_back_to_heading_rad():
    sc = scenario_from_dict({"behavior": "straight", "start": {"kind": "poses", "heading_rad": 0.75,
                                                                 "poses": {0: [0.1, 0.2]}}})
    x, y, th = sim.start_poses(sc, 0, [0], [0])
    assert (x[0, 0], y[0, 0], th[0, 0]) == (0.1, 0.2, 0.75)


BAD = [
    ({"kind": "poses"}, "start.poses"),
    ({"kind": "poses", "poses": [[0, 0, 0]]}, "start.poses"),
    ({"kind": "poses", "poses": {0: [0.1]}}, "start.poses.0"),
    ({"kind": "poses", "poses": {0: [0.1, "far", 0.0]}}, "start.poses.0.y_m"),
    ({"kind": "poses", "poses": {"zero": [0.1, 0.2, 0.0]}}, "start.poses.zero"),
    ({"kind": "poses", "poses": {0: {"x": 0.1, "y": 0.2}}}, "start.poses.0"),
    ({"kind": "uniform", "poses": {0: [0.1, 0.2, 0.0]}}, "start.kind"),
    ({"kind": "poses", "runs": {"first": {0: [0, 0, 0]}}}, "start.runs.first"),
    ({"kind": "spiral"}, "start.kind"),
]


@pytest.mark.parametrize("start, field", BAD)
def test_bad_start_poses_name_the_field(start, field):
    with pytest.raises(ConfigError) as e:
        scenario_from_dict({"behavior": "straight", "start": start})
    assert str(e.value).split(":")[0] == field, str(e.value)
    assert "\n" not in str(e.value)


def test_a_robot_without_a_pose_is_refused_when_the_config_is_read():
    doc = {"scenario": {"behavior": "straight", "start": {"kind": "poses", "poses": {0: [0, 0, 0], 1: [1, 0, 0]}}},
           "swarm": {"population": {"n": 3}}, "runs": 2}
    with pytest.raises(ConfigError, match=r"start.poses: no start pose for robot 2"):
        config_from_dict(doc)
    doc["scenario"]["start"]["runs"] = {1: {0: [0, 0, 0]}}
    doc["swarm"]["population"]["n"] = 2
    with pytest.raises(ConfigError, match=r"start.runs.1: no start pose for robot 1"):
        config_from_dict(doc)


def test_simulate_verb_starts_robots_at_the_poses(tmp_path):
    cfg = {"scenario": {"preset": "argos-code", "behavior": "straight", "duration_s": 0.5,
                        "start": {"kind": "poses", "poses": {0: [0.5, -0.25, 0.0], 1: [-0.75, 0.125, 1.5]}}},
           "swarm": {"robots": {0: {}, 1: {}}}, "seed": 1, "runs": 2, "record_every": 1}
    (tmp_path / "c.yaml").write_text(yaml.safe_dump(cfg))
    p = subprocess.run([sys.executable, "-m", "kilobot_twin", "simulate", str(tmp_path / "c.yaml"), "--out",
                        str(tmp_path / "r.npz"), "--no-progress", "--workers", "1"], capture_output=True, text=True,
                       cwd=ROOT)
    assert p.returncode == 0, p.stderr
    files = sorted((tmp_path / "r_traj").glob("*.npz"))
    assert files, list(tmp_path.iterdir())
    with np.load(files[0]) as z:
        x0, y0 = z["x"][..., 0], z["y"][..., 0]
    assert np.array_equal(x0, np.array([[0.5, -0.75]] * 2)) and np.array_equal(y0, np.array([[-0.25, 0.125]] * 2))
