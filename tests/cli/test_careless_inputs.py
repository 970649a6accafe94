"""Careless input to every verb: one line on stderr, exit code 2, no traceback, nothing created.

Each case runs the real command line in a scratch folder that holds a few fixtures (a plain file,
an empty folder, a small valid dataset, config and population); afterwards the folder must hold
exactly what it held before (no half-made output folder, no bag, no log folder).
"""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]

CFG = {"scenario": {"preset": "paper", "behavior": {"kind": "phototaxis"}, "duration_s": 5},
       "swarm": {"population": {"n": 3}}, "seed": 1, "runs": 1}


@pytest.fixture(scope="module")
def scratch(tmp_path_factory):
    d = tmp_path_factory.mktemp("careless")
    (d / "afile.txt").write_text("not a folder\n")
    (d / "emptydir").mkdir()
    (d / "cfg.yaml").write_text(yaml.safe_dump(CFG))
    (d / "notyaml.yaml").write_text("robots: [\n")
    (d / "seeded.yaml").write_text("seed: 7\npopulation: {n: 3}\n")
    from kilobot_twin.gap.synth import synth

    synth("motion", "none", d / "data", robots=2, trials=2, seed=1, duration_s=10.0)
    synth("blink", "none", d / "one_trial", robots=2, trials=1, seed=1, duration_s=10.0)
    # Tracks of one sample each: nothing to summarise.
    shutil.copytree(d / "data", d / "one_sample")
    (d / "one_sample" / "observations.csv").write_text("trial,robot_id,t_s,x_m,y_m\n0,0,0.0,0,0\n1,0,0.0,0,0\n")
    # The same tracks labelled as a random walk: the gap workflow models straight runs only.
    shutil.copytree(d / "data", d / "walk_data")
    meta = yaml.safe_load((d / "walk_data" / "meta.yaml").read_text())
    (d / "walk_data" / "meta.yaml").write_text(yaml.safe_dump(dict(meta, behavior="random_walk")))
    return d


def _tree(root: Path) -> set:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


POP = str(ROOT / "config" / "population_example.yaml")

# (arguments, a word the one line must contain)
CASES = [
    (["simulate", "missing.yaml"], "missing.yaml"),
    (["simulate", "emptydir"], "emptydir"),
    (["simulate", "notyaml.yaml"], "notyaml.yaml"),
    (["simulate", "cfg.yaml", "--out", "afile.txt/r.npz"], "--out"),
    (["simulate", "cfg.yaml", "--out", "emptydir"], "--out"),
    (["simulate", "cfg.yaml", "--traits", "missing.yaml", "--out", "r.npz"], "missing.yaml"),
    (["simulate", "cfg.yaml", "--runs", "0"], "--runs"),
    (["demo", "--out", "afile.txt"], "--out"),
    (["demo", "--workers", "0"], "--workers"),
    (["experiment", "straight", "--out", "afile.txt"], "--out"),
    (["experiment", "flocking"], "flocking"),
    (["experiment", "straight", "--preset", "argos"], "--preset"),
    (["reproduce", "--out", "afile.txt"], "--out"),
    (["synth", "--kind", "motion", "--out", "afile.txt"], "--out"),
    (["synth", "--kind", "motion", "--out", "data"], "--out"),
    (["synth", "--kind", "motion", "--hidden", "warp_drive", "--out", "new_data"], "warp_drive"),
    (["synth", "--kind", "dance", "--out", "new_data"], "--kind"),
    (["synth", "--kind", "motion", "--heading-noise-tau", "-1", "--out", "new_data"], "--heading-noise-tau"),
    (["synth", "--kind", "motion", "--heading-noise-tau", "2s", "--out", "new_data"], "--heading-noise-tau"),
    (["synth", "--kind", "motion", "--effect-scale", "0", "--out", "new_data"], "--effect-scale"),
    (["synth", "--kind", "motion", "--effect-scale", "nan", "--out", "new_data"], "--effect-scale"),
    (["gap", "data", "--out", "afile.txt"], "--out"),
    (["gap", "data", "--out", "data"], "--out"),
    (["gap", "missing_data", "--out", "gap_out"], "missing_data"),
    (["gap", "emptydir", "--out", "gap_out"], "emptydir"),
    (["gap", "afile.txt", "--out", "gap_out"], "afile.txt"),
    (["gap", "data", "--model", "missing.yaml", "--out", "gap_out"], "missing.yaml"),
    (["gap", "walk_data", "--out", "gap_out"], "behavior"),
    (["gap", "data", "walk_data", "--out", "gap_out"], "random_walk"),
    (["gap", "data", "--seed", "-1", "--out", "gap_out"], "--seed"),
    (["gap", "one_trial", "--out", "gap_out"], "trials"),  # was a traceback, and gap_out was left
    (["gap", "one_sample", "--out", "gap_out"], "turn_rate"),  # likewise
    (["synth", "--kind", "motion", "--seed", "-1", "--out", "new_data"], "--seed"),
    (["traits", "draw", "missing.yaml", "--out", "t.yaml"], "missing.yaml"),
    (["traits", "draw", POP, "--out", "emptydir"], "--out"),
    (["traits", "draw", POP, "--out", "afile.txt/t.yaml"], "--out"),
    (["traits", "draw", "seeded.yaml", "--seed", "4", "--out", "t.yaml"], "--seed"),  # --seed did nothing
    (["traits", "check", "missing.yaml"], "missing.yaml"),
    (["traits", "check", "emptydir"], "emptydir"),
    (["traits", "check", "notyaml.yaml"], "notyaml.yaml"),
    (["run", "--out", "afile.txt", "--duration", "1"], "--out"),
    (["run", "--out", "afile.txt/bag", "--duration", "1"], "--out"),
    (["run", "--scenario", "missing.yaml", "--out", "bags/x"], "missing.yaml"),
    (["run", "--mode", "fast", "--out", "bags/x"], "--mode"),
    (["run", "--duration", "0", "--out", "bags/x"], "--duration"),
    (["run", "--traits", "missing.yaml", "--out", "bags/x"], "missing.yaml"),
    (["import", "missing_data", "--out", "bags/imp"], "missing_data"),
]


@pytest.mark.parametrize("args, word", CASES, ids=[" ".join(a) for a, _ in CASES])
def test_careless_input_one_line_exit_2_nothing_created(scratch, args, word):
    before = _tree(scratch)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    p = subprocess.run([sys.executable, "-m", "kilobot_twin", *args], capture_output=True, text=True, cwd=scratch,
                       env=env, timeout=300)
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2, (p.returncode, p.stderr[-2000:])
    assert "Traceback" not in p.stderr
    assert len(lines) == 1 and word in lines[0], p.stderr
    assert lines[0].startswith("kilobot-twin"), lines[0]
    assert _tree(scratch) == before, f"created: {sorted(_tree(scratch) - before)}"
