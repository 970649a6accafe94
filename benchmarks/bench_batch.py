"""Batch-engine throughput in robot-steps per second, for small and large swarms.

Targets (issue 15, both cores busy, 2000 steps): phototaxis >= 10 M robot-steps/s at 5 robots x
60 runs and >= 20 M at 100 x 100; straight motion with Gaussian noise >= 25 M (100 x 100).
Prints one line per (case, size) and the peak resident memory. Wall time covers everything
after import: key derivation, the run, gathering results (and, for the process pool, process
start). The first call compiles the kernel if its on-disk cache is cold; best-of-N hides that.

    python benchmarks/bench_batch.py                        # the issue's table
    python benchmarks/bench_batch.py --sizes 5x60 --cases phototaxis --repeat 5
    python benchmarks/bench_batch.py --robots 100 --runs 100  # one size (as before)
    python benchmarks/bench_batch.py --cpu                    # CPU ns per robot-step, one worker

``--cpu`` measures process CPU time with one worker instead of wall time: on a machine shared
with other work it says what the engine costs, and 2 / (ns per robot-step) what two idle
cores would give.
"""

from __future__ import annotations

import argparse
import resource
import time

from kilobot_twin.batch import Campaign, run_campaign
from kilobot_twin.core.scenario import scenario_from_dict
from kilobot_twin.core.traits import draw_population

CASES = {
    "straight": ("straight (Gaussian noise, Eq. 5)",
                 {"preset": "paper", "behavior": "straight"},
                 {"sigma_omega": 0.05, "sigma_v": 0.001}),
    "straight_wheel": ("straight (authors' uniform wheel noise)",
                       {"preset": "paper", "behavior": "straight"},
                       {"wheel_noise": 0.5}),
    "phototaxis": ("phototaxis (argos-code controller, wheel noise)",
                   {"preset": "argos-code", "behavior": {"kind": "phototaxis", "p_right": 0.5, "reference": 2000}},
                   {"wheel_noise": 0.5}),
}
TARGETS_M = {("phototaxis", 5, 60): 10, ("phototaxis", 100, 100): 20, ("straight", 100, 100): 25}


def _size(text: str) -> tuple[int, int]:
    robots, runs = text.lower().split("x")
    return int(robots), int(runs)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=3, help="best of N")
    ap.add_argument("--sizes", default="5x60,20x50,100x100", help="comma list of ROBOTSxRUNS")
    ap.add_argument("--robots", type=int, help="one size: robots (with --runs; overrides --sizes)")
    ap.add_argument("--runs", type=int, help="one size: runs")
    ap.add_argument("--cases", default="phototaxis,straight,straight_wheel", help=f"comma list of {', '.join(CASES)}")
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--cpu", action="store_true", help="CPU time per robot-step with one worker (a shared machine)")
    a = ap.parse_args()
    if a.cpu:
        a.workers = 1
    clock = time.process_time if a.cpu else time.perf_counter
    sizes = [_size(s) for s in a.sizes.split(",")]
    if a.robots or a.runs:
        sizes = [(a.robots or 100, a.runs or 100)]
    print(f"{a.steps} steps, {a.workers} worker(s), best of {a.repeat}")
    for key in a.cases.split(","):
        name, sc_doc, traits = CASES[key]
        sc = scenario_from_dict({**sc_doc, "dt_s": 0.1, "duration_s": a.steps * 0.1})
        for robots, runs in sizes:
            swarm = draw_population({"n": robots, "heading_bias": {"dist": "uniform", "low": -0.04, "high": 0.04},
                                     **traits}, seed=1)
            best = float("inf")
            for _ in range(a.repeat):
                t0 = clock()
                run_campaign(Campaign(sc, swarm, seed=1, runs=runs), workers=a.workers, progress=False)
                best = min(best, clock() - t0)
            rate = robots * runs * a.steps / best / 1e6
            if a.cpu:
                ns = 1e3 / rate
                print(f"{name:48s} {robots:4d} x {runs:4d} {ns:7.0f} ns CPU per robot-step  "
                      f"(2 idle cores: {2e3 / ns:5.1f} M robot-steps/s)", flush=True)
                continue
            target = TARGETS_M.get((key, robots, runs))
            note = f"  target >= {target} M: {'met' if rate >= target else 'NOT MET'}" if target else ""
            print(f"{name:48s} {robots:4d} x {runs:4d} {rate:7.1f} M robot-steps/s  ({best:.3f} s){note}", flush=True)
    parent = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    child = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    print(f"peak RSS: parent {parent:.0f} MB, largest worker process {child:.0f} MB")


if __name__ == "__main__":
    main()
