"""The third world (benchmarks/stress_world.py) writes datasets the project's reader accepts (block
YAML, columns in another order, rows shuffled), and without nuisances its robots turn and drive as
its truth says, measured by the twin's summaries (two code bases, one answer)."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from kilobot_twin.recording import measured
from kilobot_twin.gap.model import measured_summaries

_spec = importlib.util.spec_from_file_location("stress_world", Path(__file__).parents[2] / "benchmarks" / "stress_world.py")
sw = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(sw)


@pytest.mark.parametrize("kind, hidden", [("motion", "heading_bias,bias_drift"), ("light_sweep", "sensor_gain"),
                                          ("blink", "clock_drift")])
def test_reader_accepts_shuffled_datasets(tmp_path, kind, hidden):
    truth = sw.generate(kind, hidden, tmp_path, seed=2)
    header = (tmp_path / "observations.csv").read_text().splitlines()[0].split(",")
    assert header[:3] != ["trial", "robot_id", "t_s"]  # not the spec's order: the reader goes by the header
    ds = measured.load(tmp_path)
    sh = truth["shape"]
    assert ds.kind == kind and ds.trials == sh["trials"] and ds.robots == list(range(sh["robots"]))
    for tr in ds.tracks.values():
        assert np.all(np.diff(tr.t_s) > 0)


def test_noiseless_world_matches_the_projects_summaries(tmp_path):
    """No nuisances: the summaries' turn rates and speeds (2 s chords) are the truth's, and the
    truth's heading bias is b = -omega L / v in the twin's units."""
    truth = sw.generate("motion", "heading_bias,speed_heterogeneity", tmp_path, seed=4, nuisance_scale=0.0,
                        fixed_shape=True)
    _, s = measured_summaries(measured.load(tmp_path))
    n = truth["shape"]["robots"]
    w = np.array([truth["robots"][str(i)]["turn_rate_rad_s"] for i in range(n)])
    v = np.array([truth["robots"][str(i)]["speed_m_s"] for i in range(n)])
    np.testing.assert_allclose(s["turn_rate"], np.broadcast_to(w, s["turn_rate"].shape), atol=2e-5)
    np.testing.assert_allclose(s["speed"], np.broadcast_to(v, s["speed"].shape), rtol=2e-3)
    b = np.array([truth["robots"][str(i)]["heading_bias"] for i in range(n)])
    np.testing.assert_allclose(b, -w * 0.025 / v)


def test_bad_effect_is_one_line_and_creates_nothing(tmp_path, capsys):
    assert sw.main(["--kind", "motion", "--hidden", "nope", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: --hidden") and not (tmp_path / "x").exists()
