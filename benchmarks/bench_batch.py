"""Batch-engine throughput: 100 robots x 100 runs x 2000 steps, both cores busy.

Targets (issue 2): straight motion >= 20 M robot-steps/s, phototaxis >= 8 M robot-steps/s,
peak memory under 2 GB. Prints one line per case and the peak resident memory of the
parent and of the largest worker. Wall time covers everything after import: process start,
key derivation, the run, gathering results.

    python benchmarks/bench_batch.py [--workers 2] [--repeat 3]
"""

from __future__ import annotations

import argparse
import resource
import time

from kilobot_twin.batch import Campaign, run_campaign
from kilobot_twin.core.scenario import scenario_from_dict
from kilobot_twin.core.traits import draw_population

CASES = {
    "straight (Gaussian noise, Eq. 5)": (
        {"preset": "paper", "behavior": "straight"},
        {"sigma_omega": 0.05, "sigma_v": 0.001},
    ),
    "straight (authors' uniform wheel noise)": (
        {"preset": "paper", "behavior": "straight"},
        {"wheel_noise": 0.5},
    ),
    "phototaxis (argos-code controller, wheel noise)": (
        {"preset": "argos-code", "behavior": {"kind": "phototaxis", "p_right": 0.5, "reference": 2000}},
        {"wheel_noise": 0.5},
    ),
}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=3, help="best of N")
    ap.add_argument("--robots", type=int, default=100)
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--steps", type=int, default=2000)
    a = ap.parse_args()
    print(f"{a.robots} robots x {a.runs} runs x {a.steps} steps, {a.workers} worker(s), best of {a.repeat}")
    for name, (sc_doc, traits) in CASES.items():
        sc = scenario_from_dict({**sc_doc, "dt_s": 0.1, "duration_s": a.steps * 0.1})
        swarm = draw_population({"n": a.robots, "heading_bias": {"dist": "uniform", "low": -0.04, "high": 0.04},
                                 **traits}, seed=1)
        best = float("inf")
        for _ in range(a.repeat):
            t0 = time.perf_counter()
            run_campaign(Campaign(sc, swarm, seed=1, runs=a.runs), workers=a.workers, progress=False)
            best = min(best, time.perf_counter() - t0)
        rate = a.robots * a.runs * a.steps / best
        print(f"{name:50s} {rate / 1e6:6.1f} M robot-steps/s  ({best:.2f} s)")
    parent = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    child = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    print(f"peak RSS: parent {parent:.0f} MB, largest worker {child:.0f} MB, "
          f"sum bound {parent + a.workers * child:.0f} MB")


if __name__ == "__main__":
    main()
