"""``recorder``: every robot, world and analysis topic into a rosbag2-layout MCAP bag (what it
records and ``~/recorded``: README, "nodes"; the file: :mod:`kilobot_twin.recording.bag`).

Parameters: ``out`` (bag directory, default ``bags/<UTC time>``), ``topics`` (comma-separated
prefixes, default ``/kilobot_,/swarm,/world,/analysis,/clock``), ``discovery_period_s`` (how often
the graph is searched for new topics), ``chunk_bytes``, ``compression`` (zstd, lz4, none),
``ack_every`` (``~/recorded`` is published every this many robot messages and at 20 Hz when it
changed), ``bundles`` (default true: the robots of a batched ``swarm`` process are written from
its ``bundle``, one message per step holding the bytes each robot published on its own topics,
instead of through one subscription per robot and topic; false: every robot topic is subscribed).
Subscriptions are raw (the bytes received are written as they are); transient-local
publishers are subscribed transient-local, so that their one message is recorded even if it
was published before the recorder joined. ``metadata.yaml`` is written on shutdown.
"""

from __future__ import annotations

import importlib
import json
import struct
import time
from datetime import datetime, timezone

import numpy as np
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from std_msgs.msg import String, UInt8MultiArray, UInt64

from .. import __version__
from ..outputs import check_out_dir
from ..errors import ConfigError
from ..ros import params, qos
from ..recording.bag import DEFAULT_CHUNK_BYTES, BagWriter
from ..recording.cdr import read_bundle, stamp_ns
from ..recording.topics import (BEST_EFFORT, DATA_QOS, RELIABLE, ROBOT_DATA, ROBOT_TYPES, SWARM_BUNDLE,
                                 SWARM_MEMBERS_TOPIC, TRANSIENT_LOCAL, VOLATILE, parse_robot_topic, qos_yaml,
                                 robot_namespace, swarm_bundle_topic)
from ..ros.executors import run_node
from ..ros.latched import LatchedReader

PROG = "kilobot-twin recorder"
#: Longest wait (s) for a swarm's member list before the robot topics of the graph are subscribed
#: one by one (the member list is latched and arrives within milliseconds of its discovery).
MEMBERS_WAIT_S = 5.0


def message_class(type_name: str):
    pkg, _, name = type_name.split("/")
    return getattr(importlib.import_module(f"{pkg}.msg"), name)


class RecorderNode(Node):
    def __init__(self, *, context=None, parameter_overrides=None, **kwargs):
        super().__init__("recorder", context=context, parameter_overrides=parameter_overrides, **kwargs)
        default_out = "bags/" + datetime.now(timezone.utc).strftime("%Y%m%d_%H%M%S")
        self.out = params.text(self, "out", default_out)
        self.prefixes = [p.strip() for p in params.text(self, "topics", "/kilobot_,/swarm,/world,/analysis,/clock").split(",")
                         if p.strip()]
        period = params.number(self, "discovery_period_s", 0.2, minimum=0.0, strict=True)
        chunk = params.integer(self, "chunk_bytes", DEFAULT_CHUNK_BYTES, minimum=1024)
        compression = params.text(self, "compression", "zstd", choices=["zstd", "lz4", "none"])
        if not self.out:
            raise ConfigError("out", "empty bag path", "give e.g. -p out:=bags/run1")
        check_out_dir(self.out, "out", new=True)  # never overwrite a bag
        self._bag_options = {"chunk_size": chunk, "compression": compression}
        self._started_ns = time.time_ns()
        self.bag: BagWriter | None = None  # created with the first message: a run that never starts leaves nothing
        self.channels: dict[str, int | None] = {}  # topic -> channel id (None: subscribed, nothing written yet)
        self.world_doc: dict | None = None
        self.traits: dict[int, dict] = {}
        self.joined: list[tuple[str, int]] = []
        # Acknowledgements: robot data messages written, published every `ack_every` messages and
        # at 20 Hz when it changed (the world lets lockstep run ahead of it by a bounded lag).
        self.ack_every = params.integer(self, "ack_every", 500, minimum=1)
        self.robot_messages = 0
        self._acked = 0
        self.pub_recorded = self.create_publisher(UInt64, "~/recorded", qos.CLOCK)
        # Bundles: robots of a batched swarm are written from their swarm's bundle. A robot's own
        # data subscriptions (taken before its swarm's member list arrived) are dropped then; what
        # they wrote last marks where the bundle takes over (nothing written twice or lost).
        self.bundles = bool(params.declare(self, "bundles", True))
        self.covered: dict[int, str] = {}              # robot id -> swarm topic base
        self._members_pending: dict[str, float] = {}   # members topic subscribed, not heard -> since
        self._members_readers: dict = {}  # a swarm's members topic -> its LatchedReader
        self._robot_subs: dict[int, list] = {}         # robot id -> its data subscriptions
        self._last: dict[tuple[int, str], bytes] = {}  # (robot, kind) -> last message written from its topic
        self._handover: dict[tuple[int, str], int] = {}  # (robot, kind) -> bundle items up to this stamp are in
        self._bundle_cids: dict[tuple[str, bytes], tuple[np.ndarray, np.ndarray | None]] = {}
        self.create_timer(0.05, self._ack)
        self.create_timer(period, self.discover)
        self.discover()

    # --- discovery ---------------------------------------------------------------------------

    def wanted(self, topic: str) -> bool:
        return any(topic.startswith(p) for p in self.prefixes)

    def discover(self) -> None:
        graph = self.get_topic_names_and_types()
        if self.bundles:
            for topic, _types in graph:
                m = SWARM_MEMBERS_TOPIC.match(topic)
                if m and topic not in self._members_pending:
                    self._members_pending[topic] = time.monotonic()
                    self._members_readers[topic] = LatchedReader(
                        self, String, topic, lambda msg, base=m.group(1), t=topic: self._on_members(base, t, msg))
        waiting = any(time.monotonic() - t < MEMBERS_WAIT_S for t in self._members_pending.values() if t)
        for topic, types in graph:
            if topic in self.channels or not self.wanted(topic) or not types:
                continue
            parsed = parse_robot_topic(topic)
            if self.bundles and parsed and parsed[1] in ROBOT_DATA and (parsed[0] in self.covered or waiting):
                continue  # written from its swarm's bundle (or perhaps soon: its member list is on the way)
            if self.bundles and topic.endswith("/" + SWARM_BUNDLE) and SWARM_MEMBERS_TOPIC.match(
                    topic[: -len(SWARM_BUNDLE)] + "members"):
                continue  # a bundle is written as the robots' own topics
            pubs = self.get_publishers_info_by_topic(topic)
            if not pubs:
                continue
            latched = any(p.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in pubs)
            best_effort = all(p.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT for p in pubs)
            type_name = types[0]
            try:
                cls = message_class(type_name)
            except (ImportError, AttributeError, ValueError):
                self.get_logger().warning(f"{topic}: type {type_name} not installed, not recorded")
                self.channels[topic] = -1
                continue
            profile = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1 if latched else 1000,
                                 reliability=ReliabilityPolicy.BEST_EFFORT if best_effort else ReliabilityPolicy.RELIABLE,
                                 durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)
            self.channels[topic] = None
            self.joined.append((topic, time.time_ns()))
            offered = qos_yaml(BEST_EFFORT if best_effort else RELIABLE, TRANSIENT_LOCAL if latched else VOLATILE,
                               profile.depth)
            sub = self.create_subscription(cls, topic, self._callback(topic, type_name, offered), profile, raw=True)
            if parsed and parsed[1] in ROBOT_DATA:
                self._robot_subs.setdefault(parsed[0], []).append(sub)

    def _writer(self) -> BagWriter:
        """The bag, created on the first message."""
        if self.bag is None:
            try:
                self.bag = BagWriter(self.out, **self._bag_options)
            except OSError as exc:
                raise ConfigError("out", f"cannot create the bag: {exc.strerror}", "give a writable directory") from None
            self.bag.add_metadata("kilobot_twin.version", {"version": __version__, "started_at_ns": str(self._started_ns)})
        return self.bag

    def _callback(self, topic: str, type_name: str, qos: str):
        time_ns = time.time_ns
        cid = bag = None

        # One-argument callbacks: the EventsExecutor of rclpy 7.1.6 fails on raw callbacks that
        # also take the message info, so publish time = receive time.
        def record(data: bytes) -> None:
            nonlocal cid, bag
            if cid is None:  # the topic's first message: its channel goes into the bag
                bag = self._writer()
                cid = self.channels[topic] = bag.add_topic(topic, type_name, qos)
            bag.write(cid, data, time_ns())

        parsed = parse_robot_topic(topic)
        if parsed and parsed[1] in ROBOT_DATA:
            ack_every = self.ack_every
            covered, last, key = self.covered, self._last, parsed

            def record_robot(data: bytes) -> None:
                if key[0] in covered:
                    return  # its swarm's bundle has it (this subscription is on its way out)
                record(data)
                last[key] = data
                self.robot_messages += 1
                if self.robot_messages % ack_every == 0:
                    self._ack()
            return record_robot

        if topic.endswith("/traits") or topic.endswith("/scenario"):
            def record_document(data: bytes) -> None:
                record(data)
                self._document(topic, data)
            return record_document
        return record

    # --- bundles ------------------------------------------------------------------------------

    def _on_members(self, base: str, topic: str, msg: String) -> None:
        """A swarm covers these robots: from now on they are written from its bundle."""
        self._members_pending[topic] = 0.0
        try:
            ids = [int(i) for i in json.loads(msg.data).get("robots", [])]
        except (ValueError, TypeError, AttributeError):
            self.get_logger().warning(f"{topic}: unreadable member list; its robots are recorded topic by topic")
            return
        new = [i for i in ids if i not in self.covered]
        if not new:
            return
        for rid in new:
            self.covered[rid] = base
            for sub in self._robot_subs.pop(rid, []):
                self.destroy_subscription(sub)
            for kind in ROBOT_DATA:
                if (rid, kind) in self._last:
                    self._handover[(rid, kind)] = stamp_ns(self._last.pop((rid, kind)))
        if not any(b == base for r, b in self.covered.items() if r not in new):
            self.create_subscription(UInt8MultiArray, swarm_bundle_topic(base), self._on_bundle, qos.DATA, raw=True)

    def _robot_channels(self, kind: str, ids) -> tuple[np.ndarray, np.ndarray | None]:
        """Channel ids of ``kind`` for the robots ``ids`` whose topic the ``topics`` prefixes want
        (registered on first use; a topic already in the bag keeps its channel), and which of
        ``ids`` those are (None: all)."""
        key = (kind, ids.tobytes())
        got = self._bundle_cids.get(key)
        if got is None:
            topics = [f"{robot_namespace(rid)}/{kind}" for rid in ids.tolist()]
            keep = np.array([self.wanted(t) for t in topics], dtype=bool)
            cids = []
            for topic in (t for t, k in zip(topics, keep) if k):
                cid = self.channels.get(topic)
                if cid is None or cid < 0:
                    cid = self.channels[topic] = self._writer().add_topic(topic, ROBOT_TYPES[kind], DATA_QOS)
                cids.append(cid)
            got = self._bundle_cids[key] = (np.array(cids, dtype=np.uint16), None if keep.all() else keep)
        return got

    def _on_bundle(self, data: bytes) -> None:
        try:
            blocks = read_bundle(data)
        except (ValueError, struct.error) as exc:
            self.get_logger().error(f"a swarm bundle that does not parse ({exc}): its messages are not in the bag")
            return
        now = time.time_ns()
        written = 0
        for kind, ids, block, size in blocks:
            cids, keep = self._robot_channels(kind, ids)
            if not len(cids):
                continue
            if keep is not None:  # some robots' topics are not wanted
                ids, block = ids[keep], np.frombuffer(block, dtype=f"V{size}")[keep].tobytes()
            if not self._handover:
                self._writer().write_block(cids, block, size, now)
                written += len(cids)
                continue
            for rid, cid, at in zip(ids.tolist(), cids.tolist(), range(0, len(block), size)):
                item = bytes(block[at:at + size])
                if self._take_over(rid, kind, item):
                    self._writer().write(cid, item, now)
                    written += 1
        before = self.robot_messages
        self.robot_messages += written
        if self.robot_messages // self.ack_every != before // self.ack_every:
            self._ack()

    def _take_over(self, rid: int, kind: str, item: bytes) -> bool:
        """Whether a bundle item is new: not already written from the robot's own topic."""
        up_to = self._handover.get((rid, kind))
        if up_to is None:
            return True
        if stamp_ns(item) <= up_to:
            return False
        del self._handover[(rid, kind)]
        return True

    def _ack(self) -> None:
        if self.robot_messages != self._acked:
            self._acked = self.robot_messages
            self.pub_recorded.publish(UInt64(data=self._acked))

    def _document(self, topic: str, data: bytes) -> None:
        try:
            doc = json.loads(deserialize_message(data, String).data)
        except ValueError:
            return
        if topic.endswith("/scenario") and doc.get("format", "").startswith("kilobot-twin/world"):
            self.world_doc = doc
            self.bag.add_metadata("kilobot_twin.world", {k: doc[k] for k in ("seed", "run", "mode", "robots", "scenario")})
        elif topic.endswith("/traits") and "id" in doc:
            self.traits[int(doc["id"])] = doc

    # --- close -------------------------------------------------------------------------------

    def close(self) -> None:
        if self.bag is None:
            self.get_logger().info(f"no message received: no bag written at {self.out}")
            return
        if self.bag.closed:
            return
        doc = self.world_doc or {}
        meta = {"version": __version__, "seed": doc.get("seed", ""), "run": doc.get("run", ""), "mode": doc.get("mode", ""),
                "scenario": doc.get("scenario", {}),
                "traits": {str(k): {"traits": v["traits"], "behavior": v.get("behavior"), "seed": v.get("seed")}
                           for k, v in sorted(self.traits.items())},
                "robots_joined": len(self.traits)}
        self.bag.add_metadata("kilobot_twin", meta)
        self.bag.close({"kilobot_twin_version": __version__, "seed": doc.get("seed", ""), "mode": doc.get("mode", "")})
        n = sum(t["count"] for t in self.bag.topics.values())
        self.get_logger().info(f"bag {self.bag.dir}: {n} messages on {len(self.bag.topics)} topics")


def main(args=None):
    run_node(PROG, RecorderNode, on_exit=RecorderNode.close, args=args)


if __name__ == "__main__":
    main()
