"""``replay``: publish a recorded bag again, on its original topics and types, in recorded time
(what it publishes, ``/clock``, QoS: README, "Replay, view, import").

Parameters: ``bag`` (directory), ``rate`` (> 0; 2 = twice as fast), ``loop``, ``topics``
(comma-separated exact names or prefixes ending in ``/`` or ``*``; empty = all),
``wait_for_subscribers_s`` (before playing, wait up to this long until every topic has a
subscriber: for recorders that discover topics), ``clock_hz`` (the ``/clock`` generated for a
bag without one), ``start_delay_s``. Messages go out from a hybrid sleep / busy-wait loop on
the monotonic clock.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import rclpy
import yaml
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from ..errors import ConfigError, is_number
from ..ros import params
from ..ros.executors import STOP, run_node
from .recorder import message_class

PROG = "kilobot-twin replay"
#: Sleep until this close to a message's time, then busy-wait (time.sleep overshoots by ~0.1-1 ms).
SPIN_WINDOW_NS = 2_000_000


@dataclass
class LoadedBag:
    """Messages of a bag in log-time order: parallel arrays plus the channel table."""

    topics: list[dict]                  # [{name, type, qos}] by channel index
    log_ns: np.ndarray                  # (M,) int64
    channel: np.ndarray                 # (M,) int32 index into topics
    data: list[bytes] = field(repr=False)

    def __len__(self) -> int:
        return len(self.data)


def topic_selected(topic: str, patterns: list[str]) -> bool:
    if not patterns:
        return True
    for p in patterns:
        if p.endswith("*") and topic.startswith(p[:-1]):
            return True
        if p.endswith("/") and topic.startswith(p):
            return True
        if topic == p:
            return True
    return False


def load_bag(bag_dir: str | Path, patterns: list[str] | None = None) -> LoadedBag:
    """Read every (selected) message of a bag into memory (what is intact of a damaged bag)."""
    from ..recording.bag import BagReader

    reader = BagReader(bag_dir)
    patterns = patterns or []
    qos = {ch["topic"]: ch["qos"] for ch in reader.channels}
    topics: list[dict] = []
    index: dict[str, int] = {}
    log_ns, chan, data = [], [], []
    for m in reader.messages():
        k = index.get(m.topic)
        if k is None:
            k = index[m.topic] = len(topics) if topic_selected(m.topic, patterns) else -1
            if k >= 0:
                topics.append({"name": m.topic, "type": m.type, "qos": qos.get(m.topic, "")})
        if k >= 0:
            log_ns.append(m.log_time_ns)
            chan.append(k)
            data.append(m.data)
    if not data:
        raise ConfigError("--topics" if patterns else str(bag_dir), "no messages to replay",
                          "check the topic names with `kilobot-twin bag info`")
    return LoadedBag(topics, np.asarray(log_ns, dtype=np.int64), np.asarray(chan, dtype=np.int32), data)


def qos_from_yaml(text: str) -> QoSProfile:
    """The QoS a topic was offered with (rosbag2's offered_qos_profiles), deep enough for bursts."""
    try:
        prof = (yaml.safe_load(text) or [{}])[0]
    except (yaml.YAMLError, IndexError, TypeError):
        prof = {}
    latched = prof.get("durability") == 1
    best_effort = prof.get("reliability") == 2
    depth = int(prof.get("depth", 1) or 1) if latched else 1000
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=max(1, depth),
                      reliability=ReliabilityPolicy.BEST_EFFORT if best_effort else ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


class ReplayNode(Node):
    def __init__(self, *, context=None, parameter_overrides=None, **kwargs):
        super().__init__("replay", context=context, parameter_overrides=parameter_overrides, **kwargs)
        self.bag_dir = params.text(self, "bag", "")
        self.rate = params.number(self, "rate", 1.0, minimum=0.0, strict=True)
        self.loop = bool(self.declare_parameter("loop", False).value)
        topics = params.text(self, "topics", "")
        self.patterns = [t.strip() for t in topics.split(",") if t.strip()]
        self.wait_s = params.number(self, "wait_for_subscribers_s", 0.0, minimum=0.0)
        self.clock_hz = params.number(self, "clock_hz", 100.0, minimum=0.0, strict=True)
        self.start_delay_s = params.number(self, "start_delay_s", 0.05, minimum=0.0)
        if not self.bag_dir:
            raise ConfigError("bag", "no bag given", "give -p bag:=bags/NAME")
        self.bag = load_bag(self.bag_dir, self.patterns)
        self.pubs = []
        for t in self.bag.topics:
            try:
                cls = message_class(t["type"])
            except (ImportError, AttributeError, ValueError):
                raise ConfigError(t["name"], f"message type {t['type']!r} is not installed",
                                  "install its interface package or leave the topic out with --topics") from None
            self.pubs.append(self.create_publisher(cls, t["name"], qos_from_yaml(t["qos"])))
        self.has_clock = any(t["name"] == "/clock" for t in self.bag.topics)
        self.clock_pub = None
        if not self.has_clock and (not self.patterns or topic_selected("/clock", self.patterns)):
            from rosgraph_msgs.msg import Clock

            self.clock_pub = self.create_publisher(Clock, "/clock", QoSProfile(depth=100))
        self.errors_ns: list[np.ndarray] = []
        self.published = 0

    @property
    def stopped(self) -> bool:
        """SIGINT / SIGTERM reached the node process (see :func:`~kilobot_twin.ros.executors.run_node`)."""
        return STOP.is_set()

    def wait_for_subscribers(self) -> bool:
        """Up to ``wait_for_subscribers_s``: until every publisher has at least one subscriber."""
        if self.wait_s <= 0:
            return True
        end = time.monotonic() + self.wait_s
        while time.monotonic() < end and not self.stopped:
            if all(p.get_subscription_count() > 0 for p in self.pubs):
                return True
            time.sleep(0.02)
        return all(p.get_subscription_count() > 0 for p in self.pubs)

    def play(self) -> dict:
        """Publish the bag (``loop``: until stopped); returns timing statistics of the last pass."""
        self.wait_for_subscribers()
        while True:
            stats = self._play_once()
            if not self.loop or self.stopped:
                return stats

    def _play_once(self) -> dict:
        bag = self.bag
        rel = (bag.log_ns - bag.log_ns[0]).astype(np.float64) / self.rate
        offsets = np.rint(rel).astype(np.int64)
        clock_events = None
        if self.clock_pub is not None:
            from rosgraph_msgs.msg import Clock

            from ..ros.convert import ns_to_time

            period = int(1e9 / self.clock_hz)
            clock_events = (np.arange(0, int(bag.log_ns[-1] - bag.log_ns[0]) + 1, period), Clock(), ns_to_time)
        pubs = [p.publish for p in self.pubs]
        chan = bag.channel.tolist()
        data = bag.data
        off = offsets.tolist()
        err = np.zeros(len(data), dtype=np.int64)
        mono = time.monotonic_ns
        sleep = time.sleep
        start = mono() + int(self.start_delay_s * 1e9)
        ci = 0
        t_wall0 = time.perf_counter()
        for i in range(len(data)):
            if self.stopped:
                err = err[:i]
                break
            target = start + off[i]
            if clock_events is not None:
                ci = self._clock_until(clock_events, ci, off[i], start)
            now = mono()
            if target - now > SPIN_WINDOW_NS:
                sleep((target - now - SPIN_WINDOW_NS) / 1e9)
            while True:
                now = mono()
                if now >= target:
                    break
            err[i] = now - target
            pubs[chan[i]](data[i])
        wall = time.perf_counter() - t_wall0
        self.published += len(err)
        self.errors_ns.append(err)
        return timing_stats(err, wall, len(err))

    def _clock_until(self, events, ci: int, up_to_off: int, start: int) -> int:
        """Publish generated /clock ticks (recorded time = first log time + offset) due before ``up_to_off``."""
        times, msg, ns_to_time = events
        t0 = int(self.bag.log_ns[0])
        while ci < len(times) and times[ci] / self.rate <= up_to_off:
            target = start + int(times[ci] / self.rate)
            while time.monotonic_ns() < target:
                pass
            ns_to_time(t0 + int(times[ci]), msg.clock)
            self.clock_pub.publish(msg)
            ci += 1
        return ci


def timing_stats(err_ns: np.ndarray, wall_s: float, n: int) -> dict:
    e = np.asarray(err_ns, dtype=np.float64) / 1e6
    if not len(e):
        return {"messages": 0, "wall_s": wall_s}
    return {"messages": n, "wall_s": wall_s, "rate_msg_s": n / max(wall_s, 1e-9),
            "err_p50_ms": float(np.percentile(e, 50)), "err_p99_ms": float(np.percentile(e, 99)),
            "err_max_ms": float(e.max())}


def replay_bag(bag: str, rate: float = 1.0, loop: bool = False, topics: list[str] | None = None,
               wait_for_subscribers_s: float = 0.0, context=None) -> dict:
    """Replay a bag in this process (own rclpy init unless ``context`` is given); returns timing statistics."""
    if not (is_number(rate) and rate > 0):
        raise ConfigError("--rate", f"must be a positive finite number, got {rate}", "e.g. --rate 1 (recorded speed) or --rate 10")
    if not (is_number(wait_for_subscribers_s) and wait_for_subscribers_s >= 0):
        raise ConfigError("--wait-for-subscribers", f"must be a finite number >= 0, got {wait_for_subscribers_s}",
                          "give seconds, e.g. --wait-for-subscribers 5")
    own = context is None
    if own:
        rclpy.init()
    node = None
    try:
        node = ReplayNode(context=context, parameter_overrides=[
            rclpy.parameter.Parameter("bag", value=str(bag)), rclpy.parameter.Parameter("rate", value=float(rate)),
            rclpy.parameter.Parameter("loop", value=bool(loop)),
            rclpy.parameter.Parameter("topics", value=",".join(topics or [])),
            rclpy.parameter.Parameter("wait_for_subscribers_s", value=float(wait_for_subscribers_s))])
        stats = node.play()
        # Let reliable publishers hand their last messages over before the node goes away.
        for p in node.pubs:
            p.wait_for_all_acked(rclpy.duration.Duration(seconds=2.0))
        stats["topics"] = len(node.pubs)
        return stats
    finally:
        if node is not None:
            node.destroy_node()
        if own:
            rclpy.try_shutdown()


def _play(node) -> None:
    stats = node.play()
    node.get_logger().info(f"replayed {stats['messages']} messages; timing error p99 {stats.get('err_p99_ms', 0):.3f} ms")


def main(args=None):
    run_node(PROG, ReplayNode, run=_play, args=args)


if __name__ == "__main__":
    main()
