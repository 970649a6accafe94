"""``world``: owns the arena, the light field and time.

Publishes (node ``world``, private names):

- ``~/scenario`` (std_msgs/String, transient-local): the scenario document (JSON: scenario,
  seed, run, robots, mode, and ``clock_period_s``: simulated seconds between a robot's
  ``clock`` messages, parameter of the same name, default 1 s, 0 = every step), from which
  robots rebuild exactly the batch engine's scenario;
- ``~/light_field`` (sensor_msgs/Image 32FC1, transient-local): the field's intensity on a
  raster over the arena (row 0 = top = +y), once, and again whenever it changes
  (time-varying fields, at most ``field_rate_hz`` per simulated second);
- ``~/state`` (std_msgs/String, transient-local): ``waiting`` -> ``running`` -> ``done``;
- ``/clock`` (rosgraph_msgs/Clock): simulated time.

Start gate: the world waits until ``robots`` robots are on the graph and every node named in
``wait_for_nodes`` (comma-separated, e.g. ``recorder,analysis@cloud``) subscribes to each robot's
``wait_topics`` (default ``pose,light,led,clock,robots``; ``robots`` is a batched swarm's cloud; a
node that subscribes to a swarm's ``bundle`` counts as subscribed to its robots' data topics, and
so does one named ``name@cloud`` that subscribes to the swarm's cloud, from which it reads them) and
to every ``/analysis/`` topic on the graph, and until the writers of those topics (or of the
swarm's bundle or cloud that carries a robot's) have matched as many readers as the world sees
on them, as their processes report on ``/_kilobot_twin/matched`` (at most ``match_timeout_s``,
default 5 s, then a warning: a reader whose QoS a writer cannot serve never matches), so that a
recording holds every message, then ``settle_s`` more. A start that has not come says what it
waits for, as a warning every ``gate_report_s`` seconds (default 10; 0: never). Then:

- ``lockstep``: publish /clock for step k once every robot has published its pose for step
  ``k - window_steps`` (a robot of a batched ``swarm`` process counts as published when its
  swarm's ``robots`` cloud of that step arrives: one message per swarm and step instead of one
  per robot; see ``swarm``) (``window_steps=1``: strictly one step at a time; a window hides the
  round trip, robots still take the steps in order, so the result equals the batch engine's
  either way) and, when the recorder is awaited, once the recorder acknowledges (on
  ``/recorder/recorded``) every robot message up to step ``k - recorder_lag_steps``; the run
  ends when the recorder holds every message (or made no progress for ``ack_timeout_s``);
- ``realtime``: stamp the start, publish /clock at ``clock_hz`` and stop after the duration.
"""

from __future__ import annotations

import json
import time

import numpy as np
from rclpy.node import Node
from rclpy.task import Future
from geometry_msgs.msg import PoseStamped
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Image, PointCloud2
from std_msgs.msg import String, UInt64

from ..core.light import raster as light_raster
from ..core.scenario import Scenario
from ..errors import ConfigError
from ..recording import cdr, topics
from ..ros import convert, params, qos
from ..ros.executors import run_node, spin_node
from ..ros.latched import LatchedReader
from ..ros.stepping import LockstepPacer
from ..core.scenarios import NAMED, named_scenario, scenario_file, world_document

PROG = "kilobot-twin world"
DATA_TOPICS = ("pose", "light", "led", "clock")
SWARM_TOPICS = (topics.SWARM_CLOUD,)


class WorldNode(Node):
    def __init__(self, *, context=None, parameter_overrides=None, **kwargs):
        super().__init__("world", context=context, parameter_overrides=parameter_overrides, **kwargs)
        name = params.text(self, "scenario", "straight", choices=list(NAMED))
        path = params.text(self, "scenario_file", "")
        duration = params.number(self, "duration_s", 0.0, minimum=0.0)
        self.mode = params.text(self, "mode", "lockstep", choices=["lockstep", "realtime"])
        self.seed = params.integer(self, "seed", 0, minimum=0)
        self.run = params.integer(self, "run", 0, minimum=0)
        self.n_robots = params.integer(self, "robots", 1, minimum=0)
        # "name" awaits a node on each robot's topics (or its swarm's bundle); "name@cloud" takes
        # a swarm's cloud for its robots' data, as the analysis node reads them
        awaited = [s.strip() for s in params.text(self, "wait_for_nodes", "").split(",") if s.strip()]
        for s in awaited:
            if "@" in s and not s.endswith("@cloud"):
                raise ConfigError("wait_for_nodes", f"unknown reading {s!r}", "write a node name, or name@cloud for a "
                                  "node that reads a swarm's robots from its cloud, e.g. -p wait_for_nodes:=recorder,analysis@cloud")
        self.wait_for_nodes = [s.split("@")[0] for s in awaited]
        self.cloud_readers = {s.split("@")[0] for s in awaited if s.endswith("@cloud")}
        self.wait_topics = [s.strip() for s in params.text(self, "wait_topics", ",".join(DATA_TOPICS + SWARM_TOPICS)).split(",")
                            if s.strip()]
        self.settle_s = params.number(self, "settle_s", 0.5, minimum=0.0)
        self.field_pixels = int(params.integer(self, "field_pixels", 128, minimum=2))
        self.field_rate_hz = params.number(self, "field_rate_hz", 2.0, minimum=0.0, strict=True)
        self.clock_hz = params.number(self, "clock_hz", 10.0, minimum=0.0, strict=True)
        self.linger_s = params.number(self, "linger_s", 0.5, minimum=0.0)
        self.stats_file = params.text(self, "stats_file", "")
        self.window_steps = params.integer(self, "window_steps", 32, minimum=1)
        self.recorder_lag_steps = params.integer(self, "recorder_lag_steps", 60, minimum=1)
        self.ack_timeout_s = params.number(self, "ack_timeout_s", 5.0, minimum=0.0, strict=True)
        self.clock_period_s = params.number(self, "clock_period_s", 1.0, minimum=0.0)
        self.gate_report_s = params.number(self, "gate_report_s", 10.0, minimum=0.0)
        self.match_timeout_s = params.number(self, "match_timeout_s", 5.0, minimum=0.0)
        self.await_recorder = "recorder" in self.wait_for_nodes and self.mode == "lockstep"
        self.scenario = self._scenario(name, path, duration)
        self.n_steps = self.scenario.n_steps
        # One robot's data messages after each step: pose, light, led every step, clock on clock steps.
        steps = np.arange(self.n_steps + 1)
        self.pacer = LockstepPacer(self.scenario.dt_s, self.n_steps, self.window_steps, self.recorder_lag_steps,
                                   3 * (steps + 1) + np.cumsum(convert.clock_steps(steps, self.scenario.dt_s,
                                                                                   self.clock_period_s)))

        self.pub_doc = self.create_publisher(String, "~/scenario", qos.LATCHED)
        self.pub_state = self.create_publisher(String, "~/state", qos.LATCHED)
        self.pub_field = self.create_publisher(Image, "~/light_field", qos.LATCHED)
        self.pub_clock = self.create_publisher(Clock, "/clock", qos.CLOCK)
        if self.await_recorder:
            self.create_subscription(UInt64, "/recorder/recorded", self._on_recorded, qos.CLOCK)
        self.pub_doc.publish(convert.json_msg(world_document(self.scenario, self.seed, self.run, self.n_robots,
                                                             self.mode, self.clock_period_s)))
        self._publish_state("waiting")
        self._raster = self._field_raster(0.0)
        self.pub_field.publish(cdr.image_cdr(self._raster, 0))
        self._next_field_s = 1.0 / self.field_rate_hz

        self.finished = Future()
        self.robots: dict[int, str] = {}  # id -> pose topic
        self.swarms: dict[str, set[int] | None] = {}  # swarm topic base -> its member ids (None: not yet heard)
        self._members_readers: dict[str, LatchedReader] = {}  # swarm topic base -> its member list's reader
        self.covered: set[int] = set()  # robots that a swarm's cloud reports for
        self._pose_subs: dict[int, object] = {}
        self._ack_progress_at = time.monotonic()
        self._ack_warned = False
        self._finish_timer = None
        self.start_wall_ns = 0
        self.end_wall_ns = 0
        self._gate_since = None
        self._created = self._gate_reported = time.monotonic()
        # Writers' matched readers as their processes report them (node -> topic -> count), and
        # since when every awaited node subscribes (the match timeout counts from then).
        self._matched: dict[str, dict[str, int]] = {}
        self._subscribed_since = None
        self._match_warned = False
        self.create_subscription(String, topics.MATCH_REPORT_TOPIC, self._on_match_report, qos.DATA)
        self._graph_timer = self.create_timer(0.1, self._poll_graph)
        self._clock_timer = None
        self._field_timer = None

    # --- setup --------------------------------------------------------------------------------

    def _scenario(self, name: str, path: str, duration: float) -> Scenario:
        if path:
            sc = scenario_file(path)
        else:
            sc = named_scenario(name, field="scenario")
        if duration > 0:
            sc = sc.replace(duration_s=duration)
        return sc

    def _field_raster(self, t_s: float) -> np.ndarray:
        return light_raster(self.scenario.light, self.scenario.arena, self.field_pixels, t_s)[0]

    def _maybe_update_field(self, t_s: float) -> None:
        if t_s + 1e-12 < self._next_field_s:
            return
        self._next_field_s = t_s + 1.0 / self.field_rate_hz
        r = self._field_raster(t_s)
        if not np.array_equal(r, self._raster):
            self._raster = r
            self.pub_field.publish(cdr.image_cdr(r, convert.step_stamp_ns(1, t_s)))

    def _publish_state(self, state: str, **extra) -> None:
        self.pub_state.publish(convert.json_msg({"state": state, "mode": self.mode, **extra}))

    # --- start gate --------------------------------------------------------------------------------

    def _poll_graph(self) -> None:
        """Find robots; start once all are there and every awaited node subscribes to them."""
        for topic, _types in self.get_topic_names_and_types():
            parsed = topics.parse_robot_topic(topic)
            if parsed and parsed[1] == "pose" and parsed[0] not in self.robots:
                rid = parsed[0]
                self.robots[rid] = topic
                self.pacer.robots = len(self.robots)
                if self.mode == "lockstep":
                    self._pose_subs[rid] = self.create_subscription(
                        PoseStamped, topic, lambda data, rid=rid: self._on_pose(rid, data), qos.DATA, raw=True)
            m = topics.SWARM_MEMBERS_TOPIC.match(topic)
            if m and m.group(1) not in self.swarms:
                self.swarms[m.group(1)] = None
                self._subscribe_members(m.group(1), topic)
        waiting = self._gate_waits_for()
        now = time.monotonic()
        if waiting:
            self._gate_since = None
            if self.gate_report_s > 0 and now - self._gate_reported >= self.gate_report_s:
                self._gate_reported = now  # a start that never comes says why, every gate_report_s
                self.get_logger().warning(f"not started after {now - self._created:.0f} s: waiting for {waiting}")
            return
        if self._gate_since is None:
            self._gate_since = now
        if now - self._gate_since >= self.settle_s:
            self._graph_timer.cancel()
            self._start()

    def _gate_waits_for(self) -> str:
        """What the start still waits for, in words ("" once everything is there)."""
        if len(self.robots) < self.n_robots:
            return f"robots: {len(self.robots)} of {self.n_robots} on the graph"
        unheard = sorted(base for base, ids in self.swarms.items() if ids is None)
        if unheard:
            return f"the member list of {', '.join(unheard)}"
        missing, carriers = self._subscribers_missing()
        if missing:
            self._subscribed_since = None
            return missing
        return self._writers_unmatched(carriers)

    def _on_match_report(self, msg: String) -> None:
        doc = json.loads(msg.data)
        self._matched[doc["node"]] = doc["matched"]

    def _writers_unmatched(self, carriers: set[str]) -> str:
        """The graph the world sees is not the one each robot process sees: a process whose writer
        has not yet discovered an awaited reader would send it nothing. The processes report their
        writers' matched readers (:class:`~kilobot_twin.ros.publishing.MatchReport`); every topic
        that carries data to an awaited node (``carriers``) must have matched as many readers as
        the world sees on it. A reader that never matches (a QoS its writer cannot serve) would hold the start
        for ever: after ``match_timeout_s`` (0: no wait) the run starts, with a warning."""
        if not carriers or self.match_timeout_s == 0:
            return ""
        now = time.monotonic()
        if self._subscribed_since is None:
            self._subscribed_since = now
        matched: dict[str, int] = {}
        for report in self._matched.values():
            for topic, n in report.items():
                matched[topic] = max(n, matched.get(topic, 0))
        for topic in sorted(carriers):
            readers, m = self.count_subscribers(topic), matched.get(topic)
            if m is not None and m >= readers:
                continue
            waiting = (f"a report of the readers matched by the writer of {topic}" if m is None
                       else f"the writer of {topic} to match its readers ({m} of {readers})")
            if now - self._subscribed_since < self.match_timeout_s:
                return waiting
            if not self._match_warned:
                self._match_warned = True
                self.get_logger().warning(f"starting after match_timeout_s ({self.match_timeout_s:g} s) still waiting for "
                                          f"{waiting}: that reader may miss the run's first messages")
            return ""
        return ""

    def _subscribers_missing(self) -> tuple[str, set[str]]:
        """The first awaited subscription not on the graph ("" when none), and the topics that
        carry data to the awaited nodes: each robot topic they read, or its swarm's bundle."""
        carriers: set[str] = set()
        if not self.wait_for_nodes:
            return "", carriers
        topics_ = [topic[: -len("pose")] + suffix for topic in self.robots.values() for suffix in self.wait_topics
                   if suffix in DATA_TOPICS]
        topics_ += [f"{base}/{suffix}" for base in self.swarms for suffix in self.wait_topics if suffix in SWARM_TOPICS]
        # A robot of a swarm also counts as subscribed by a node that takes its swarm's bundle
        # (the recorder: the same bytes in one message per step).
        bundle_takers = {base: {i.node_name for i in self.get_subscriptions_info_by_topic(topics.swarm_bundle_topic(base))}
                         for base in self.swarms}
        # and by a node awaited as reading the swarm's cloud that subscribes to it (the analysis)
        for base in self.swarms if self.cloud_readers else ():
            bundle_takers[base] |= self.cloud_readers & {
                i.node_name for i in self.get_subscriptions_info_by_topic(topics.swarm_cloud_topic(base))}
        swarm_of = {rid: base for base, ids in self.swarms.items() for rid in ids or ()}
        # The analysis node's topics too (for every awaited node but the analysis itself): its
        # first values go out with the first step.
        analysis = [t for t, _ in self.get_topic_names_and_types() if t.startswith("/analysis/")]
        for topic in topics_ + analysis:
            awaited = [n for n in self.wait_for_nodes if n != "analysis" or topic not in analysis]
            parsed = topics.parse_robot_topic(topic)
            base = swarm_of.get(parsed[0]) if parsed else None
            names = bundle_takers[base] if base is not None else set()
            if any(n in names for n in awaited):
                carriers.add(topics.swarm_bundle_topic(base))
            if all(n in names for n in awaited):
                continue  # (no graph query per robot topic when a bundle covers it)
            names = names | {i.node_name for i in self.get_subscriptions_info_by_topic(topic)}
            missing = [n for n in awaited if n not in names]
            if missing:
                return f"{', '.join(missing)} to subscribe to {topic}", carriers
            carriers.add(topic)
        return "", carriers

    def _subscribe_members(self, base: str, topic: str) -> None:
        """A swarm's member list is latched: read it with :class:`LatchedReader` (made again while
        the list is not heard; the world once waited 60 s for a list the recorder had)."""
        self._members_readers[base] = LatchedReader(self, String, topic, lambda msg, base=base: self._on_members(base, msg))

    def _on_members(self, base: str, msg: String) -> None:
        if self.swarms.get(base) is not None or self.pacer.step >= 0:
            return  # a swarm's members are fixed; and once running, the counting is too
        ids = {int(i) for i in json.loads(msg.data).get("robots", [])}
        self.swarms[base] = ids
        self.covered |= ids
        if self.mode == "lockstep":
            self.create_subscription(PointCloud2, topics.swarm_cloud_topic(base),
                                     lambda data, base=base: self._on_cloud(base, data), qos.DATA, raw=True)

    def _start(self) -> None:
        # Robots of a swarm are counted by their swarm's cloud: their pose subscriptions go.
        for rid in self.covered & set(self._pose_subs):
            self.destroy_subscription(self._pose_subs.pop(rid))
        self.start_wall_ns = time.time_ns()
        self._ack_progress_at = time.monotonic()
        self._publish_state("running", start_wall_ns=self.start_wall_ns, robots=sorted(self.robots))
        self.get_logger().info(f"{self.mode}: {len(self.robots)} robot(s), {self.n_steps} steps of {self.scenario.dt_s} s")
        if self.mode == "lockstep":
            self._advance()
        else:
            self._clock_timer = self.create_timer(1.0 / self.clock_hz, self._on_clock_timer)

    # --- lockstep ----------------------------------------------------------------------------------------

    def _advance(self) -> None:
        """Publish /clock for every step the window and the recorder allow; finish after the last."""
        dt = self.scenario.dt_s
        for k in self.pacer.next_steps(self.await_recorder and not self._ack_timed_out()):
            self._maybe_update_field(k * dt)
            self.pub_clock.publish(cdr.clock_cdr(convert.step_stamp_ns(k, dt)))
        if self.pacer.all_reported:
            self._wait_for_recorder_then_finish()

    def _on_pose(self, rid: int, data: bytes) -> None:
        if rid not in self.covered:
            self._report(data, 1)

    def _on_cloud(self, base: str, data: bytes) -> None:
        self._report(data, len(self.swarms[base] & self.robots.keys()))

    def _report(self, data: bytes, robots: int) -> None:
        """``robots`` robots have published the step in the stamp of ``data``."""
        if self.pacer.step >= 0 and not self.end_wall_ns and self.pacer.report(cdr.stamp_ns(data), robots):
            self._advance()

    # --- recorder back-pressure -----------------------------------------------------------------------

    def _ack_timed_out(self) -> bool:
        if time.monotonic() - self._ack_progress_at < self.ack_timeout_s:
            return False
        if not self._ack_warned:
            self._ack_warned = True
            self.get_logger().warning(f"no progress from the recorder for {self.ack_timeout_s:g} s "
                                      f"({self.pacer.recorded} messages acknowledged): no longer waiting for it")
        return True

    def _on_recorded(self, msg: UInt64) -> None:
        if msg.data > self.pacer.recorded:
            self.pacer.recorded = int(msg.data)
            self._ack_progress_at = time.monotonic()
        if self.mode == "lockstep" and self.pacer.step >= 0 and not self.end_wall_ns:
            self._advance()

    def _wait_for_recorder_then_finish(self) -> None:
        if self.end_wall_ns or self._finish_timer is not None:
            return
        if not self.await_recorder or self.pacer.all_recorded() or self._ack_timed_out():
            self._finish()
        elif self._finish_timer is None:
            self._finish_timer = self.create_timer(0.01, self._check_finish)

    def _check_finish(self) -> None:
        if self.pacer.all_recorded() or self._ack_timed_out():
            self._finish_timer.cancel()
            self._finish()

    # --- realtime ------------------------------------------------------------------------------------------

    def _on_clock_timer(self) -> None:
        elapsed = time.time_ns() - self.start_wall_ns
        self.pub_clock.publish(cdr.clock_cdr(elapsed))
        self._maybe_update_field(elapsed / convert.NS_PER_S)
        if elapsed >= self.scenario.duration_s * convert.NS_PER_S:
            self._clock_timer.cancel()
            self._finish()

    # --- end ----------------------------------------------------------------------------------------------------

    def _finish(self) -> None:
        self.end_wall_ns = time.time_ns()
        wall = (self.end_wall_ns - self.start_wall_ns) / 1e9
        self._publish_state("done", start_wall_ns=self.start_wall_ns, wall_s=wall, sim_s=self.scenario.duration_s,
                            steps=self.n_steps)
        if self.stats_file:
            with open(self.stats_file, "w") as f:
                json.dump({"mode": self.mode, "robots": sorted(self.robots), "steps": self.n_steps,
                           "sim_s": self.scenario.duration_s, "wall_s": wall,
                           "real_time_factor": self.scenario.duration_s / max(wall, 1e-9)}, f, indent=1)
        self.get_logger().info(f"done: {self.scenario.duration_s:g} s simulated in {wall:.2f} s wall "
                               f"(real-time factor {self.scenario.duration_s / max(wall, 1e-9):.1f})")
        # Linger so that late subscribers still get the transient-local 'done'.
        self.create_timer(max(self.linger_s, 0.01), lambda: self.finished.done() or self.finished.set_result(True))


def main(args=None):
    run_node(PROG, WorldNode, run=lambda node: spin_node(node, until=node.finished), args=args)


if __name__ == "__main__":
    main()
