"""``analysis``: live swarm metrics from every robot's pose, LED and clock (the topics under
``/analysis/``: README, "nodes"; each metric is :mod:`kilobot_twin.core.metrics`).

Robots are discovered on the graph (late joiners included). The robots of a batched ``swarm``
process are read from its ``robots`` cloud (one message per step for the whole swarm, all
robots at one stamp: the metrics are exact for that step; the swarm's transient-local
``members`` says which robots it covers), every other robot from its own ``pose``, ``led`` and
``clock`` topics (a step is evaluated once every robot's pose has reached it; ``led`` has no
stamp, so it is the latest one received). The scenario (light centre, arena, blink period)
comes from the world's transient-local document, and so does the number of robots of the run:
nothing is published before every one of them has been heard from (several swarm processes).
"""

from __future__ import annotations

import json

import numpy as np
from geometry_msgs.msg import PoseStamped
from rclpy.node import Node
from sensor_msgs.msg import PointCloud2, TimeReference
from std_msgs.msg import ColorRGBA, Float64, String, UInt32

from ..core.metrics import METRICS
from ..core.metrics import swarm_metrics as core_metrics
from ..core.scenario import Scenario
from ..recording import cdr, topics
from ..ros import convert, params, qos
from ..ros.executors import run_node
from ..ros.latched import LatchedReader
from ..ros.publishing import MatchReport
from ..core.scenarios import parse_world_document, scenario_from_document

PROG = "kilobot-twin analysis"


def swarm_metrics(x, y, led, ticks, scenario: Scenario, covered_cells: int) -> dict:
    """The metrics of one snapshot (lists over the robots heard from; NaN where undefined)."""
    half = getattr(scenario.behavior, "half_period_ticks", None)
    m = core_metrics(x, y, led, ticks, scenario.light.center, 2 * half if half else None,
                     covered_cells * scenario.arena.coverage_cell_m ** 2)
    return {k: float(v) for k, v in m.items()}


class AnalysisNode(Node):
    def __init__(self, *, context=None, parameter_overrides=None, **kwargs):
        super().__init__("analysis", context=context, parameter_overrides=parameter_overrides, **kwargs)
        self.period_ns = int(round(params.number(self, "period_s", 1.0, minimum=0.0) * convert.NS_PER_S))
        self.world = params.text(self, "world", "/world")
        self.scenario = Scenario()
        self.x: dict[int, float] = {}
        self.y: dict[int, float] = {}
        self.led: dict[int, int] = {}
        self.ticks: dict[int, float] = {}
        self.due: dict[int, int] = {}  # robot -> the next evaluation time (ns) it has not reached
        self.snaps: dict[int, dict] = {}  # evaluation time -> robot -> its state then
        self.expected = 0  # robots of the run (world document): evaluate once all are heard from
        self.cells: set[int] = set()
        self._visited: list[tuple] = []  # (stamp, xs, ys) not yet counted in the coverage cells
        self.subscribed: set[str] = set()
        self.covered: set[int] = set()  # robots read from a swarm's cloud
        self._robot_subs: dict[int, list] = {}
        self._members_readers: dict = {}  # a swarm's members topic -> its LatchedReader
        self.pub_time = self.create_publisher(Float64, "~/time_s", qos.DATA)
        self.pubs = {m: self.create_publisher(Float64, f"~/{m}", qos.DATA) for m in METRICS}
        self.pub_robots = self.create_publisher(UInt32, "~/robots", qos.DATA)
        self.latest: dict = {}
        # its writers' matched readers, for the world's start gate, until its first values go out
        self.match_report = MatchReport(self, lambda: [self.pub_time, self.pub_robots, *self.pubs.values()])
        self.world_reader = LatchedReader(self, String, f"{self.world}/scenario", self._on_world)
        self.create_timer(0.25, self._discover)

    def _on_world(self, msg: String) -> None:
        doc = parse_world_document(msg.data)
        self.scenario = scenario_from_document(doc)
        self.expected = int(doc.get("robots", 0))

    def _discover(self) -> None:
        for topic, _ in self.get_topic_names_and_types():
            if topic in self.subscribed:
                continue
            m = topics.SWARM_MEMBERS_TOPIC.match(topic)
            if m:
                self.subscribed.add(topic)
                self._members_readers[topic] = LatchedReader(self, String, topic,
                                                             lambda msg, base=m.group(1): self._on_members(base, msg))
                continue
            parsed = topics.parse_robot_topic(topic)
            if not parsed or parsed[1] not in ("pose", "led", "clock") or parsed[0] in self.covered:
                continue
            self.subscribed.add(topic)
            rid, kind = parsed
            # Raw subscriptions: the few numbers needed are read from the CDR bytes directly
            # (no message object per sample; a swarm sends thousands per second).
            if kind == "pose":
                sub = self.create_subscription(PoseStamped, topic, lambda data, r=rid: self._on_pose(r, data),
                                               qos.DATA, raw=True)
            elif kind == "led":
                sub = self.create_subscription(ColorRGBA, topic, lambda data, r=rid: self.led.__setitem__(
                    r, cdr.led(data)), qos.DATA, raw=True)
            else:
                sub = self.create_subscription(TimeReference, topic, lambda data, r=rid: self.ticks.__setitem__(
                    r, cdr.time_reference(data)[1] / cdr.NS_PER_S * self.scenario.tick_hz), qos.DATA, raw=True)
            self._robot_subs.setdefault(rid, []).append(sub)

    def _on_members(self, base: str, msg: String) -> None:
        """A swarm covers these robots: read them from its cloud, not from their own topics."""
        ids = {int(i) for i in json.loads(msg.data).get("robots", [])}
        for rid in ids - self.covered:
            for sub in self._robot_subs.pop(rid, []):
                self.destroy_subscription(sub)
        self.covered |= ids
        self.create_subscription(PointCloud2, topics.swarm_cloud_topic(base), self._on_cloud, qos.DATA, raw=True)

    def _on_cloud(self, data: bytes) -> None:
        stamp, pts = cdr.robot_cloud(data)
        ids = pts["id"].tolist()
        x, y = pts["x"].tolist(), pts["y"].tolist()
        self.x.update(zip(ids, x))
        self.y.update(zip(ids, y))
        self.led.update(zip(ids, pts["led"].tolist()))
        self.ticks.update(zip(ids, pts["ticks"].tolist()))
        self._visited.append((stamp, x, y))
        for rid in ids:
            self._sample(rid, stamp)
        self._maybe_publish()

    def _on_pose(self, rid: int, data: bytes) -> None:
        stamp, x, y, _qz, _qw = cdr.pose_stamped(data)
        self.x[rid], self.y[rid] = x, y
        self._visited.append((stamp, [x], [y]))  # coverage cells are computed in bulk at publication
        self._sample(rid, stamp)
        self._maybe_publish()

    def _sample(self, rid: int, stamp: int) -> None:
        """Keep robot ``rid``'s state as of ``stamp`` if that is its first sample at or after the
        next evaluation time it owes (robots of several swarm processes are steps apart)."""
        due = self.due.get(rid, 0)
        if stamp >= due:
            self.snaps.setdefault(due, {})[rid] = (stamp, self.x[rid], self.y[rid], self.led.get(rid),
                                                   self.ticks.get(rid))
            self.due[rid] = (stamp // self.period_ns + 1) * self.period_ns if self.period_ns else stamp + 1

    def _maybe_publish(self) -> None:
        """Publish each evaluation time once every robot of the run (and every one heard from) has
        reached it, with each robot's state at that time."""
        while self.snaps:
            due = min(self.snaps)
            snap = self.snaps[due]
            if len(snap) < max(self.expected, len(self.due)):
                return
            del self.snaps[due]
            self.publish_metrics(max(v[0] for v in snap.values()), snap)

    def publish_metrics(self, stamp_ns: int, snap: dict | None = None) -> dict:
        """Publish the metrics of ``snap`` (robot -> (stamp, x, y, led, ticks)), by default the
        latest state of every robot; coverage counts positions up to ``stamp_ns``."""
        if snap is None:
            snap = {i: (stamp_ns, self.x[i], self.y[i], self.led.get(i), self.ticks.get(i)) for i in self.x}
        later = [v for v in self._visited if v[0] > stamp_ns]
        now = [v for v in self._visited if v[0] <= stamp_ns]
        if now:
            xs = np.concatenate([v[1] for v in now])
            ys = np.concatenate([v[2] for v in now])
            self.cells.update(np.unique(self.scenario.arena.cell_index(xs, ys)).tolist())
        self._visited = later
        rows = [snap[i] for i in sorted(snap)]
        m = swarm_metrics([r[1] for r in rows], [r[2] for r in rows], [r[3] for r in rows if r[3] is not None],
                          [r[4] for r in rows if r[4] is not None], self.scenario, len(self.cells))
        self.match_report.stop()
        self.pub_time.publish(Float64(data=stamp_ns / convert.NS_PER_S))
        for k, v in m.items():
            self.pubs[k].publish(Float64(data=v))
        self.pub_robots.publish(UInt32(data=len(rows)))
        self.latest = m
        return m


def main(args=None):
    run_node(PROG, AnalysisNode, args=args)


if __name__ == "__main__":
    main()
