"""Speed of the Rerun conversion; prints its figure.

    python benchmarks/bench_view.py [--robots 100] [--steps 2000] [--repeat 5] [--naive]

Builds a synthetic recording (random walks with LED, light reading, light field, traits) and
times ``write_rrd`` (columnar: one ``send_columns`` per entity) to a temporary .rrd; prints the
best of ``--repeat``. ``--naive`` also times the same content logged with one ``rr.log`` per
robot per step (for comparison). Target: 100 robots x 2000 steps in under 1 s.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from kilobot_twin.recording.swarm_data import SwarmRecording, field_raster  # noqa: E402


def synthetic(n: int, T: int, seed: int = 0) -> SwarmRecording:
    from kilobot_twin.core.scenario import Scenario

    rng = np.random.default_rng(seed)
    bias = rng.uniform(-0.04, 0.04, n)
    dt = 0.1
    theta = np.cumsum(rng.normal(0, 0.05, (n, T)) - bias[:, None] * 0.45 * dt, axis=1)
    x = np.cumsum(0.0113 * dt * np.cos(theta), axis=1) + rng.uniform(-1, 1, (n, 1))
    y = np.cumsum(0.0113 * dt * np.sin(theta), axis=1) + rng.uniform(-1, 1, (n, 1))
    led = rng.integers(0, 2, (n, T)).astype(float)
    reading = np.clip(600 - 200 * np.hypot(x, y), 0, 1023)
    sc = Scenario()
    fld, ext = field_raster(sc)
    traits = {i: {"traits": {"heading_bias": float(bias[i]), "speed_factor": 1.0}} for i in range(n)}
    return SwarmRecording("bench", np.arange(n), np.arange(T) * dt, x, y, theta, led, reading, heading_bias=bias,
                          traits=traits, light_center=(0.0, 0.0), light_field=fld, field_extent=ext)


def naive(rec: SwarmRecording, path: str) -> float:
    import rerun as rr

    from kilobot_twin.viewer.rerun_view import led_colours

    t0 = time.perf_counter()
    s = rr.RecordingStream("kilobot_twin_naive")
    s.save(path)
    cols = led_colours(rec.led)
    for k, t in enumerate(rec.t_s):
        s.set_time("time", duration=float(t))
        for i in range(rec.n_robots):
            s.log(f"arena/robots/{i}", rr.Points2D([[rec.x[i, k], rec.y[i, k]]], colors=[cols[i, k]]))
            s.log(f"light/kilobot_{i}", rr.Scalars(rec.reading[i, k]))
    s.flush()
    s.disconnect()
    return time.perf_counter() - t0


def main() -> None:
    from kilobot_twin.viewer.rerun_view import write_rrd

    ap = argparse.ArgumentParser()
    ap.add_argument("--robots", type=int, default=100)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--naive", action="store_true")
    a = ap.parse_args()
    rec = synthetic(a.robots, a.steps)
    with tempfile.TemporaryDirectory() as d:
        times = []
        for k in range(a.repeat):
            res = write_rrd(rec, Path(d) / f"bench{k}.rrd")
            times.append(res["total_s"])
        size = (Path(d) / "bench0.rrd").stat().st_size
        print(f"view: {a.robots} robots x {a.steps} steps -> .rrd in {min(times):.3f} s (best of {a.repeat}; "
              f"median {np.median(times):.3f} s; {size / 1e6:.1f} MB)  target < 1 s")
        if a.naive:
            print(f"naive (one rr.log per robot per step, points + reading only): {naive(rec, str(Path(d) / 'n.rrd')):.2f} s")


if __name__ == "__main__":
    main()
