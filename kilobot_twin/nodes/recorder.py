"""``recorder``: every robot, world and analysis topic into a rosbag2-layout MCAP bag (what it
records and ``~/recorded``: README, "nodes"; the file: :mod:`kilobot_twin.recording.bag`).

Parameters: ``out`` (bag directory, default ``bags/<UTC time>``), ``topics`` (comma-separated
prefixes, default ``/kilobot_,/swarm,/world,/analysis,/clock``), ``discovery_period_s`` (how often
the graph is searched for new topics), ``chunk_bytes``, ``compression`` (zstd, lz4, none),
``ack_every`` (``~/recorded`` is published every this many robot messages and at 20 Hz when it
changed). Subscriptions are raw (the bytes received are written as they are); transient-local
publishers are subscribed transient-local, so that their one message is recorded even if it
was published before the recorder joined. ``metadata.yaml`` is written on shutdown.
"""

from __future__ import annotations

import importlib
import json
import time
from datetime import datetime, timezone

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from std_msgs.msg import String, UInt64

from .. import __version__
from ..outputs import check_out_dir
from ..errors import ConfigError
from ..ros import params, qos
from ..recording.bag import DEFAULT_CHUNK_BYTES, BagWriter
from ..recording.topics import (BEST_EFFORT, RELIABLE, ROBOT_DATA, TRANSIENT_LOCAL, VOLATILE, parse_robot_topic,
                                 qos_yaml)
from ..ros.executors import run_node

PROG = "kilobot-twin recorder"
#: Robot data topics: what the recorder acknowledges on ``~/recorded`` (the world's back-pressure).


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
        self.create_timer(0.05, self._ack)
        self.create_timer(period, self.discover)
        self.discover()

    # --- discovery ---------------------------------------------------------------------------

    def wanted(self, topic: str) -> bool:
        return any(topic.startswith(p) for p in self.prefixes)

    def discover(self) -> None:
        for topic, types in self.get_topic_names_and_types():
            if topic in self.channels or not self.wanted(topic) or not types:
                continue
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
            qos = qos_yaml(BEST_EFFORT if best_effort else RELIABLE, TRANSIENT_LOCAL if latched else VOLATILE,
                           profile.depth)
            self.create_subscription(cls, topic, self._callback(topic, type_name, qos), profile, raw=True)

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

            def record_robot(data: bytes) -> None:
                record(data)
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
