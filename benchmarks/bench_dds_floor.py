"""The floor under the ROS graph's targets: how many messages per second rclpy itself moves on
this machine, with none of the twin's code. Prints its figures.

    python benchmarks/bench_dds_floor.py [--seconds 10] [--topics 10] [--publishers 1]

Three measurements, each in fresh processes, with the twin's data QoS (reliable, depth 200):

- ``publish only``: one process publishes a pre-serialized 76-byte message (a
  geometry_msgs/PoseStamped, CDR) in a tight loop over ``--topics`` topics, nobody listening.
  This is the cost of ``Publisher.publish(bytes)`` alone: no message objects, no serialization.
- ``publish -> take``: the same publisher(s) with one subscriber process taking the raw bytes
  (``raw=True``, no deserialization; rclpy's EventsExecutor, its fastest) and counting them:
  the pair a recorder sits on.
- the same with ``--publishers`` publisher processes (one per core is the most 2 cores hold).

Every robot-step of the twin is 3 such messages (pose, light, LED), and the recorder takes
each one, so a graph target of R robot-steps per second needs 3 R messages published and taken.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import resource
import time

#: geometry_msgs/PoseStamped in CDR, as the twin's robots publish it: encapsulation (little-endian),
#: stamp (sec, nanosec), frame_id "" (length 1: its NUL, then padding to 8), 7 doubles of pose
POSE_CDR = bytes([0, 1, 0, 0]) + bytes(8) + (1).to_bytes(4, "little") + bytes(4) + bytes(56)


def _node(name):
    import rclpy
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    rclpy.init()
    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=200, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.VOLATILE)
    return rclpy, rclpy.create_node(name), qos


def _cpu_s():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def publisher(idx, topics, seconds, start, out):
    from geometry_msgs.msg import PoseStamped

    rclpy, node, qos = _node(f"floor_pub_{idx}")
    pubs = [node.create_publisher(PoseStamped, f"/floor/t{idx}_{j}", qos) for j in range(topics)]
    start.wait()
    time.sleep(1.0)  # discovery
    n, c0, t0 = 0, _cpu_s(), time.perf_counter()
    end = t0 + seconds
    while time.perf_counter() < end:
        for p in pubs:
            p.publish(POSE_CDR)
        n += topics
    out.put(("pub", n, time.perf_counter() - t0, _cpu_s() - c0))
    node.destroy_node()
    rclpy.shutdown()


def subscriber(publishers, topics, seconds, ready, out):
    from geometry_msgs.msg import PoseStamped
    from rclpy.experimental import EventsExecutor
    from rclpy.task import Future

    rclpy, node, qos = _node("floor_sub")
    count = [0]

    def cb(_msg):
        count[0] += 1

    subs = [node.create_subscription(PoseStamped, f"/floor/t{i}_{j}", cb, qos, raw=True)
            for i in range(publishers) for j in range(topics)]
    # rclpy's fastest way to take messages: the EventsExecutor's C++ loop, run in slices
    # (its spin_once() returns to Python after every message).
    ex = EventsExecutor()
    ex.add_node(node)
    ready.set()
    c0, t0 = _cpu_s(), time.perf_counter()
    end = t0 + seconds + 3.0  # the publishers' discovery second, and a tail to drain
    while time.perf_counter() < end:
        ex.spin_until_future_complete(Future(), 0.25)
    out.put(("sub", count[0], time.perf_counter() - t0, _cpu_s() - c0, len(subs)))
    node.destroy_node()
    rclpy.shutdown()


def run(publishers, topics, seconds, listen):
    ctx = mp.get_context("spawn")
    out, start = ctx.Queue(), ctx.Event()
    procs = []
    if listen:
        procs.append(ctx.Process(target=subscriber, args=(publishers, topics, seconds, start, out)))
    else:
        start.set()
    procs += [ctx.Process(target=publisher, args=(i, topics, seconds, start, out)) for i in range(publishers)]
    for p in procs:
        p.start()
    res = [out.get(timeout=seconds + 60) for _ in procs]
    for p in procs:
        p.join(timeout=30)
    pub = [r for r in res if r[0] == "pub"]
    sent = sum(r[1] for r in pub)
    rate = sum(r[1] / r[2] for r in pub)
    cpu = sum(r[3] for r in pub) / max(r[2] for r in pub)
    line = (f"{publishers} publisher process(es) x {topics} topics: published {rate:,.0f} msg/s "
            f"({cpu:.2f} cores, {1e6 * cpu / max(rate, 1):.1f} us of CPU per message)")
    sub = [r for r in res if r[0] == "sub"]
    if sub:
        s = sub[0]
        line += (f"; the subscriber took {s[1]:,} of {sent:,} ({100 * s[1] / max(sent, 1):.1f} %), "
                 f"{s[1] / seconds:,.0f} msg/s over the publishing time, at {s[3] / s[2]:.2f} cores "
                 f"({1e6 * s[3] / max(s[1], 1):.1f} us of CPU per message)")
    print(line, flush=True)
    return rate


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--topics", type=int, default=10)
    ap.add_argument("--publishers", type=int, default=2)
    a = ap.parse_args()
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    print(f"machine: {os.cpu_count()} cores; message: {len(POSE_CDR)} bytes pre-serialized; "
          f"ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID', '0')}")
    run(1, a.topics, a.seconds, listen=False)
    run(1, a.topics, a.seconds, listen=True)
    if a.publishers > 1:
        run(a.publishers, a.topics, a.seconds, listen=True)
    print("the twin needs 3 messages per robot-step, each published and taken by the recorder: "
          "lockstep 200 robots at 20x real time (10 Hz) = 120,000 msg/s; realtime 1,000 robots at 10 Hz = 30,000 msg/s")


if __name__ == "__main__":
    main()
