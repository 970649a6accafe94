"""Campaigns on Dask give the local run's arrays; bad schedulers end in one line and exit 2."""

import socket
import subprocess
import sys

import numpy as np
import pytest
import yaml

from kilobot_twin.batch import Campaign, cluster, run_campaign
from kilobot_twin.core.scenario import scenario_from_dict
from kilobot_twin.core.traits import draw_population
from kilobot_twin.errors import ConfigError

POP = {"heading_bias": {"dist": "uniform", "low": -0.04, "high": 0.04}, "wheel_noise": 0.3, "sensor_noise": 5.0,
       "clock_rate": {"dist": "normal", "mean": 1, "sd": 0.02}, "bias_trial_sd": 0.005, "bias_drift": 0.002}


@pytest.fixture(scope="module")
def local2():
    yield "local:2"
    cluster.close_all()


def _same_results(a, b, dir_a, dir_b):
    assert sorted(a["summary"]) == sorted(b["summary"])
    for k, v in a["summary"].items():
        assert v.dtype == b["summary"][k].dtype and np.array_equal(v, b["summary"][k]), k
    assert (a["order"] is None) == (b["order"] is None)
    if a["order"] is not None:
        assert np.array_equal(a["order"], b["order"])
    if dir_a is not None:
        names = sorted(p.name for p in dir_a.iterdir())
        assert names and names == sorted(p.name for p in dir_b.iterdir())
        for name in names:
            with np.load(dir_a / name) as za, np.load(dir_b / name) as zb:
                assert za.files == zb.files
                for k in za.files:
                    assert np.array_equal(za[k], zb[k]), (name, k)


def test_local_cluster_equals_local_pool(tmp_path, local2):
    """Phototaxis on a grid with trajectories (kernel path) and the coupled blink program
    (core path, with its order parameter): a 2-worker LocalCluster == this machine's pool."""
    sw = draw_population({"n": 4, **POP}, seed=2)
    photo = Campaign(scenario_from_dict({"preset": "paper", "duration_s": 30}), sw, seed=5, runs=5,
                     grid={"behavior.p_right": [0.2, 0.9]}, record_every=10, trials_from_runs=True)
    here = run_campaign(photo, out=tmp_path / "here.npz", workers=2, progress=False)
    there = run_campaign(photo, out=tmp_path / "there.npz", progress=False, scheduler=local2)
    assert there["meta"]["scheduler"] == "local:2" and there["meta"]["workers"] == 2
    _same_results(here, there, tmp_path / "here_traj", tmp_path / "there_traj")

    sync = Campaign(scenario_from_dict({"behavior": "blink", "duration_s": 10, "coupling_per_s": 0.5,
                                        "start": {"kind": "grid", "columns": 2, "random_phase": True}}), sw, seed=1, runs=3)
    _same_results(run_campaign(sync, workers=1, progress=False), run_campaign(sync, progress=False, scheduler=local2),
                  None, None)


def test_dask_progress_counts_every_robot_step(local2, monkeypatch):
    from kilobot_twin.batch import campaign as campaign_mod

    bars = []

    class Bar:
        def __init__(self, total, desc):
            self.total, self.n = total, 0
            bars.append(self)

        def update(self, k):
            self.n += k

        def close(self):
            pass

    monkeypatch.setattr(campaign_mod, "_bar", Bar)
    sc = scenario_from_dict({"behavior": "straight", "duration_s": 7})
    run_campaign(Campaign(sc, draw_population({"n": 3}, seed=1), runs=4, grid={"dt_s": [0.1, 0.05]}),
                 scheduler=local2, progress=True)
    assert bars[0].total == (70 + 140) * 4 * 3 and bars[0].n == bars[0].total


@pytest.mark.parametrize("spec", ["local", "local:0", "local:x", "tcp://host", "http://h:8786", "8786", ""])
def test_bad_scheduler_strings(spec):
    with pytest.raises(ConfigError, match="scheduler"):
        cluster.parse_scheduler(spec)


def test_good_scheduler_strings():
    assert cluster.parse_scheduler("local:3") == ("local", 3)
    assert cluster.parse_scheduler("tcp://10.1.2.3:8786") == ("tcp", "tcp://10.1.2.3:8786")
    assert cluster.parse_scheduler("tcp://node-7.cluster:8786") == ("tcp", "tcp://node-7.cluster:8786")


def _config(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump({"scenario": {"behavior": "straight", "duration_s": 5},
                                   "swarm": {"population": {"n": 2}}, "runs": 2}))
    return cfg


def test_cli_rejects_a_malformed_scheduler_in_one_line(tmp_path):
    out = tmp_path / "r.npz"
    for verb in (["simulate", str(_config(tmp_path)), "--out", str(out)], ["experiment", "straight"], ["reproduce"]):
        p = subprocess.run([sys.executable, "-m", "kilobot_twin", *verb, "--scheduler", "local:zero"],
                           capture_output=True, text=True, cwd=tmp_path)
        assert p.returncode == 2, p.stderr
        assert len(p.stderr.strip().splitlines()) == 1 and "--scheduler" in p.stderr and "local:N" in p.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.yaml"]


def test_cli_unreachable_scheduler_is_one_line_and_writes_nothing(tmp_path):
    with socket.socket() as s:  # a port on which nothing listens
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    out = tmp_path / "r.npz"
    p = subprocess.run([sys.executable, "-m", "kilobot_twin", "simulate", str(_config(tmp_path)), "--out", str(out),
                        "--scheduler", f"tcp://127.0.0.1:{port}", "--no-progress"], capture_output=True, text=True)
    assert p.returncode == 2, p.stderr
    assert p.stderr.startswith("kilobot-twin: error: scheduler: no Dask scheduler answers at tcp://127.0.0.1:")
    assert len(p.stderr.strip().splitlines()) == 1
    assert not out.exists() and not (tmp_path / "r_traj").exists()
