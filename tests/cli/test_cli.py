"""The command line: verbs work, bad input ends in one line and exit code 2."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from kilobot_twin import cli
from kilobot_twin.batch import load_results
from kilobot_twin.demo import DEMO_CONFIG

ROOT = Path(__file__).resolve().parents[2]


def run_cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "kilobot_twin", *args], capture_output=True, text=True, cwd=cwd)


def test_demo_config_file_matches_embedded_defaults():
    assert yaml.safe_load((ROOT / "config" / "demo_phototaxis.yaml").read_text()) == DEMO_CONFIG


@pytest.mark.parametrize("name", ["straight_fan.yaml", "demo_phototaxis.yaml"])
def test_shipped_configs_load(name):
    from kilobot_twin.config import load_config

    cfg = load_config(ROOT / "config" / name)
    assert len(cfg.swarm) > 0 and cfg.runs > 0


def test_shipped_traits_files_are_valid():
    assert cli.check_traits(str(ROOT / "config" / "traits_example.yaml")) == 4
    assert cli.check_traits(str(ROOT / "config" / "population_example.yaml")) == 49


def test_simulate_writes_results_with_metadata(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump({
        "scenario": {"preset": "paper", "behavior": {"kind": "phototaxis", "p_right": 1.0}, "duration_s": 20},
        "swarm": {"population": {"n": 5, "heading_bias": {"dist": "linspace", "low": -0.04, "high": 0.04}}},
        "seed": 3, "runs": 4, "grid": {"behavior.p_right": [0.5, 1.0]},
    }))
    out = tmp_path / "r.npz"
    p = run_cli("simulate", str(cfg), "--out", str(out), "--parquet", "--no-progress", "--workers", "2")
    assert p.returncode == 0, p.stderr
    res = load_results(out)
    assert res["summary"]["cost_m"].shape == (2, 4, 5)
    assert res["meta"]["seed"] == 3 and res["meta"]["version"]
    assert res["meta"]["points"] == [{"behavior.p_right": 0.5}, {"behavior.p_right": 1.0}]
    np.testing.assert_allclose(res["swarm"].heading_bias, np.linspace(-0.04, 0.04, 5))
    import pyarrow.parquet as pq

    table = pq.read_table(out.with_suffix(".parquet"))
    assert table.num_rows == 2 * 4 * 5
    assert np.allclose(np.sort(table["cost_m"].to_numpy()), np.sort(res["summary"]["cost_m"].ravel()))


def test_traits_draw_then_check(tmp_path):
    out = tmp_path / "swarm.yaml"
    p = run_cli("traits", "draw", str(ROOT / "config" / "population_example.yaml"), "--out", str(out), "--seed", "4")
    assert p.returncode == 0, p.stderr
    doc = yaml.safe_load(out.read_text())
    assert len(doc["robots"]) == 49
    assert run_cli("traits", "check", str(out)).returncode == 0


def test_traits_draw_takes_the_seed_given_else_the_file_s_else_0(tmp_path):
    """``--seed`` draws; without it the file's ``seed:``; without either, 0. A file whose seed
    differs from ``--seed`` is refused (the file's seed used to win and --seed did nothing)."""
    from kilobot_twin.cli import draw_traits
    from kilobot_twin.errors import ConfigError

    pop = "population: {n: 5, heading_bias: {dist: normal, mean: 0, sd: 0.01}}\n"
    bare, seeded = tmp_path / "bare.yaml", tmp_path / "seeded.yaml"
    bare.write_text(pop)
    seeded.write_text("seed: 7\n" + pop)

    def drawn(path, seed, name):
        return yaml.safe_load(draw_traits(str(path), str(tmp_path / name), seed).read_text())["robots"]

    assert drawn(seeded, None, "a.yaml") == drawn(bare, 7, "b.yaml") == drawn(seeded, 7, "c.yaml")
    assert drawn(bare, None, "d.yaml") == drawn(bare, 0, "e.yaml") != drawn(bare, 7, "f.yaml")
    with pytest.raises(ConfigError, match="--seed"):
        draw_traits(str(seeded), str(tmp_path / "g.yaml"), 4)
    assert not (tmp_path / "g.yaml").exists()


def test_a_population_with_its_own_seed_is_the_same_swarm_whatever_the_run_s_seed(tmp_path):
    """A run configuration's ``seed`` draws a population that has none (other robots for another
    seed); a population with its own ``seed:``, in ``swarm:`` or in a ``--traits`` file, is that
    seed's swarm whatever the run's seed (README, "A run configuration")."""
    from kilobot_twin.config import config_from_dict

    pop = {"n": 5, "heading_bias": {"dist": "normal", "mean": 0, "sd": 0.01}}
    traits = tmp_path / "pop.yaml"
    traits.write_text(yaml.safe_dump({"seed": 7, "population": pop}))

    def bias(doc, seed, **kw):
        return config_from_dict(doc, seed=seed, **kw).swarm.heading_bias.tolist()

    assert bias({"swarm": {"population": pop}}, 1) != bias({"swarm": {"population": pop}}, 2)
    pinned = bias({"swarm": {"seed": 7, "population": pop}}, 1)
    assert pinned == bias({"swarm": {"seed": 7, "population": pop}}, 2) == bias({"swarm": {"population": pop}}, 7)
    assert bias({}, 1, traits_path=str(traits)) == bias({}, 2, traits_path=str(traits)) == pinned


BAD = [
    ("robots:\n  0: {heading_bias: 2.5}\n", "robots.0.heading_bias"),
    ("robots:\n  0: {clock_rate: -1}\n", "robots.0.clock_rate"),
    ("robots:\n  0: {colour: red}\n", "robots.0.colour"),
    ("robots: [\n", "line"),
    ("population: {n: 3, heading_bias: {dist: cauchy}}\n", "population.heading_bias.dist"),
]


@pytest.mark.parametrize("text, field", BAD)
def test_bad_traits_file_one_line_exit_2(tmp_path, text, field):
    f = tmp_path / "bad.yaml"
    f.write_text(text)
    p = run_cli("traits", "check", str(f))
    assert p.returncode == 2
    assert "Traceback" not in p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and field in lines[0], p.stderr


BAD_CONFIGS = [
    ({"scenario": {"behavior": "dance"}}, "behavior.kind"),
    ({"scenario": {"preset": "argos"}}, "preset"),
    ({"scenario": {"dt_s": -0.1}}, "dt_s"),
    ({"scenario": {"light": {"kind": "cone", "radius_m": "big"}}}, "light.radius_m"),
    ({"scenario": {"behavior": {"kind": "phototaxis", "p_right": 1.5}}}, "behavior.p_right"),
    ({"scenario": {}, "runs": 0}, "runs"),
    ({"scenario": {}, "grid": {"behavior.p_right": 0.5}}, "grid"),
    ({"scenario": {}, "grid": {"behavior.p_right": [2.0]}}, "behavior.p_right"),
    ({"scenario": {}, "swarm": {"robots": {0: {"heading_bias": "x"}}}}, "robots.0.heading_bias"),
    ({"scenario": {"arena": {"walls": "yes"}}}, "arena.walls"),
    ({"scenaro": {}}, "scenaro"),
    # YAML's .nan and .inf are floats: every number must be finite (they were taken, or crashed)
    ({"scenario": {"coupling_per_s": float("nan")}}, "coupling_per_s"),
    ({"scenario": {"neighbour_radius_m": float("inf")}}, "neighbour_radius_m"),
    ({"scenario": {"floor_tilt_direction_rad": float("nan")}}, "floor_tilt_direction_rad"),
    ({"scenario": {"cost_window_steps": float("inf")}}, "cost_window_steps"),
    ({"scenario": {}, "trials_from_runs": "false"}, "trials_from_runs"),  # bool("false") was True
]


@pytest.mark.parametrize("doc, field", BAD_CONFIGS)
def test_bad_run_config_one_line_exit_2(tmp_path, doc, field):
    f = tmp_path / "bad.yaml"
    f.write_text(yaml.safe_dump(doc))
    p = run_cli("simulate", str(f), "--out", str(tmp_path / "o.npz"), "--no-progress")
    assert p.returncode == 2, p.stderr
    assert "Traceback" not in p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and field in lines[0], p.stderr
    assert not (tmp_path / "o.npz").exists()


def test_missing_traits_file_and_bad_argument(tmp_path):
    f = tmp_path / "c.yaml"
    f.write_text("scenario: {}\n")
    p = run_cli("simulate", str(f), "--traits", str(tmp_path / "nope.yaml"))
    assert p.returncode == 2 and "nope.yaml" in p.stderr and len(p.stderr.strip().splitlines()) == 1
    p = run_cli("simulate", str(f), "--runs", "zero")
    assert p.returncode == 2 and "--runs" in p.stderr and len(p.stderr.strip().splitlines()) == 1
