"""``swarm``: N robot nodes in one process (composition).

Parameters: ``robots`` (N), ``traits_file`` (YAML with ``robots:`` or ``population:``; empty:
draw from the default population of :mod:`kilobot_twin.core.scenarios`), ``seed``, ``run``,
``trial``, ``world``, ``batched`` (step all robots in one vectorised core call: in lockstep on
each /clock step, in realtime on one wall timer of period ``dt_s``; Kuramoto coupling between
the process's robots is then exact in both modes),
``stats_file`` (JSON written at exit: messages published, CPU, memory),
``slices`` and ``slice_index`` (one swarm across K processes, on one host or several: process
k of K owns the k-th of K contiguous blocks of the robot ids; give each its own node name,
e.g. ``-r __node:=swarm_1``, so that its ``members`` and ``robots`` topics differ; the world
waits for all of them. Kuramoto coupling acts within a process only, so a coupled scenario is
refused with slices > 1).

A batched swarm also publishes ``~/members``, ``~/bundle`` (its robots' messages of a step, the same
bytes, in one message: what the recorder writes) and ``~/robots`` (README, "nodes"). The robots are
lean nodes (no parameter services, no rosout) with the world's scenario's behaviour unless
``behavior`` is set.
"""

from __future__ import annotations

import json
import os
import resource
import time

import numpy as np

from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.task import Future
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import String, UInt8MultiArray

from ..core import behaviors as B
from ..core.traits import TRAIT_NAMES
from ..errors import ConfigError
from ..recording import cdr, topics
from ..ros import convert, params, qos
from ..ros.executors import make_executor, release, run_node, spin
from ..ros.latched import LatchedReader
from ..ros.model import SwarmModel
from ..ros.publishing import MatchReport
from ..ros.stepping import StepRule
from ..core.scenarios import (clock_period_from_document, load_swarm_traits, parse_world_document,
                             scenario_from_document)
from .robot import RobotNode

PROG = "kilobot-twin swarm"


def _rss_bytes() -> int:
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except OSError:  # pragma: no cover - not Linux
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


class SwarmNode(Node):
    def __init__(self, *, context=None, parameter_overrides=None, **kwargs):
        super().__init__("swarm", context=context, parameter_overrides=parameter_overrides, **kwargs)
        self.n_robots = params.integer(self, "robots", 1, minimum=1)
        self.seed = params.integer(self, "seed", 0, minimum=0)
        self.run = params.integer(self, "run", 0, minimum=0)
        self.trial = params.integer(self, "trial", 0, minimum=0)
        self.world = params.text(self, "world", "/world")
        self.behavior_kind = params.text(self, "behavior", "", choices=[""] + list(B.BEHAVIORS))
        self.batched = bool(params.declare(self, "batched", True))
        self.stats_file = params.text(self, "stats_file", "")
        self.slices = params.integer(self, "slices", 1, minimum=1)
        self.slice_index = params.integer(self, "slice_index", 0, minimum=0)
        if self.slice_index >= self.slices:
            raise ConfigError("slice_index", f"must be < slices = {self.slices}, got {self.slice_index}",
                              f"use 0 .. {self.slices - 1}")
        traits = load_swarm_traits(params.text(self, "traits_file", ""), self.n_robots, self.seed)
        self.n_robots = len(traits)  # robots of the whole swarm
        if self.slices > len(traits):
            raise ConfigError("slices", f"{self.slices} processes for {len(traits)} robots", "use at most one per robot")
        self.traits = traits.subset(np.array_split(np.arange(len(traits)), self.slices)[self.slice_index])

        self.robots: list[RobotNode] = []
        self.match_report = None
        self.gate_open = False  # the world's state has left "waiting"
        self.model: SwarmModel | None = None
        self.world_doc: dict | None = None
        self.world_ready = Future()
        self.mode = None
        self.rt_timer = None
        self.start_wall_ns = 0
        self.late_steps = 0
        self.t_start = time.monotonic()
        self.cpu_start = time.process_time()
        self.rss_before_robots = _rss_bytes()
        self.rss_after_robots = 0
        self.world_reader = LatchedReader(self, String, f"{self.world}/scenario", self._on_world)
        self.state_reader = LatchedReader(self, String, f"{self.world}/state", self._on_state)
        self.create_subscription(Clock, "/clock", self._on_clock, qos.CLOCK)
        self.pub_members = self.pub_cloud = self.pub_bundle = None
        self.clock_period_s = 0.0  # from the world document

    # --- robots ---------------------------------------------------------------------------------

    def _on_world(self, msg: String) -> None:
        if self.world_doc is None:
            self.world_doc = parse_world_document(msg.data)
            self.world_ready.done() or self.world_ready.set_result(True)

    def create_robots(self, executor) -> None:
        """Create the robot nodes (after the world's scenario document arrived) and add them."""
        doc = self.world_doc
        scenario = scenario_from_document(doc)
        if self.slices > 1 and scenario.coupling_per_s > 0:
            raise ConfigError("slices", "Kuramoto coupling acts within one process only",
                              "run a coupled scenario (sync) with slices:=1")
        behavior = scenario.behavior if not self.behavior_kind else B.BEHAVIORS[self.behavior_kind]()
        scenario = scenario.replace(behavior=behavior)
        self.mode = doc.get("mode", "lockstep")
        self.clock_period_s = clock_period_from_document(doc)
        self.rule = StepRule(scenario.dt_s, scenario.n_steps)
        common = [("seed", self.seed), ("run", self.run), ("trial", self.trial), ("world", self.world),
                  ("swarm_size", max(self.n_robots, int(doc.get("robots", 0))))]
        common += params.behavior_overrides(behavior)
        if self.batched:
            self.model = SwarmModel(scenario, self.traits, self.seed, self.run, self.trial,
                                    max(self.n_robots, int(doc.get("robots", 0))))
            # Announced before the robots exist, so that nobody counts a robot both ways.
            self.pub_cloud = self.create_publisher(PointCloud2, f"~/{topics.SWARM_CLOUD}", qos.DATA)
            self.pub_bundle = self.create_publisher(UInt8MultiArray, f"~/{topics.SWARM_BUNDLE}", qos.DATA)
            self.pub_members = self.create_publisher(String, "~/members", qos.LATCHED)
            self.pub_members.publish(convert.members_msg(self.traits.ids))
        for col, rid in enumerate(self.traits.ids):
            tr = self.traits.robot(col)
            overrides = [Parameter(k, value=v) for k, v in common + [("robot_id", int(rid))]]
            overrides += [Parameter(k, value=float(getattr(tr, k))) for k in TRAIT_NAMES]
            node = RobotNode(int(rid), context=self.context, parameter_overrides=overrides, lean=True,
                             use_global_arguments=False, standalone=False)
            node.set_world(doc, shared=(self.model, col) if self.model is not None else None)
            self.robots.append(node)
            executor.add_node(node)
        if not self.gate_open:
            self.match_report = MatchReport(self, self._data_writers)
        self.rss_after_robots = _rss_bytes()
        self.get_logger().info(f"{len(self.robots)} robot(s) up, {self.mode}"
                               f"{' (batched physics)' if self.model is not None else ''}, "
                               f"{(self.rss_after_robots - self.rss_before_robots) / len(self.robots) / 1e6:.2f} MB/robot")

    # --- time ------------------------------------------------------------------------------------------

    def _data_writers(self) -> list:
        writers = [p for r in self.robots for p in (r.pub_pose, r.pub_light, r.pub_led, r.pub_clock)]
        return writers + ([self.pub_bundle, self.pub_cloud] if self.model is not None else [])

    def _on_state(self, msg: String) -> None:
        doc = json.loads(msg.data)
        state = doc.get("state")
        if state != "waiting":
            self.gate_open = True
            if self.match_report is not None:
                self.match_report.stop()  # the world's gate has opened
        if self.model is None or self.mode != "realtime":
            for r in self.robots:
                r.set_state(doc)
        elif state == "running" and self.rt_timer is None and not self.robots[0].done:
            self.start_wall_ns = int(doc["start_wall_ns"])
            self._publish_all(self._wall_stamp())
            self.rt_timer = self.create_timer(self.model.scenario.dt_s, self._on_realtime_timer)
        elif state == "done":
            if self.rt_timer is not None:
                self.rt_timer.cancel()
                if not self.robots[0].done:  # the steps due by the end: the last races the world's done
                    self._on_realtime_timer()
            for r in self.robots:
                r.done = True
        if state == "running":
            self.t_start = time.monotonic()
            self.cpu_start = time.process_time()

    def _wall_stamp(self) -> int:
        return max(0, time.time_ns() - self.start_wall_ns)

    def _on_realtime_timer(self) -> None:
        """Realtime, batched: step every robot once per period of wall time since the start.

        A late timer (a busy process) takes the missed steps at once, so the swarm's simulated
        time keeps up with the wall clock; those samples carry their publication time, and
        ``late_steps`` in the stats counts them.
        """
        behind = self.rule.due(self._wall_stamp(), self.model.step_index)
        if behind > 1:
            self.late_steps += behind - 1
        for _ in range(behind):
            self.model.step()
            self._publish_all(self._wall_stamp())

    def _on_clock(self, msg: Clock) -> None:
        if not self.robots or self.mode != "lockstep":
            return
        ns = convert.time_to_ns(msg.clock)
        if self.model is None:
            for r in self.robots:
                r.on_clock(ns)
            return
        action = self.rule.on_clock(ns, self.model.step_index)
        if action == StepRule.STEP:
            self.model.step()
        if action is not None:
            self._publish_all(ns)

    def _publish_all(self, stamp_ns) -> None:
        """Every robot's messages of the current step, serialized in one vectorised call; then the
        same bytes once more as the swarm's bundle (what the recorder writes), then the cloud."""
        records = dict(zip(cdr.BUNDLE_KINDS, self.model.records(stamp_ns)))
        if not convert.clock_steps(self.model.step_index, self.model.scenario.dt_s, self.clock_period_s):
            del records["clock"]
        pose, light, led, clock = (cdr.rows(records[k]) if k in records else [None] * len(self.robots)
                                   for k in cdr.BUNDLE_KINDS)
        for r, *msgs in zip(self.robots, pose, light, led, clock):
            r.publish_serialized(*msgs)
        self.pub_bundle.publish(cdr.bundle_cdr(self.model.ids, records))
        self.pub_cloud.publish(self.model.cloud(stamp_ns))

    # --- report ------------------------------------------------------------------------------------------------

    def stats(self) -> dict:
        per_robot = {int(r.robot_id): r.published for r in self.robots}
        total = sum(per_robot.values())
        clocks = sum(r.clocks_published for r in self.robots)
        return {
            "robots": len(self.robots), "mode": self.mode, "batched": self.model is not None,
            "samples_published": total, "messages_published": 3 * total + clocks, "per_robot_samples": per_robot,
            "topics_per_robot": ["pose", "light", "led", "clock"],
            "published_per_topic": {"pose": total, "light": total, "led": total, "clock": clocks},
            # Of those, handed to DDS (a robot topic with no reader skips it: ReaderAwarePublisher).
            "handed_to_dds": sum(p.handed for r in self.robots
                                 for p in (r.pub_pose, r.pub_light, r.pub_led, r.pub_clock)),
            "wall_s": time.monotonic() - self.t_start, "cpu_s": time.process_time() - self.cpu_start,
            "rss_bytes": _rss_bytes(), "rss_before_robots_bytes": self.rss_before_robots,
            "rss_after_robots_bytes": self.rss_after_robots, "late_steps": self.late_steps,
        }

    def write_stats(self) -> None:
        if self.stats_file:
            with open(self.stats_file, "w") as f:
                json.dump(self.stats(), f, indent=1)

    def destroy_node(self):
        for r in self.robots:
            r.destroy_node()
        self.robots = []
        return super().destroy_node()


def _run(node: SwarmNode) -> None:
    """Wait for the world's scenario, then create the robots in the same executor and spin."""
    executor = make_executor()
    executor.add_node(node)
    try:
        spin(executor, until=node.world_ready)
        node.create_robots(executor)
        spin(executor)
    finally:
        release(executor, node, *node.robots)  # before the nodes are destroyed (see release)


def main(args=None):
    run_node(PROG, SwarmNode, run=_run, on_exit=SwarmNode.write_stats, args=args)


if __name__ == "__main__":
    main()
