"""Timing of `kilobot-twin replay`; prints its figures.

    python benchmarks/bench_replay.py [--robots 100] [--hz 10] [--seconds 10] [--rates 1,10] [--no-recorder]

Writes a synthetic twin bag (``robots`` x ``hz`` x {pose, light, led} = 3,000 messages/s by
default, plus /clock), then replays it at each rate into a recorder process (a real
subscriber on every topic) and prints the timing error (publish time - scheduled time) p50 /
p99 / max and how many messages the recorder got. Target: p99 < 5 ms at 1x for 3,000 msg/s.
The error of a message is measured just before its publish call, so in a burst (``--burst``)
later messages carry the publish time of the ones before them (~30 us each).
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from kilobot_twin.recording.bag import BagReader  # noqa: E402
from kilobot_twin.recording.twin_bag import TwinBagWriter  # noqa: E402


def synthetic_bag(path: Path, robots: int, hz: float, seconds: float, seed: int = 0, burst: bool = False) -> int:
    """``burst``: every sample of a step shares one log time; otherwise log times are spread
    evenly over the step, as a recorder receiving the stream logs them."""
    rng = np.random.default_rng(seed)
    w = TwinBagWriter(path)
    dt_ns = int(1e9 / hz)
    t0 = 1_700_000_000 * 10**9
    n = 0
    for k in range(int(seconds * hz)):
        stamp = k * dt_ns
        w.clock(stamp, t0 + stamp)
        for r in range(robots):
            log = t0 + stamp + (0 if burst else (r + 1) * dt_ns // (robots + 1))
            w.robot_sample(r, stamp, log, *rng.normal(0, 0.5, 2), rng.uniform(-3, 3),
                           reading=float(rng.integers(0, 1024)), led=int(rng.integers(0, 2)))
            n += 3
    w.close()
    return n + int(seconds * hz)


def main() -> None:
    from kilobot_twin.nodes.replay import replay_bag

    ap = argparse.ArgumentParser()
    ap.add_argument("--robots", type=int, default=100)
    ap.add_argument("--hz", type=float, default=10.0)
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--rates", default="1,10")
    ap.add_argument("--no-recorder", action="store_true")
    ap.add_argument("--burst", action="store_true", help="all robots' samples of a step at one log time")
    a = ap.parse_args()
    os.environ.setdefault("ROS_DOMAIN_ID", str(150 + os.getpid() % 50))
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    with tempfile.TemporaryDirectory() as d:
        src = Path(d) / "src"
        total = synthetic_bag(src, a.robots, a.hz, a.seconds, burst=a.burst)
        print(f"bag: {total} messages over {a.seconds:g} s ({total / a.seconds:.0f} msg/s at 1x), "
              + ("bursts: every sample of a step at one log time" if a.burst else "log times spread over each step"))
        for rate in (float(r) for r in a.rates.split(",")):
            rec = None
            out = Path(d) / f"rec_{rate:g}"
            if not a.no_recorder:
                rec = subprocess.Popen([sys.executable, "-m", "kilobot_twin.nodes.recorder", "--ros-args", "-p",
                                        f"out:={out}", "-p", "topics:=/kilobot_,/clock"], env=env,
                                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            try:
                s = replay_bag(str(src), rate=rate, wait_for_subscribers_s=0 if rec is None else 60)
            finally:
                if rec is not None:
                    time.sleep(0.5)
                    rec.send_signal(signal.SIGINT)
                    rec.wait(60)
            got = f", recorder got {sum(BagReader(out).counts().values())} of {total}" if rec is not None else ""
            print(f"rate {rate:g}x: {s['messages']} msgs in {s['wall_s']:.2f} s ({s['rate_msg_s']:.0f} msg/s); timing error "
                  f"p50 {s['err_p50_ms']:.3f} ms, p99 {s['err_p99_ms']:.3f} ms, max {s['err_max_ms']:.2f} ms{got}"
                  + ("  [target p99 < 5 ms]" if rate == 1 else ""))


if __name__ == "__main__":
    main()
