"""rosbag2-layout MCAP bags: write, read (also when damaged), repair. The only module that opens
MCAP files; no rclpy import.

A bag is a directory ``NAME/`` with ``metadata.yaml`` (rosbag2_bagfile_information, storage
``mcap``) and ``NAME_0.mcap`` (profile ``ros2``, CDR messages, ``ros2msg`` schemas, zstd
chunks). Messages are stored as the serialized bytes received (no round trip).

The MCAP file is written unbuffered, so every chunk the writer has completed is on disk: a
recorder killed with SIGKILL leaves a file without summary. :class:`BagReader` reads a file
record by record from the start and does not need the summary: every chunk carries its own
lengths and the CRC of its content, so a damaged chunk is skipped, the reader finds the next
record (a chunk is recognised by opcode 0x06, consistent lengths and its CRC) and goes on.
What was skipped is said in one line (:attr:`BagReader.note`, also issued as a
:class:`BagDamageWarning`). :func:`repair_bag` writes what is intact into a clean file.
"""

from __future__ import annotations

import io
import json
import mmap
import os
import re
import shutil
import struct
import time
import warnings
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator, NamedTuple

import yaml
import numpy as np
from mcap.data_stream import ReadDataStream, RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (Attachment, AttachmentIndex, Channel, Chunk, ChunkIndex, DataEnd, Footer, Header, Message,
                          Metadata, MetadataIndex, Schema, Statistics, SummaryOffset)

from .. import __version__
from ..errors import ConfigError
from .schemas import ros2msg_schema

ROS_DISTRO = "jazzy"
METADATA_VERSION = 8
#: Bytes of uncompressed messages per chunk: small enough that SIGKILL loses at most a
#: fraction of a second at the rates the twin records.
DEFAULT_CHUNK_BYTES = 256 * 1024
MAGIC = b"\x89MCAP0\r\n"
#: Largest chunk content accepted (a damaged size field must not allocate gigabytes).
MAX_CHUNK_BYTES = 1 << 30


class BagDamageWarning(UserWarning):
    """A bag was read in part: the message says what was skipped."""


def mcap_path(bag_dir: str | Path) -> Path:
    d = Path(bag_dir)
    return d / f"{d.name}_0.mcap"


def repair_hint(bag_dir: str | Path) -> str:
    return f"`kilobot-twin bag repair {bag_dir}` writes a clean bag of what is intact"


def _check_bag_dir(bag_dir: str | Path) -> Path:
    """The bag's MCAP file, or the one-line error for anything that is not a bag directory."""
    d = Path(bag_dir)
    fix = "give a bag directory bags/NAME written by `kilobot-twin run` or `import`"
    if d.is_file():
        raise ConfigError(str(d), "is a file, not a bag directory", fix)
    if not d.is_dir():
        raise ConfigError(str(d), "no such bag directory", fix)
    path = mcap_path(d)
    if not path.is_file():
        if (d / "observations.csv").exists() or (d / "meta.yaml").exists():
            fix = f"this is a measured dataset: make a bag of it with `kilobot-twin import {d} --out bags/NAME`"
        raise ConfigError(str(d), f"no {path.name} in the bag directory", fix)
    return path


# --- writing --------------------------------------------------------------------------------------

class _DirectFile:
    """A write-through file: each write reaches the OS at once (the writer writes whole records),
    so a SIGKILL never leaves completed chunks in a user-space buffer. Never replaces a file."""

    def __init__(self, path: Path):
        self._raw = open(path, "xb", buffering=0)
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


#: A Message record's opcode, length and fixed fields (channel, sequence, log and publish time), packed.
_MESSAGE_RECORD = [("op", "u1"), ("len", "<u8"), ("cid", "<u2"), ("seq", "<u4"), ("log", "<u8"), ("pub", "<u8")]
_MESSAGE_RECORD_BYTES = 31
_MESSAGE_HEAD_PACK = struct.Struct("<BQHIQQ").pack
_BLOCK_DTYPES: dict[int, np.dtype] = {}


class _ChunkedMcapWriter:
    """An indexed, chunked MCAP writer whose messages are added in blocks.

    mcap's own ``Writer`` costs about 7 us of Python per message (a record object, its fields
    written one by one, an index tuple); a 200-robot swarm in lockstep at 20x real time needs
    120,000 messages a second. Here a block of messages of one size (a swarm bundle's poses, say)
    becomes one NumPy record array: its Message records and their message-index entries are
    built without a Python step per message. Every other record (header, schema, channel,
    chunk, message index, metadata, statistics, summary, footer) is mcap's own record class,
    laid out as mcap's ``Writer`` lays them out (schemas and channels inside the chunks and
    repeated in the summary; chunk, metadata and summary-offset indexes; CRCs of chunks and
    summary). Readers other than ours (mcap, rosbags, rerun, Foxglove's @mcap/core) check it.
    """

    def __init__(self, stream, chunk_size: int, compression: str, library: str):
        self._f = stream
        self._chunk_size = chunk_size
        self._compression = "" if compression == "none" else compression
        if self._compression == "zstd":
            import zstandard

            self._compress = zstandard.ZstdCompressor().compress
        elif self._compression == "lz4":
            import lz4.frame

            self._compress = lz4.frame.compress
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self._counts = np.zeros(64, dtype=np.int64)  # messages per channel id
        self._chunk_indexes: list[ChunkIndex] = []
        self._metadata_indexes: list[MetadataIndex] = []
        self.message_count = self.metadata_count = 0
        self.start_time: int | None = None
        self.end_time = 0
        self._reset_chunk()
        self._f.write(MAGIC)
        self._write_record(Header(profile="ros2", library=library))

    def _write_record(self, record) -> None:
        b = RecordBuilder()
        record.write(b)
        self._f.write(b.end())

    def _reset_chunk(self) -> None:
        self._parts: list[bytes] = []
        self._chunk_len = 0
        self._ix: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # (channel, log time, offset) per block
        self._single: list[tuple[int, int, int]] = []  # (channel, log time, offset) of single messages
        self._chunk_start: int | None = None
        self._chunk_end = 0

    def _add_to_chunk(self, data: bytes) -> None:
        self._parts.append(data)
        self._chunk_len += len(data)
        if self._chunk_len > self._chunk_size:
            self._finalize_chunk()

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        sid = len(self.schemas) + 1
        self.schemas[sid] = Schema(id=sid, name=name, encoding=encoding, data=data)
        b = RecordBuilder()
        self.schemas[sid].write(b)
        self._add_to_chunk(b.end())
        return sid

    def register_channel(self, topic: str, message_encoding: str, schema_id: int, metadata: dict) -> int:
        cid = len(self.channels) + 1
        if cid >= 1 << 16:
            raise ValueError("an MCAP file holds at most 65,535 channels")
        self.channels[cid] = Channel(id=cid, topic=topic, message_encoding=message_encoding, schema_id=schema_id,
                                     metadata=metadata)
        if cid >= len(self._counts):
            self._counts = np.concatenate([self._counts, np.zeros(len(self._counts), dtype=np.int64)])
        b = RecordBuilder()
        self.channels[cid].write(b)
        self._add_to_chunk(b.end())
        return cid

    def add_message(self, channel_id: int, sequence: int, log_time: int, publish_time: int, data) -> None:
        """One message (record built with struct: cheaper than NumPy for one)."""
        self._single.append((channel_id, log_time, self._chunk_len))
        self._counts[channel_id] += 1
        self._times(log_time, 1)
        self._add_to_chunk(_MESSAGE_HEAD_PACK(Opcode.MESSAGE, _MESSAGE_RECORD_BYTES - 9 + len(data), channel_id,
                                              sequence & 0xFFFFFFFF, log_time, publish_time) + bytes(data))

    def add_block(self, channel_ids, sequence0: int, log_time: int, publish_time: int, block, size: int) -> None:
        """Messages of ``size`` bytes each, message ``i`` = ``block[i * size:(i + 1) * size]`` on
        channel ``channel_ids[i]``, sequence numbers from ``sequence0``."""
        cids = np.asarray(channel_ids, dtype=np.uint16)
        k = cids.shape[0]
        if k == 0:
            return
        dtype = _BLOCK_DTYPES.get(size)
        if dtype is None:
            dtype = _BLOCK_DTYPES[size] = np.dtype(_MESSAGE_RECORD + ([("data", f"V{size}")] if size else []))
        rec = np.empty(k, dtype=dtype)
        rec["op"] = Opcode.MESSAGE
        rec["len"] = _MESSAGE_RECORD_BYTES - 9 + size
        rec["cid"] = cids
        rec["seq"] = (np.arange(sequence0, sequence0 + k, dtype=np.uint64) & 0xFFFFFFFF).astype(np.uint32)
        rec["log"] = log_time
        rec["pub"] = publish_time
        if size:
            rec["data"] = np.frombuffer(block, dtype=f"V{size}", count=k)
        step = _MESSAGE_RECORD_BYTES + size
        self._ix.append((cids, np.full(k, log_time, dtype=np.uint64),
                         self._chunk_len + step * np.arange(k, dtype=np.uint64)))
        np.add.at(self._counts, cids, 1)
        self._times(log_time, k)
        self._add_to_chunk(rec.tobytes())

    def _times(self, log_time: int, k: int) -> None:
        self.message_count += k
        if self.start_time is None or log_time < self.start_time:
            self.start_time = log_time
        if log_time > self.end_time:
            self.end_time = log_time
        if self._chunk_start is None or log_time < self._chunk_start:
            self._chunk_start = log_time
        if log_time > self._chunk_end:
            self._chunk_end = log_time

    def channel_counts(self) -> dict[int, int]:
        return {int(c): int(n) for c, n in enumerate(self._counts) if n}

    def add_metadata(self, name: str, data: dict) -> None:
        offset = self._f.tell()
        b = RecordBuilder()
        Metadata(name=name, metadata=data).write(b)
        raw = b.end()
        self._f.write(raw)
        self._metadata_indexes.append(MetadataIndex(offset=offset, length=len(raw), name=name))
        self.metadata_count += 1

    def _finalize_chunk(self) -> None:
        if not self._ix and not self._single:  # schemas and channels alone wait for the first message
            return
        raw = b"".join(self._parts)
        data = self._compress(raw) if self._compression else raw
        chunk = Chunk(compression=self._compression, data=data, message_start_time=self._chunk_start,
                      message_end_time=self._chunk_end, uncompressed_crc=zlib.crc32(raw), uncompressed_size=len(raw))
        start = self._f.tell()
        b = RecordBuilder()
        chunk.write(b)
        chunk_bytes = b.end()
        self._f.write(chunk_bytes)
        # Message indexes: per channel, (log time, offset in the uncompressed chunk), in order.
        if self._single:
            single = np.array(self._single, dtype=np.uint64).reshape(-1, 3)
            self._ix.append((single[:, 0].astype(np.uint16), single[:, 1], single[:, 2]))
        cids = np.concatenate([c for c, _, _ in self._ix])
        logs = np.concatenate([t for _, t, _ in self._ix])
        offs = np.concatenate([o for _, _, o in self._ix])
        if len(self._ix) > 1:  # singles and blocks interleave: index entries in file order
            by_offset = np.argsort(offs, kind="stable")
            cids, logs, offs = cids[by_offset], logs[by_offset], offs[by_offset]
        order = np.argsort(cids, kind="stable")
        cids, pairs = cids[order], np.stack([logs[order], offs[order]], axis=1).astype("<u8")
        bounds = np.flatnonzero(np.diff(cids)) + 1
        index_start = self._f.tell()
        offsets, parts, pos = {}, [], index_start
        for lo, hi in zip(np.concatenate([[0], bounds]).tolist(), np.concatenate([bounds, [len(cids)]]).tolist()):
            cid = int(cids[lo])
            body = pairs[lo:hi].tobytes()
            record = struct.pack("<BQHI", Opcode.MESSAGE_INDEX, 2 + 4 + len(body), cid, len(body)) + body
            offsets[cid] = pos
            pos += len(record)
            parts.append(record)
        self._f.write(b"".join(parts))
        self._chunk_indexes.append(ChunkIndex(
            message_start_time=self._chunk_start, message_end_time=self._chunk_end, chunk_start_offset=start,
            chunk_length=len(chunk_bytes), message_index_offsets=offsets, message_index_length=pos - index_start,
            compression=self._compression, compressed_size=len(data), uncompressed_size=len(raw)))
        self._reset_chunk()

    def finish(self) -> None:
        """The last chunk, the data end, the summary (repeated schemas and channels, statistics,
        chunk and metadata indexes, summary offsets) and the footer."""
        self._finalize_chunk()
        self._write_record(DataEnd(data_section_crc=0))
        summary_start = self._f.tell()
        b = RecordBuilder()
        offsets = []

        def group(opcode, records) -> None:
            start = b.count
            for r in records:
                r.write(b)
            offsets.append(SummaryOffset(group_opcode=opcode, group_start=summary_start + start,
                                         group_length=b.count - start))

        counts = self.channel_counts()
        group(Opcode.SCHEMA, self.schemas.values())
        group(Opcode.CHANNEL, self.channels.values())
        group(Opcode.STATISTICS, [Statistics(
            message_count=self.message_count, schema_count=len(self.schemas), channel_count=len(self.channels),
            attachment_count=0, metadata_count=self.metadata_count, chunk_count=len(self._chunk_indexes),
            message_start_time=self.start_time or 0, message_end_time=self.end_time, channel_message_counts=counts)])
        group(Opcode.CHUNK_INDEX, self._chunk_indexes)
        group(Opcode.METADATA_INDEX, self._metadata_indexes)
        offset_start = summary_start + b.count
        for o in offsets:
            o.write(b)
        summary = b.end()
        crc = zlib.crc32(struct.pack("<BQQQ", Opcode.FOOTER, 20, summary_start, offset_start), zlib.crc32(summary))
        self._f.write(summary)
        self._write_record(Footer(summary_start=summary_start, summary_offset_start=offset_start, summary_crc=crc))
        self._f.write(MAGIC)


class BagWriter:
    """Write a rosbag2-layout MCAP bag into the directory ``path`` (created if needed; an existing
    MCAP file is never replaced). Usable as a context manager (closes on leaving).

    ``file_path`` writes the MCAP file elsewhere (repair writes beside the damaged one).
    """

    def __init__(self, path: str | Path, chunk_size: int = DEFAULT_CHUNK_BYTES, compression: str = "zstd",
                 file_path: str | Path | None = None):
        self.dir = Path(path)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.file_path = Path(file_path) if file_path is not None else mcap_path(self.dir)
        if compression not in ("zstd", "lz4", "none"):
            raise ValueError(f"compression {compression!r}: use zstd, lz4 or none")
        self._f = _DirectFile(self.file_path)
        self.compression = compression
        self._w = _ChunkedMcapWriter(self._f, chunk_size, compression, f"kilobot_twin {__version__}")
        self._schemas: dict[str, int] = {}
        self.topics: dict[int, dict] = {}  # channel id -> {name, type, qos, count}
        self._seq = 0
        self.first_ns: int | None = None
        self.last_ns = 0
        self.closed = False

    def __enter__(self) -> "BagWriter":
        return self

    def __exit__(self, exc_type, *_exc) -> None:
        if exc_type is None:
            self.close()
        else:
            self.finish()   # a readable file, but no metadata.yaml: the run did not end well

    def finish(self) -> None:
        """Write the MCAP summary and close the file (no ``metadata.yaml``)."""
        if not self.closed:
            self._sync_counts()
            self._w.finish()
            self._f.close()
            self.closed = True

    def add_topic(self, topic: str, type_name: str, qos_yaml: str = "") -> int:
        """Register a channel (and its schema once per type); returns the channel id."""
        return self.add_raw_channel(topic, type_name, "ros2msg", ros2msg_schema(type_name).encode(), "cdr",
                                    {"offered_qos_profiles": qos_yaml})

    def add_raw_channel(self, topic: str, schema_name: str, schema_encoding: str, schema_data: bytes,
                        message_encoding: str = "cdr", metadata: dict | None = None) -> int:
        """Register a channel with a schema given as stored (the first schema of a name is kept)."""
        sid = self._schemas.get(schema_name)
        if sid is None:
            sid = self._schemas[schema_name] = self._w.register_schema(schema_name, schema_encoding, schema_data)
        meta = dict(metadata or {})
        cid = self._w.register_channel(topic, message_encoding, sid, meta)
        self.topics[cid] = {"name": topic, "type": schema_name, "qos": meta.get("offered_qos_profiles", ""), "count": 0}
        return cid

    def write(self, channel_id: int, data: bytes, log_time_ns: int, publish_time_ns: int | None = None) -> None:
        """One message."""
        self._seq += 1
        self._w.add_message(channel_id, self._seq, log_time_ns, log_time_ns if publish_time_ns is None else publish_time_ns,
                            data)
        self._logged(log_time_ns)

    def write_block(self, channel_ids, block, size: int, log_time_ns: int, publish_time_ns: int | None = None) -> None:
        """Messages of ``size`` bytes each: message ``i`` is ``block[i * size:(i + 1) * size]`` on
        channel ``channel_ids[i]``, all logged at ``log_time_ns`` (a swarm bundle's block)."""
        self._w.add_block(channel_ids, self._seq + 1, log_time_ns,
                          log_time_ns if publish_time_ns is None else publish_time_ns, block, size)
        self._seq += len(channel_ids)
        self._logged(log_time_ns)

    def _logged(self, log_time_ns: int) -> None:
        if self.first_ns is None:
            self.first_ns = log_time_ns
        if log_time_ns > self.last_ns:
            self.last_ns = log_time_ns

    def count(self, channel_id: int) -> int:
        """Messages written on a channel so far."""
        return int(self._w._counts[channel_id])

    def _sync_counts(self) -> None:
        for cid, t in self.topics.items():
            t["count"] = self.count(cid)

    def add_metadata(self, name: str, data: dict) -> None:
        """An MCAP metadata record (string values; non-strings are stored as JSON)."""
        self._w.add_metadata(name, {k: v if isinstance(v, str) else json.dumps(v, sort_keys=True) for k, v in data.items()})

    def close(self, custom_data: dict | None = None, base_info: dict | None = None) -> Path:
        """Write the summary (index, statistics) and ``metadata.yaml`` (``base_info``: a previous
        rosbag2_bagfile_information whose other fields are kept)."""
        if self.closed:
            return self.dir
        self.finish()
        write_metadata_yaml(self.dir, list(self.topics.values()), self.first_ns or 0, self.last_ns,
                            self.compression, custom_data, base_info)
        return self.dir


def write_metadata_yaml(bag_dir: Path, topics: list[dict], first_ns: int, last_ns: int, compression: str,
                        custom_data: dict | None = None, base_info: dict | None = None) -> Path:
    """rosbag2's ``metadata.yaml``; ``base_info`` keeps what an earlier file said (counts, times and
    files are recomputed, topics and custom data are merged)."""
    total = sum(t["count"] for t in topics)
    rel = mcap_path(bag_dir).name
    base = dict(base_info or {})
    old_topics = {}
    for t in base.get("topics_with_message_count") or []:
        try:
            old_topics[t["topic_metadata"]["name"]] = t
        except (TypeError, KeyError):
            continue
    entries = []
    for t in topics:
        meta = {"name": t["name"], "type": t["type"], "serialization_format": "cdr",
                "offered_qos_profiles": t["qos"], "type_description_hash": ""}
        old = old_topics.pop(t["name"], None)
        if old is not None and isinstance(old.get("topic_metadata"), dict):
            meta = {**meta, **old["topic_metadata"]}
        entries.append({"topic_metadata": meta, "message_count": t["count"]})
    entries += [{**t, "message_count": 0} for t in old_topics.values()]   # recorded, nothing recovered
    custom = base.get("custom_data") if isinstance(base.get("custom_data"), dict) else {}
    info = {
        "version": METADATA_VERSION,
        "storage_identifier": "mcap",
        **base,
        "duration": {"nanoseconds": max(0, last_ns - first_ns)},
        "starting_time": {"nanoseconds_since_epoch": first_ns},
        "message_count": total,
        "topics_with_message_count": entries,
        # Compression is inside the MCAP chunks (storage-level), not rosbag2 file/message compression.
        "compression_format": "",
        "compression_mode": "",
        "relative_file_paths": [rel],
        "files": [{"path": rel, "starting_time": {"nanoseconds_since_epoch": first_ns},
                   "duration": {"nanoseconds": max(0, last_ns - first_ns)}, "message_count": total}],
        "custom_data": {**{str(k): str(v) for k, v in custom.items()},
                        **{k: str(v) for k, v in (custom_data or {}).items()}},
        "ros_distro": base.get("ros_distro", ROS_DISTRO),
    }
    path = Path(bag_dir) / "metadata.yaml"
    path.write_text(yaml.safe_dump({"rosbag2_bagfile_information": info}, sort_keys=False))
    return path


# --- reading --------------------------------------------------------------------------------------

class BagMessage(NamedTuple):
    topic: str
    type: str
    log_time_ns: int
    publish_time_ns: int
    data: bytes


class _Bad(Exception):
    """A record that does not parse (the reason is said to the user)."""


_U64 = struct.Struct("<Q")
_CHUNK_HEAD = struct.Struct("<QQQII")
_MESSAGE_HEAD = struct.Struct("<HIQQ")
# Opcodes a scan may resynchronise on, followed by a length below 4 GiB (its high 4 bytes zero).
_RESYNC = re.compile(rb"[\x02\x03\x04\x06\x07\x08\x0b\x0c\x0d\x0e\x0f][\x00-\xff]{4}\x00\x00\x00\x00", re.DOTALL)


def _exact(cls, payload: bytes, *args):
    """Parse one record with mcap's reader; it must use every byte of its payload."""
    stream = ReadDataStream(io.BytesIO(payload))
    try:
        rec = cls.read(stream, *args)
    except Exception as exc:  # noqa: BLE001 - any parse failure of damaged bytes is a bad record
        raise _Bad(f"unreadable {cls.__name__.lower()} record ({type(exc).__name__})") from None
    if stream.count != len(payload):
        raise _Bad(f"inconsistent {cls.__name__.lower()} record")
    return rec


def _chunk_content(payload: bytes) -> tuple[int, int, bytes]:
    """(start time, end time, uncompressed records) of a chunk record; raises :class:`_Bad`."""
    if len(payload) < _CHUNK_HEAD.size + 8:
        raise _Bad("chunk too short")
    start, end, size, crc, clen = _CHUNK_HEAD.unpack_from(payload, 0)
    off = _CHUNK_HEAD.size
    comp = bytes(payload[off:off + clen])
    off += clen
    if clen > 16 or off + 8 > len(payload):
        raise _Bad("chunk header is damaged")
    (dlen,) = _U64.unpack_from(payload, off)
    off += 8
    if off + dlen != len(payload):
        raise _Bad("chunk lengths disagree")
    data = payload[off:]
    if size > MAX_CHUNK_BYTES:
        raise _Bad("chunk header is damaged")
    try:
        if comp == b"zstd":
            import zstandard

            raw = zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
        elif comp == b"lz4":
            import lz4.frame

            raw = lz4.frame.decompress(data)
        elif comp in (b"", b"none"):
            raw = bytes(data)
        else:
            raise _Bad("chunk header is damaged (unknown compression)")
    except _Bad:
        raise
    except Exception as exc:  # noqa: BLE001 - zstd/lz4 report corrupt data in their own types
        raise _Bad(f"corrupt compressed data ({type(exc).__name__})") from None
    if len(raw) != size:
        raise _Bad("content size disagrees with the chunk header")
    if crc and zlib.crc32(raw) != crc:
        raise _Bad("CRC mismatch")
    return start, end, raw


def _chunk_records(raw: bytes) -> list:
    """Schemas, channels and messages inside a chunk's (CRC-checked) content."""
    out, pos = [], 0
    while pos < len(raw):
        if pos + 9 > len(raw):
            raise _Bad("chunk content ends inside a record")
        op = raw[pos]
        (n,) = _U64.unpack_from(raw, pos + 1)
        body = raw[pos + 9:pos + 9 + n]
        if len(body) != n:
            raise _Bad("chunk content ends inside a record")
        if op == 0x03:
            out.append(_exact(Schema, body))
        elif op == 0x04:
            out.append(_exact(Channel, body))
        elif op == 0x05:
            if n < _MESSAGE_HEAD.size:
                raise _Bad("message record too short")
            cid, seq, log, pub = _MESSAGE_HEAD.unpack_from(body, 0)
            out.append(Message(channel_id=cid, sequence=seq, log_time=log, publish_time=pub,
                               data=bytes(body[_MESSAGE_HEAD.size:])))
        pos += 9 + n
    return out


@dataclass
class _Scan:
    """Everything a record-by-record pass over one MCAP file found."""

    size: int
    schemas: dict = field(default_factory=dict)
    channels: dict = field(default_factory=dict)
    metadata: dict = field(default_factory=dict)
    messages: list = field(default_factory=list)
    chunk_offsets: list = field(default_factory=list)   # file offsets of chunks read
    bad_chunks: list = field(default_factory=list)      # (offset, reason)
    skipped: list = field(default_factory=list)         # (from byte, to byte, reason): not understood
    index_offsets: list = field(default_factory=list)   # chunk offsets from the summary's chunk index
    stats: Statistics | None = None
    magic_ok: bool = True
    records: int = 0
    footer: bool = False
    footer_at: int = 0
    summary_start: int = 0
    summary_crc: int = 0
    summary_damaged: bool = False
    top: list = field(default_factory=list)             # (offset, record) outside chunks, to be checked
    loose: list = field(default_factory=list)           # (from, to, message) outside chunks, to be checked
    data_end: int | None = None
    truncated_at: int | None = None


def _scan(buf) -> _Scan:
    s = _Scan(size=len(buf))
    s.magic_ok = bytes(buf[:8]) == MAGIC
    pos = 8 if s.magic_ok else 0
    if not s.magic_ok:
        pos = _resync(buf, 0, s)
    while pos < s.size:
        if s.footer:
            if bytes(buf[pos:]) != MAGIC:
                s.skipped.append((pos, s.size, "unexpected bytes after the footer"))
            break
        op = buf[pos]
        if pos + 9 > s.size:
            s.truncated_at = pos
            break
        (n,) = _U64.unpack_from(buf, pos + 1)
        end = pos + 9 + n
        if not 0x01 <= op <= 0x0F or end > s.size:
            nxt = _resync(buf, pos + 1, s)
            if nxt >= s.size and 0x01 <= op <= 0x0F and end > s.size:
                s.truncated_at = pos   # a plausible record cut off by the end of the file
                break
            s.skipped.append((pos, nxt, "unreadable bytes"))
            pos = nxt
            continue
        try:
            _record(s, op, pos, buf[pos + 9:end])
        except _Bad as exc:
            if op == 0x06 and _framing_ok(buf[pos + 9:end]):
                s.bad_chunks.append((pos, str(exc)))   # its lengths hold: only its content is lost
                pos = end
                continue
            nxt = _resync(buf, pos + 1, s)
            s.skipped.append((pos, nxt, str(exc)))
            pos = nxt
            continue
        s.records += 1
        pos = end
    _take_top_level(s, buf)
    _take_loose_messages(s)
    return s


def _take_loose_messages(s: _Scan) -> None:
    """Messages outside chunks are MCAP's unchunked layout; they carry no CRC. In a file that
    has chunks they are other records with a damaged opcode (a message index's 0x07 with one bit
    flipped is a plausible message on a real channel), so they are skipped there."""
    if not (s.chunk_offsets or s.bad_chunks):
        s.messages.extend(m for _a, _b, m in s.loose)
        return
    for a, b, _m in s.loose:
        s.skipped.append((a, b, "a message record outside the chunks of a chunked file"))
    s.skipped.sort()


def _take_top_level(s: _Scan, buf) -> None:
    """Schemas, channels, statistics and chunk index outside chunks. Those of the summary section
    are used only when its CRC (in the footer) holds: unlike chunks they carry no CRC of their own.
    Without a footer, records after the data end are taken as the summary and not used."""
    summary_ok = False
    if s.footer and 0 < s.summary_start <= s.footer_at:
        summary_ok = not s.summary_crc or zlib.crc32(buf[s.summary_start:s.footer_at + 25]) == s.summary_crc
        if not summary_ok:
            s.summary_damaged = True
    # Unverified: everything after the data end (or the footer's summary start if that is lost).
    start = None if summary_ok else s.data_end if s.data_end is not None else (s.summary_start or None)
    for pos, r in s.top:
        if start is not None and pos >= start:
            continue   # an unverified summary record (a flipped byte would go unnoticed)
        if isinstance(r, Schema):
            s.schemas.setdefault(r.id, r)
        elif isinstance(r, Channel):
            s.channels.setdefault(r.id, r)
        elif isinstance(r, Statistics):
            s.stats = r
        else:
            s.index_offsets.append(r[1])


def _framing_ok(payload) -> bool:
    """A chunk whose own length fields agree with the record length (its bounds can be trusted)."""
    if len(payload) < _CHUNK_HEAD.size + 8:
        return False
    clen = _CHUNK_HEAD.unpack_from(payload, 0)[4]
    if clen > 16 or _CHUNK_HEAD.size + clen + 8 > len(payload):
        return False
    return _CHUNK_HEAD.size + clen + 8 + _U64.unpack_from(payload, _CHUNK_HEAD.size + clen)[0] == len(payload)


def _record(s: _Scan, op: int, pos: int, payload) -> None:
    """Take one top-level record into the scan (raises :class:`_Bad` if it does not parse)."""
    if op == 0x06:
        _start, _end, raw = _chunk_content(payload)
        recs = _chunk_records(raw)
        s.chunk_offsets.append(pos)
        for r in recs:
            if isinstance(r, Message):
                s.messages.append(r)
            elif isinstance(r, Channel):
                s.channels.setdefault(r.id, r)
            else:
                s.schemas.setdefault(r.id, r)
    elif op == 0x03:
        s.top.append((pos, _exact(Schema, bytes(payload))))
    elif op == 0x04:
        s.top.append((pos, _exact(Channel, bytes(payload))))
    elif op == 0x0C:
        r = _exact(Metadata, bytes(payload))
        s.metadata[r.name] = dict(r.metadata)
    elif op == 0x0B:
        s.top.append((pos, _exact(Statistics, bytes(payload))))
    elif op == 0x08:
        s.top.append((pos, ("chunk index", _exact(ChunkIndex, bytes(payload)).chunk_start_offset)))
    elif op == 0x05:
        if len(payload) < _MESSAGE_HEAD.size:
            raise _Bad("message record too short")
        if s.data_end is not None:
            # The summary holds no messages (MCAP spec): this is another record with a flipped opcode.
            raise _Bad("message record after the data end")
        cid, seq, log, pub = _MESSAGE_HEAD.unpack_from(payload, 0)
        s.loose.append((pos, pos + 9 + len(payload), Message(channel_id=cid, sequence=seq, log_time=log,
                                                             publish_time=pub, data=bytes(payload[_MESSAGE_HEAD.size:]))))
    elif op == 0x02:
        if len(payload) != 20:
            raise _Bad("footer of the wrong length")
        s.footer = True
        s.summary_start, _offsets, s.summary_crc = struct.unpack_from("<QQI", payload, 0)
        s.footer_at = pos
    elif op == 0x0F:
        _exact(DataEnd, bytes(payload))
        s.data_end = pos
    elif op == 0x07:
        if not _message_index_ok(payload):
            raise _Bad("inconsistent message index record")
    else:
        # Header, attachment (and its index), metadata index, summary offset: nothing to keep, but
        # their lengths are checked like any other record's, for a flipped length byte would
        # otherwise carry the scan past intact records.
        _exact(_OTHER[op], bytes(payload))


_OTHER = {0x01: Header, 0x09: Attachment, 0x0A: AttachmentIndex, 0x0D: MetadataIndex, 0x0E: SummaryOffset}


def _message_index_ok(payload) -> bool:
    """A message index record's own length agrees with the record's: channel id, the entries'
    byte length, then whole (time, offset) pairs."""
    n = len(payload)
    return n >= 6 and 6 + struct.unpack_from("<I", payload, 2)[0] == n and (n - 6) % 16 == 0


def _resync(buf, start: int, s: _Scan) -> int:
    """The next offset at or after ``start`` where a whole record parses (a chunk: with its CRC)."""
    size = len(buf)
    for m in _RESYNC.finditer(buf, start):
        pos = m.start()
        op = buf[pos]
        (n,) = _U64.unpack_from(buf, pos + 1)
        if pos + 9 + n > size:
            continue
        payload = buf[pos + 9:pos + 9 + n]
        try:
            if op == 0x06:
                _chunk_records(_chunk_content(payload)[2])
            elif op in (0x03, 0x04, 0x0C):
                _exact({0x03: Schema, 0x04: Channel, 0x0C: Metadata}[op], bytes(payload))
            elif op == 0x02:
                if n != 20 or bytes(buf[pos + 29:pos + 37]) != MAGIC:
                    continue
            elif op == 0x07:
                if not _message_index_ok(payload):
                    continue
            elif op == 0x0F:
                if n != 4:
                    continue
            else:
                continue   # other summary records are not trusted after damage
        except _Bad:
            continue
        return pos
    return size


class BagReader:
    """Read one bag: channels, messages in log-time order, MCAP metadata records, counts.

    Reads every record from the start (the summary is not needed): a bag whose recorder was
    killed, or with damaged bytes, gives what is intact. Raises the one-line
    :class:`~kilobot_twin.errors.ConfigError` when ``bag_dir`` is not a bag, the file is not
    MCAP, or nothing in a damaged file is readable. When something was skipped, :attr:`note`
    says what in one line (also issued as a :class:`BagDamageWarning` unless ``warn=False``).
    """

    def __init__(self, bag_dir: str | Path, warn: bool = True):
        self.dir = Path(bag_dir)
        self.file = _check_bag_dir(self.dir)
        size = self.file.stat().st_size
        if size == 0:
            raise ConfigError(str(self.file), "empty file (the recorder wrote nothing)", "nothing can be recovered")
        with open(self.file, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as buf:
            scan = _scan(buf)
        if not scan.magic_ok and not scan.records:
            raise ConfigError(str(self.file), "not an MCAP file (no MCAP record in it)",
                              "give a bag directory written by `kilobot-twin run` or `import`")
        self._scan = scan
        # A channel is usable with its schema (the type name); schema 0 means "no schema".
        self._types = {cid: (ch.topic, scan.schemas[ch.schema_id].name if ch.schema_id else "")
                       for cid, ch in scan.channels.items() if ch.schema_id in scan.schemas or not ch.schema_id}
        scan.messages.sort(key=lambda m: m.log_time)   # stable: write order among equal times
        self.lost_channel_messages = sum(1 for m in scan.messages if m.channel_id not in self._types)
        self.finalised = scan.footer
        self.data_end_offset = scan.data_end   # where the data section ends (summary follows)
        self.chunks_read = len(scan.chunk_offsets)
        self.chunks_total = (scan.stats.chunk_count if scan.stats is not None
                             else len(scan.index_offsets) if scan.index_offsets else None)
        self.damaged = bool(scan.bad_chunks or scan.skipped or scan.truncated_at is not None or not scan.footer
                            or scan.summary_damaged
                            or not scan.magic_ok or self.lost_channel_messages
                            or (self.chunks_total is not None and self.chunks_total != self.chunks_read))
        self.note = f"{self._describe()}; {repair_hint(self.dir)}" if self.damaged else None
        if self.damaged and not self.message_count:
            raise ConfigError(str(self.file), f"no readable message ({self._describe(head=False)})",
                              "the recording is lost; `kilobot-twin bag repair` can only keep what is intact")
        if self.note and warn:
            warnings.warn(self.note, BagDamageWarning, stacklevel=2)

    @property
    def message_count(self) -> int:
        return len(self._scan.messages) - self.lost_channel_messages

    def _describe(self, head: bool = True) -> str:
        s = self._scan
        total = f" of {self.chunks_total}" if self.chunks_total is not None else ""
        parts = []
        expected = f" of {s.stats.message_count}" if s.stats is not None else ""
        read = f"read {self.chunks_read}{total} chunk(s), {self.message_count}{expected} message(s)"
        order = sorted(set(s.chunk_offsets) | {o for o, _ in s.bad_chunks} | set(s.index_offsets))
        for off, why in s.bad_chunks:
            parts.append(f"chunk {order.index(off) + 1} is corrupt from byte {off} ({why})")
        for a, b, why in s.skipped:
            lost = [order.index(o) + 1 for o in s.index_offsets if a <= o < b]
            what = f"chunk(s) {', '.join(map(str, lost))} in " if lost else ""
            parts.append(f"{what}bytes {a}-{b} unreadable ({why})")
        if not s.magic_ok:
            parts.append("the file's magic is damaged")
        if s.summary_damaged:
            parts.append("the summary section is damaged (CRC mismatch) and was not used")
        if self.lost_channel_messages:
            parts.append(f"{self.lost_channel_messages} message(s) whose channel or schema record is lost")
        if s.truncated_at is not None:
            parts.append(f"the file ends inside a record at byte {s.truncated_at} (truncated or the recorder was killed)")
        elif not s.footer:
            parts.append("the file has no summary (not finalised)")
        return f"{f'{self.file}: ' if head else ''}{read}; skipped: {'; '.join(parts) or 'nothing'}"

    @property
    def channels(self) -> list[dict]:
        """[{id, topic, type, qos}] of every channel whose definition was read."""
        s = self._scan
        return [{"id": cid, "topic": ch.topic, "type": self._types[cid][1],
                 "qos": ch.metadata.get("offered_qos_profiles", "")} for cid, ch in sorted(s.channels.items())
                if cid in self._types]

    def messages(self, topics=None) -> Iterator[BagMessage]:
        """(topic, type name, log time ns, publish time ns, CDR bytes) in log-time order."""
        want = None if topics is None else set(topics)
        types = self._types
        for m in self._scan.messages:
            tt = types.get(m.channel_id)
            if tt is None or (want is not None and tt[0] not in want):
                continue
            yield BagMessage(tt[0], tt[1], m.log_time, m.publish_time, m.data)

    def metadata(self) -> dict[str, dict[str, str]]:
        """MCAP metadata records by name."""
        return {k: dict(v) for k, v in self._scan.metadata.items()}

    def counts(self) -> dict[str, int]:
        """Readable messages per topic (every channel read, also those with none)."""
        out = {topic: 0 for topic, _type in self._types.values()}
        for m in self._scan.messages:
            tt = self._types.get(m.channel_id)
            if tt is not None:
                out[tt[0]] += 1
        return out


# --- repair ---------------------------------------------------------------------------------------

def _free_name(path: Path) -> Path:
    """``path``, or ``path.1``, ``path.2``... whichever does not exist (nothing is overwritten)."""
    if not path.exists():
        return path
    k = 1
    while path.with_name(f"{path.name}.{k}").exists():
        k += 1
    return path.with_name(f"{path.name}.{k}")


def _old_info(bag_dir: Path) -> dict | None:
    try:
        doc = yaml.safe_load((bag_dir / "metadata.yaml").read_text())
        info = doc["rosbag2_bagfile_information"]
        return info if isinstance(info, dict) else None
    except (OSError, yaml.YAMLError, TypeError, KeyError, UnicodeDecodeError):
        return None


def _custom_from_records(records: dict[str, dict]) -> dict:
    """What the recorder's ``metadata.yaml`` custom data holds, from the MCAP metadata records."""
    out = {}
    if "version" in records.get("kilobot_twin.version", {}):
        out["kilobot_twin_version"] = records["kilobot_twin.version"]["version"]
    for name in ("kilobot_twin.world", "kilobot_twin"):
        for key in ("seed", "mode"):
            if key in records.get(name, {}):
                try:
                    out[key] = str(json.loads(records[name][key]))
                except ValueError:
                    out[key] = records[name][key]
    return out


def repair_bag(bag_dir: str | Path) -> dict:
    """Rewrite a bag that was not finalised (recorder killed) or is damaged: every intact chunk is kept,
    also those after a damaged one, with the MCAP metadata records.

    The damaged file is kept as ``NAME_0.mcap.damaged`` and a previous ``metadata.yaml`` as
    ``metadata.yaml.damaged`` (``.1``, ``.2``... if those exist); the new ``metadata.yaml`` keeps
    what the old one said (topics, custom data such as the seed) with recomputed counts and times,
    or is rebuilt from the MCAP metadata records. An intact bag is left alone.
    """
    bag_dir = Path(bag_dir)
    reader = BagReader(bag_dir, warn=False)
    src = reader.file
    old = _old_info(bag_dir)
    if not reader.damaged and old is not None:
        return {"intact": True, "chunks": reader.chunks_read, "messages": reader.message_count,
                "channels": len(reader.channels), "skipped": None}
    s = reader._scan
    tmp = _free_name(src.with_name(src.name + ".repairing"))
    try:
        w = BagWriter(bag_dir, file_path=tmp)
        cid_map = {}
        for cid, ch in sorted(s.channels.items()):
            sc = s.schemas.get(ch.schema_id)
            if sc is not None:
                cid_map[cid] = w.add_raw_channel(ch.topic, sc.name, sc.encoding, sc.data, ch.message_encoding,
                                                 dict(ch.metadata))
        for name, meta in s.metadata.items():
            w.add_metadata(name, meta)
        w.add_metadata("repair", {"repaired_at_ns": str(time.time_ns()), "complete_chunks": str(reader.chunks_read),
                                  "skipped": reader.note or "nothing"})
        n = 0
        for m in s.messages:
            if m.channel_id in cid_map:
                w.write(cid_map[m.channel_id], m.data, m.log_time, m.publish_time)
                n += 1
        w.finish()
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    damaged = _free_name(src.with_name(src.name + ".damaged"))
    os.replace(src, damaged)
    os.replace(tmp, src)
    if (bag_dir / "metadata.yaml").exists():
        shutil.copy2(bag_dir / "metadata.yaml", _free_name(bag_dir / "metadata.yaml.damaged"))
    custom = {} if old is not None else _custom_from_records(s.metadata)
    write_metadata_yaml(bag_dir, list(w.topics.values()), w.first_ns or 0, w.last_ns, w.compression,
                        {**custom, "repaired": "true"}, old)
    return {"intact": False, "chunks": reader.chunks_read, "messages": n, "channels": len(cid_map),
            "skipped": reader.note, "damaged": str(damaged)}
