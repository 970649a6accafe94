"""Make a measured-v1 motion dataset again with trials that shift the whole swarm.

Every robot of trial k moves at speed factor ``1 - A k + N(0, B)`` (``--speed A,B``: a battery
running down, with some trial-to-trial scatter) and/or turns by a common ``N(0, S)`` rad/s
(``--turn S``: a floor or arena that differs from trial to trial), applied to each track's
observed displacements from its first sample. Reads and writes the CSV alone (no code of
``kilobot_twin``), so the workflow is held against a change it was not built around:

    python benchmarks/common_shift.py SRC DST --speed 0.02,0.01 --seed 3001
    kilobot-twin gap DST --out OUT
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

import numpy as np


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("src", help="a measured-v1 motion dataset (folder with meta.yaml and observations.csv)")
    ap.add_argument("dst", help="a new folder for the shifted dataset (must not exist)")
    ap.add_argument("--speed", default=None, help="A,B: speed factor 1 - A k + N(0, B) in trial k")
    ap.add_argument("--turn", type=float, default=0.0, help="S: a common turn rate N(0, S) rad/s per trial")
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)
    src, dst = Path(a.src), Path(a.dst)
    if not (src / "observations.csv").is_file():
        print(f"common_shift: src: {src} has no observations.csv; give a measured-v1 dataset folder", file=sys.stderr)
        return 2
    if dst.exists():
        print(f"common_shift: dst: {dst} exists; give a new folder", file=sys.stderr)
        return 2
    try:
        A, B = (float(v) for v in a.speed.split(",")) if a.speed else (0.0, 0.0)
    except ValueError:
        print(f"common_shift: --speed: {a.speed!r} is not A,B; give two numbers, e.g. 0.02,0.01", file=sys.stderr)
        return 2
    lines = (src / "observations.csv").read_text().splitlines()
    head = lines[0].split(",")
    if head[:5] != ["trial", "robot_id", "t_s", "x_m", "y_m"]:
        print(f"common_shift: src: columns {head} are not a motion dataset's; give one", file=sys.stderr)
        return 2
    rows = [line.split(",") for line in lines[1:]]
    trial = np.array([int(r[0]) for r in rows])
    robot = np.array([int(r[1]) for r in rows])
    t, x, y = (np.array([float(r[i]) if r[i] else np.nan for r in rows]) for i in (2, 3, 4))
    rng = np.random.default_rng(a.seed)
    K = int(trial.max()) + 1
    f = 1 - A * np.arange(K) + B * rng.standard_normal(K) if a.speed else np.ones(K)
    w = a.turn * rng.standard_normal(K) if a.turn else np.zeros(K)
    out_x, out_y = x.copy(), y.copy()
    for k in range(K):
        for r in np.unique(robot[trial == k]):
            idx = np.nonzero((trial == k) & (robot == r))[0]
            idx = idx[np.argsort(t[idx])]
            ii = idx[np.isfinite(x[idx]) & np.isfinite(y[idx])]
            if len(ii) < 2:
                continue
            dx, dy = np.diff(x[ii]) * f[k], np.diff(y[ii]) * f[k]
            c, s = np.cos(w[k] * t[ii][1:]), np.sin(w[k] * t[ii][1:])
            out_x[ii[1:]] = x[ii[0]] + np.cumsum(c * dx - s * dy)
            out_y[ii[1:]] = y[ii[0]] + np.cumsum(s * dx + c * dy)
    shutil.copytree(src, dst)
    with open(dst / "observations.csv", "w") as fh:
        fh.write(lines[0] + "\n")
        for i, r in enumerate(rows):
            xs = f"{out_x[i]:.6g}" if np.isfinite(out_x[i]) else ""
            ys = f"{out_y[i]:.6g}" if np.isfinite(out_y[i]) else ""
            fh.write(",".join([r[0], r[1], r[2], xs, ys] + r[5:]) + "\n")
    print(f"speed factors {np.round(f, 3).tolist()}; common turn rates {np.round(w, 4).tolist()} rad/s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
