"""rosbag2-layout MCAP bags: write, summarise, repair. No rclpy import.

A bag is a directory ``NAME/`` with ``metadata.yaml`` (rosbag2_bagfile_information, storage
``mcap``) and ``NAME_0.mcap`` (profile ``ros2``, CDR messages, ``ros2msg`` schemas, zstd
chunks). Messages are stored as the serialized bytes received (no round trip).

The MCAP file is written unbuffered, so every chunk the writer has completed is on disk: a
recorder killed with SIGKILL leaves a file without summary from which :func:`repair_bag`
recovers every complete chunk.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import yaml
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, Message, Metadata, Schema
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.writer import CompressionType, Writer

from .. import __version__
from .schemas import ros2msg_schema

ROS_DISTRO = "jazzy"
METADATA_VERSION = 8
#: Bytes of uncompressed messages per chunk: small enough that SIGKILL loses at most a
#: fraction of a second at the rates the twin records.
DEFAULT_CHUNK_BYTES = 256 * 1024


class _DirectFile:
    """A write-through file: each write reaches the OS at once (the writer writes whole records),
    so a SIGKILL never leaves completed chunks in a user-space buffer."""

    def __init__(self, path: Path):
        self._raw = open(path, "wb", buffering=0)
        self._pos = 0

    def write(self, data) -> int:
        view = memoryview(data)
        while view:
            n = self._raw.write(view)
            view = view[n:]
        self._pos += len(data)
        return len(data)

    def tell(self) -> int:
        return self._pos

    def flush(self) -> None:
        pass

    def close(self) -> None:
        self._raw.close()


def mcap_path(bag_dir: str | Path) -> Path:
    d = Path(bag_dir)
    return d / f"{d.name}_0.mcap"


class BagWriter:
    """Write a rosbag2-layout MCAP bag into the directory ``path`` (created; must not exist or be empty)."""

    def __init__(self, path: str | Path, chunk_size: int = DEFAULT_CHUNK_BYTES, compression: str = "zstd"):
        self.dir = Path(path)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.file_path = mcap_path(self.dir)
        self._f = _DirectFile(self.file_path)
        comp = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}[compression]
        self.compression = compression
        self._w = Writer(self._f, chunk_size=chunk_size, compression=comp)
        self._w.start(profile="ros2", library=f"kilobot_twin {__version__} (mcap-python)")
        self._schemas: dict[str, int] = {}
        self.topics: dict[int, dict] = {}  # channel id -> {name, type, qos, count}
        self._seq = 0
        self.first_ns: int | None = None
        self.last_ns = 0
        self.closed = False

    def add_topic(self, topic: str, type_name: str, qos_yaml: str = "") -> int:
        """Register a channel (and its schema once per type); returns the channel id."""
        sid = self._schemas.get(type_name)
        if sid is None:
            sid = self._w.register_schema(type_name, "ros2msg", ros2msg_schema(type_name).encode())
            self._schemas[type_name] = sid
        cid = self._w.register_channel(topic, "cdr", sid, {"offered_qos_profiles": qos_yaml})
        self.topics[cid] = {"name": topic, "type": type_name, "qos": qos_yaml, "count": 0}
        return cid

    def write(self, channel_id: int, data: bytes, log_time_ns: int, publish_time_ns: int | None = None) -> None:
        self._seq += 1
        self._w.add_message(channel_id, log_time_ns, data, log_time_ns if publish_time_ns is None else publish_time_ns,
                            self._seq)
        self.topics[channel_id]["count"] += 1
        if self.first_ns is None:
            self.first_ns = log_time_ns
        if log_time_ns > self.last_ns:
            self.last_ns = log_time_ns

    def add_metadata(self, name: str, data: dict) -> None:
        """An MCAP metadata record (string values; non-strings are stored as JSON)."""
        self._w.add_metadata(name, {k: v if isinstance(v, str) else json.dumps(v, sort_keys=True) for k, v in data.items()})

    def close(self, custom_data: dict | None = None) -> Path:
        """Write the summary (index, statistics) and ``metadata.yaml``."""
        if self.closed:
            return self.dir
        self._w.finish()
        self._f.close()
        self.closed = True
        write_metadata_yaml(self.dir, list(self.topics.values()), self.first_ns or 0, self.last_ns,
                            self.compression, custom_data)
        return self.dir


def qos_yaml(reliability: int, durability: int, depth: int, history: int = 1) -> str:
    """rosbag2's offered_qos_profiles string for one publisher (ints as in rmw: reliable=1,
    best_effort=2; transient_local=1, volatile=2; keep_last=1)."""
    inf = {"sec": 2147483647, "nsec": 4294967295}
    return yaml.safe_dump([{"history": history, "depth": depth, "reliability": reliability, "durability": durability,
                            "deadline": inf, "lifespan": inf, "liveliness": 1, "liveliness_lease_duration": inf,
                            "avoid_ros_namespace_conventions": False}], sort_keys=False)


def write_metadata_yaml(bag_dir: Path, topics: list[dict], first_ns: int, last_ns: int, compression: str,
                        custom_data: dict | None = None) -> Path:
    total = sum(t["count"] for t in topics)
    rel = mcap_path(bag_dir).name
    info = {
        "version": METADATA_VERSION,
        "storage_identifier": "mcap",
        "duration": {"nanoseconds": max(0, last_ns - first_ns)},
        "starting_time": {"nanoseconds_since_epoch": first_ns},
        "message_count": total,
        "topics_with_message_count": [
            {"topic_metadata": {"name": t["name"], "type": t["type"], "serialization_format": "cdr",
                                "offered_qos_profiles": t["qos"], "type_description_hash": ""},
             "message_count": t["count"]}
            for t in topics
        ],
        # Compression is inside the MCAP chunks (storage-level), not rosbag2 file/message compression.
        "compression_format": "",
        "compression_mode": "",
        "relative_file_paths": [rel],
        "files": [{"path": rel, "starting_time": {"nanoseconds_since_epoch": first_ns},
                   "duration": {"nanoseconds": max(0, last_ns - first_ns)}, "message_count": total}],
        "custom_data": {k: str(v) for k, v in (custom_data or {}).items()},
        "ros_distro": ROS_DISTRO,
    }
    path = Path(bag_dir) / "metadata.yaml"
    path.write_text(yaml.safe_dump({"rosbag2_bagfile_information": info}, sort_keys=False))
    return path


# --- reading ------------------------------------------------------------------------------------

def summary_counts(bag_dir: str | Path) -> dict[str, int]:
    """Messages per topic from the MCAP summary (statistics)."""
    with open(mcap_path(bag_dir), "rb") as f:
        summ = make_reader(f).get_summary()
        counts = summ.statistics.channel_message_counts
        return {summ.channels[cid].topic: n for cid, n in counts.items()}


def read_metadata(bag_dir: str | Path) -> dict[str, dict]:
    """MCAP metadata records by name."""
    with open(mcap_path(bag_dir), "rb") as f:
        return {m.name: dict(m.metadata) for m in make_reader(f).iter_metadata()}


# --- repair -----------------------------------------------------------------------------------------

def repair_bag(bag_dir: str | Path) -> dict:
    """Rewrite a bag whose MCAP file lacks its summary (recorder killed): every complete chunk is kept.

    The damaged file is kept as ``NAME_0.mcap.damaged``. Returns counts of what was recovered.
    """
    bag_dir = Path(bag_dir)
    src = mcap_path(bag_dir)
    if not src.is_file():
        from ..errors import ConfigError

        raise ConfigError(str(bag_dir), f"no {src.name} in the bag directory", "give a bag directory written by the recorder")
    damaged = src.with_suffix(".mcap.damaged")
    os.replace(src, damaged)
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    metadata: list[Metadata] = []
    messages: list[Message] = []
    complete_chunks = 0
    error = None
    with open(damaged, "rb") as f:
        reader = StreamReader(f, skip_magic=False, emit_chunks=True, validate_crcs=True)
        try:
            for rec in reader.records:
                if isinstance(rec, Chunk):
                    inner = _chunk_records(rec)  # raises on a cut-off chunk: it is not counted
                    complete_chunks += 1
                else:
                    inner = [rec]
                for r in inner:
                    if isinstance(r, Schema):
                        schemas[r.id] = r
                    elif isinstance(r, Channel):
                        channels[r.id] = r
                    elif isinstance(r, Metadata):
                        metadata.append(r)
                    elif isinstance(r, Message):
                        messages.append(r)
        except Exception as exc:  # the truncated tail: stop at the first incomplete record
            error = f"{type(exc).__name__}: {exc}"
    w = BagWriter.__new__(BagWriter)
    BagWriter.__init__(w, bag_dir)
    sid_map, cid_map = {}, {}
    for cid, ch in channels.items():
        sc = schemas.get(ch.schema_id)
        if sc is None:
            continue
        if sc.name not in w._schemas:
            w._schemas[sc.name] = w._w.register_schema(sc.name, sc.encoding, sc.data)
        sid_map[ch.schema_id] = w._schemas[sc.name]
        new = w._w.register_channel(ch.topic, ch.message_encoding, sid_map[ch.schema_id], dict(ch.metadata))
        w.topics[new] = {"name": ch.topic, "type": sc.name, "qos": ch.metadata.get("offered_qos_profiles", ""), "count": 0}
        cid_map[cid] = new
    for m in metadata:
        w.add_metadata(m.name, dict(m.metadata))
    w.add_metadata("repair", {"repaired_at_ns": str(time.time_ns()), "complete_chunks": str(complete_chunks),
                              "stopped_at": error or "end of file"})
    messages.sort(key=lambda m: (m.log_time, m.sequence))
    for m in messages:
        if m.channel_id in cid_map:
            w.write(cid_map[m.channel_id], m.data, m.log_time, m.publish_time)
    w.close({"repaired": "true"})
    return {"chunks": complete_chunks, "messages": len(messages), "channels": len(cid_map), "stopped_at": error}


def _chunk_records(chunk: Chunk) -> list:
    """The records inside one chunk (raises if the chunk is corrupt)."""
    return breakup_chunk(chunk, validate_crc=True)
