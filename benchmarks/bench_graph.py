"""Speed of the ROS graph; prints its figures.

    python benchmarks/bench_graph.py [lockstep] [realtime] [recorder] [--quick] [--repeat K]
        [--robots N] [--swarms K]

``--robots`` / ``--swarms`` set the swarm of the lockstep and realtime cases (issue 15's
targets: ``realtime --robots 1000 --swarms K`` holds >= 99 % of its publications and the bag
every published message; ``lockstep --robots 200`` runs >= 20x real time).

- lockstep: 50 robots, 60 s simulated, K runs (default 5: on 2 shared cores one run varies by
  tens of percent); each run's real-time factor and their median (target >= 20).
- realtime: 200 robots in one swarm process at 10 Hz for 60 s; share of the publications
  held (target >= 99 %), bag count == published count, CPU and memory per robot node
  (target <= 1 MB).
- recorder: one publisher process blasting serialized poses over 10 topics for 10 s into a
  recorder process, offering 55,000 msg/s (a little above the target, so that the figure can
  show it); messages/s recorded and loss (target >= 50,000 msg/s, no loss).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from kilobot_twin.recording.bag import BagReader  # noqa: E402
from kilobot_twin.ros.launcher import FASTDDS_PROFILES, run_twin  # noqa: E402


def bench_lockstep(tmp: Path, robots=50, duration=60.0, repeat=5, swarms=1):
    factors = []
    for i in range(repeat):
        rep = run_twin("phototaxis", robots=robots, duration=duration, seed=1, mode="lockstep",
                       out=str(tmp / f"lock{i}"), install_signal_handlers=False, swarms=swarms)
        pub = rep.swarm_stats.get("messages_published", 0)
        rec = sum(n for t, n in rep.counts.items() if t.startswith("/kilobot_") and not t.endswith("/traits"))
        print(f"lockstep: {robots} robots in {swarms} swarm process(es), {duration:g} s simulated in {rep.wall_s:.2f} s wall -> "
              f"real-time factor {rep.real_time_factor:.1f}; robot messages recorded {rec}/{pub}; "
              f"problems: {rep.problems or 'none'}")
        factors.append(rep.real_time_factor)
    f = sorted(factors)
    print(f"lockstep: real-time factor median {f[len(f) // 2]:.1f} of {repeat} runs "
          f"(min {f[0]:.1f}, max {f[-1]:.1f}; target >= 20)")
    return factors


def bench_realtime(tmp: Path, robots=200, duration=60.0, swarms=1):
    rep = run_twin("random_walk", robots=robots, duration=duration, seed=1, mode="realtime", out=str(tmp / "rt"),
                   install_signal_handlers=False, swarms=swarms)
    ss = rep.swarm_stats
    if not ss:  # the swarm processes wrote no stats (killed, or the run never started)
        print(f"realtime: {robots} robots in {swarms} swarm process(es): no swarm stats; problems: {rep.problems}")
        return rep
    expected = robots * (int(round(duration / 0.1)) + 1)
    pub = ss["samples_published"]
    per_robot = ss["per_robot_samples"].values()
    rec = {k: sum(n for t, n in rep.counts.items() if t.startswith("/kilobot_") and t.endswith("/" + k))
           for k in ss["topics_per_robot"]}
    print(f"realtime: {robots} robots in {swarms} swarm process(es) x {duration:g} s at 10 Hz: published {pub}/{expected} samples "
          f"({100 * pub / expected:.2f} %, target >= 99 %), slowest robot {min(per_robot)} samples")
    per_topic = ss["published_per_topic"]
    print("realtime: recorded/published per topic: " + ", ".join(f"{k} {v}/{per_topic[k]}" for k, v in rec.items())
          + " (clock once per simulated second); swarm clouds "
          + str(sum(n for t, n in rep.counts.items() if t.startswith("/swarm") and t.endswith("/robots"))))
    mem = (ss["rss_after_robots_bytes"] - ss["rss_before_robots_bytes"]) / robots / 1e6
    print(f"realtime: swarm CPU {ss['cpu_s']:.1f} s over {ss['wall_s']:.1f} s wall = "
          f"{100 * ss['cpu_s'] / ss['wall_s']:.0f} % of a core, {1e3 * ss['cpu_s'] / ss['wall_s'] / robots:.2f} ms CPU/s per robot; "
          f"memory {mem:.2f} MB per robot node (RSS growth while creating them; target <= 1 MB), "
          f"swarm RSS {ss['rss_bytes'] / 1e6:.0f} MB")
    return rep


PUBLISHER = r"""
import sys, time, rclpy
from rclpy.node import Node
from geometry_msgs.msg import PoseStamped
from rclpy.serialization import serialize_message
from kilobot_twin.ros import qos
rate, seconds, topics = float(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3])
rclpy.init()
n = Node("blaster")
pubs = [n.create_publisher(PoseStamped, f"/kilobot_{i}/pose", qos.DATA) for i in range(topics)]
deadline = time.monotonic() + 30
while time.monotonic() < deadline and not all(p.get_subscription_count() for p in pubs):
    time.sleep(0.05)
time.sleep(1.0)
m = PoseStamped(); m.header.frame_id = "arena"; data = serialize_message(m)
sent = 0; t0 = time.monotonic(); batch = 100
while True:
    now = time.monotonic() - t0
    if now >= seconds:
        break
    target = int(now * rate)
    while sent < target:
        for _ in range(min(batch, target - sent)):
            pubs[sent % topics].publish(data); sent += 1
    time.sleep(0.0005)
el = time.monotonic() - t0
print(sent, el, flush=True)
time.sleep(2.0)
"""


def bench_recorder(tmp: Path, rate=55_000.0, seconds=10.0, topics=10):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    env.setdefault("FASTRTPS_DEFAULT_PROFILES_FILE", str(FASTDDS_PROFILES))  # as `kilobot-twin run` does
    out = tmp / "rec"
    rec = subprocess.Popen([sys.executable, "-m", "kilobot_twin.nodes.recorder", "--ros-args", "-p", f"out:={out}",
                            "-p", "topics:=/kilobot_"], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    pub = subprocess.run([sys.executable, "-c", PUBLISHER, str(rate), str(seconds), str(topics)], env=env,
                         capture_output=True, text=True, timeout=120)
    rec.send_signal(signal.SIGINT)
    rec.wait(60)
    sent, elapsed = pub.stdout.split()
    sent, elapsed = int(sent), float(elapsed)
    got = sum(BagReader(out).counts().values())
    print(f"recorder: publisher sent {sent} messages in {elapsed:.2f} s ({sent / elapsed:,.0f} msg/s offered over {topics} "
          f"topics); bag holds {got} ({100 * got / sent:.3f} %, lost {sent - got}); "
          f"sustained {got / elapsed:,.0f} msg/s into MCAP (target >= 50,000, no loss)")
    return sent, got, elapsed


def main(argv):
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("which", nargs="*", metavar="{lockstep,realtime,recorder}", default=[])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--repeat", type=int, default=None, help="lockstep runs (default 5, 1 with --quick)")
    ap.add_argument("--robots", type=int, default=None, help="robots (default: lockstep 50, realtime 200)")
    ap.add_argument("--swarms", type=int, default=1, help="swarm processes (run --swarms)")
    a = ap.parse_args(argv)
    bad = [w for w in a.which if w not in ("lockstep", "realtime", "recorder")]
    if bad:  # (argparse's choices refuse an empty list for nargs="*" on Python 3.11)
        ap.error(f"unknown case {bad[0]!r}: use lockstep, realtime or recorder")
    which, quick = a.which or ["lockstep", "realtime", "recorder"], a.quick
    repeat = a.repeat if a.repeat is not None else (1 if quick else 5)
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        if "recorder" in which:
            bench_recorder(tmp, seconds=3.0 if quick else 10.0)
        if "lockstep" in which:
            bench_lockstep(tmp, robots=a.robots or 50, duration=10.0 if quick else 60.0, repeat=repeat, swarms=a.swarms)
        if "realtime" in which:
            bench_realtime(tmp, robots=a.robots or (50 if quick else 200), duration=10.0 if quick else 60.0,
                           swarms=a.swarms)


if __name__ == "__main__":
    main(sys.argv[1:])
