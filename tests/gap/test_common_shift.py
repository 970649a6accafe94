"""benchmarks/common_shift.py: a trial's shift of the whole swarm, checked against geometry by hand
on straight tracks (speed scales every displacement; a common turn rate w turns the path so that
its heading at time t is w t)."""

from pathlib import Path

import numpy as np
from . import benchmark

cs = benchmark.load("common_shift")


def _straight(folder: Path, K=3, N=2, T=601, dt=0.1, v=0.01):
    folder.mkdir()
    (folder / "meta.yaml").write_text("format: kilobot-twin/measured-v1\nkind: motion\n")
    rows = ["trial,robot_id,t_s,x_m,y_m"]
    for k in range(K):
        for i in range(N):
            rows += [f"{k},{i},{j * dt:.4f},{0.1 * i + v * j * dt:.6g},{0.05 * k:.6g}" for j in range(T)]
    (folder / "observations.csv").write_text("\n".join(rows) + "\n")


def _read(folder: Path):
    a = np.genfromtxt(folder / "observations.csv", delimiter=",", skip_header=1)
    return a[:, 0].astype(int), a[:, 1].astype(int), a[:, 2], a[:, 3], a[:, 4]


def test_speed_and_turn_shift_every_robot_of_a_trial_alike(tmp_path, capsys):
    src = tmp_path / "src"
    _straight(src)
    assert cs.main([str(src), str(tmp_path / "sp"), "--speed", "0.05,0.02", "--seed", "4"]) == 0
    f = 1 - 0.05 * np.arange(3) + 0.02 * np.random.default_rng(4).standard_normal(3)
    k, i, t, x, y = _read(tmp_path / "sp")
    for kk in range(3):
        for ii in range(2):
            sel = (k == kk) & (i == ii)
            assert abs((x[sel][-1] - x[sel][0]) - f[kk] * 0.01 * 60.0) < 1e-5  # 6 significant digits
    assert cs.main([str(src), str(tmp_path / "tu"), "--turn", "0.01", "--seed", "5"]) == 0
    w = 0.01 * np.random.default_rng(5).standard_normal(3)
    k, i, t, x, y = _read(tmp_path / "tu")
    for kk in range(3):
        sel = (k == kk) & (i == 1)
        heading = np.arctan2(np.diff(y[sel]), np.diff(x[sel]))
        np.testing.assert_allclose(heading[-200:], w[kk] * t[sel][1:][-200:], atol=2e-3)
        # a circle of radius v / w: the chord from the start spans half the angle turned
        chord = np.arctan2(y[sel][-1] - y[sel][0], x[sel][-1] - x[sel][0])
        assert abs(chord - w[kk] * 60.0 / 2) < 2e-3
    # bad input: one line naming the field, exit 2, nothing written
    capsys.readouterr()
    assert cs.main([str(src), str(tmp_path / "bad"), "--speed", "fast"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--speed" in err[0] and not (tmp_path / "bad").exists()
