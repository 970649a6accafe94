"""Bags: ros2msg schemas, write -> independent readers (rosbags, rerun), repair of a killed writer."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from rclpy.serialization import serialize_message
from std_msgs.msg import String

from kilobot_twin.recording.bag import BagReader, BagWriter, mcap_path, repair_bag
from kilobot_twin.recording.schemas import ros2msg_schema

from .message_path import RobotMessages, RobotSample

RERUN = shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))


def rerun_check(path) -> subprocess.CompletedProcess:
    return subprocess.run([RERUN, "mcap", "check", str(path)], capture_output=True, text=True, timeout=60)


def rosbags_records(bag_dir):
    """Every message of a bag as rosbags reads it with its own ROS 2 Jazzy type store (not the
    bag's schemas): (topic, log time in ns, message), in rosbags' order."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_JAZZY)
    with Reader(bag_dir) as r:
        return [(c.topic, t, ts.deserialize_cdr(raw, c.msgtype)) for c, t, raw in r.messages()]


def rosbags_messages(bag_dir):
    return [(topic, m) for topic, _t, m in rosbags_records(bag_dir)]


FOXGLOVE = Path(__file__).resolve().parents[1] / "foxglove"


def foxglove_messages(mcap_file) -> list[dict]:
    """Every message of an MCAP file as Foxglove reads it (``tests/foxglove/decode.cjs``: its MCAP
    reader, each schema parsed from the text the file carries, its CDR decoder), in file order:
    topic, log_time (int ns), trailing (bytes after the decoded message), msg (plain JSON; NaN
    as None). ``make install`` puts node (requirements.txt) and the npm packages in .venv."""
    import json
    import os

    venv = Path(sys.executable).parent.parent
    node = shutil.which("node", path=str(Path(sys.executable).parent)) or shutil.which("node")
    modules = venv / "foxglove" / "node_modules"
    assert node and modules.is_dir(), f"no node or no {modules}: run make install (requirements.txt, tests/foxglove)"
    res = subprocess.run([node, str(FOXGLOVE / "decode.cjs"), str(mcap_file)], capture_output=True, text=True,
                         timeout=120, env=dict(os.environ, NODE_PATH=str(modules)))
    assert res.returncode == 0, res.stderr
    out = [json.loads(line) for line in res.stdout.splitlines() if line]
    for d in out:
        d["log_time"] = int(d["log_time"])
    return out


def _plain(m):
    """A rosbags message as plain values (its constants, class attributes, left out)."""
    import numpy as np

    if hasattr(m, "__dataclass_fields__"):
        return {k: _plain(getattr(m, k)) for k in m.__dataclass_fields__ if k != "__msgtype__" and not k.isupper()}
    if isinstance(m, np.ndarray):
        return m.tolist()
    if isinstance(m, (list, tuple)):
        return [_plain(x) for x in m]
    return m


def _same(a, b, path: str) -> None:
    """rosbags' value ``a`` equals Foxglove's ``b`` exactly (64-bit integers come as strings, NaN as None)."""
    import math

    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), (path, a, b)
        for k in a:
            _same(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), (path, len(a), b if not isinstance(b, list) else len(b))
        for i, (x, y) in enumerate(zip(a, b)):
            _same(x, y, f"{path}[{i}]")
    elif isinstance(a, float):
        assert (math.isnan(a) and b is None) or a == b, (path, a, b)
    elif isinstance(a, bool):
        assert b is a, (path, a, b)
    elif isinstance(a, int):
        assert a == (int(b) if isinstance(b, str) else b) and not isinstance(b, bool), (path, a, b)
    else:
        assert a == b, (path, a, b)


def assert_foxglove_reads_what_rosbags_reads(bag_dir) -> int:
    """Foxglove, decoding each message from the schema the bag carries, reads every message as
    rosbags does from its own ROS 2 Jazzy type store: the same messages (topic and log time, as
    many of each), every field equal; after each message at most the 3 bytes of padding that round a CDR
    buffer up to 4 (as DDS sends it). Returns the number of messages."""
    ours = [(topic, t, _plain(m)) for topic, t, m in rosbags_records(bag_dir)]
    fox = foxglove_messages(mcap_path(bag_dir))
    assert len(fox) == len(ours)
    ours.sort(key=lambda x: (x[0], x[1]))  # by topic, then log time (stable: file order within a time)
    fox.sort(key=lambda d: (d["topic"], d["log_time"]))
    for (topic, t, m), d in zip(ours, fox):
        assert (topic, t) == (d["topic"], d["log_time"])
        assert 0 <= d["trailing"] <= 3, (topic, d["trailing"])
        _same(m, d["msg"], topic)
    return len(fox)


def test_schema_lists_every_dependency_once():
    s = ros2msg_schema("geometry_msgs/msg/PoseStamped")
    deps = [ln for ln in s.splitlines() if ln.startswith("MSG: ")]
    assert deps == ["MSG: std_msgs/Header", "MSG: builtin_interfaces/Time", "MSG: geometry_msgs/Pose",
                    "MSG: geometry_msgs/Point", "MSG: geometry_msgs/Quaternion"]
    assert s.startswith("# A Pose with reference coordinate frame")


def _pose(i):
    s = RobotSample(robot_id=3, step=i, stamp_ns=i * 100_000_000, x_m=0.25 + i * 1e-3, y_m=-1.5 + i * 1e-7,
                            theta_rad=0.3 + 0.01 * i, reading=512.0 + i, led=i % 2, ticks=3.1 * i, tick_hz=31.0)
    return RobotMessages().fill(s), s


def test_written_bag_reads_back_with_rosbags_and_passes_rerun_check(tmp_path):
    bag = tmp_path / "b1"
    w = BagWriter(bag, chunk_size=4096)
    cp = w.add_topic("/kilobot_3/pose", "geometry_msgs/msg/PoseStamped")
    cl = w.add_topic("/kilobot_3/light", "sensor_msgs/msg/Illuminance")
    cc = w.add_topic("/kilobot_3/led", "std_msgs/msg/ColorRGBA")
    ct = w.add_topic("/kilobot_3/traits", "std_msgs/msg/String")
    w.write(ct, serialize_message(String(data='{"id": 3}')), 1)
    samples = []
    for i in range(300):
        m, s = _pose(i)
        samples.append(s)
        for c, msg in ((cp, m.pose), (cl, m.light), (cc, m.led)):
            w.write(c, serialize_message(msg), 10 + i)
    w.add_metadata("kilobot_twin", {"seed": 5, "version": "x"})
    w.close({"seed": 5})

    res = rerun_check(mcap_path(bag))
    assert res.returncode == 0, res.stdout + res.stderr
    assert "ok" in res.stdout
    msgs = rosbags_messages(bag)
    assert len(msgs) == 1 + 3 * 300
    poses = [m for t, m in msgs if t.endswith("/pose")]
    lights = [m for t, m in msgs if t.endswith("/light")]
    leds = [m for t, m in msgs if t.endswith("/led")]
    for s, p, lt, ld in zip(samples, poses, lights, leds):
        assert p.pose.position.x == s.x_m and p.pose.position.y == s.y_m
        assert p.header.stamp.sec * 10**9 + p.header.stamp.nanosec == s.stamp_ns
        assert p.header.frame_id == "arena"
        assert lt.illuminance == s.reading
        assert (ld.r, ld.b) == ((1.0, 0.0) if s.led == 0 else (0.0, 1.0))
    assert BagReader(bag).counts()["/kilobot_3/pose"] == 300
    assert BagReader(bag).metadata()["kilobot_twin"]["seed"] == "5"
    assert assert_foxglove_reads_what_rosbags_reads(bag) == 1 + 3 * 300


def test_repair_recovers_every_complete_chunk(tmp_path):
    """A writer that never closes (as after SIGKILL): repair keeps all messages of complete chunks."""
    from mcap.records import Chunk
    from mcap.stream_reader import StreamReader, breakup_chunk

    bag = tmp_path / "b2"
    w = BagWriter(bag, chunk_size=2048)
    cp = w.add_topic("/kilobot_0/pose", "geometry_msgs/msg/PoseStamped")
    for i in range(1000):
        w.write(cp, serialize_message(_pose(i)[0].pose), 100 + i)
    # No close(): the file ends inside the open chunk, without summary or footer. Cut a few
    # bytes more to also leave a torn record at the end.
    f = mcap_path(bag)
    data = f.read_bytes()
    f.write_bytes(data[:-7])
    assert not (bag / "metadata.yaml").exists()
    assert rerun_check(f).returncode != 0   # an independent checker rejects the torn file

    # Independent count of the messages in complete chunks.
    expected = 0
    with open(f, "rb") as fh:
        try:
            for rec in StreamReader(fh, emit_chunks=True).records:
                if isinstance(rec, Chunk):
                    expected += sum(1 for r in breakup_chunk(rec) if type(r).__name__ == "Message")
        except Exception:
            pass
    assert 0 < expected < 1000

    res = repair_bag(bag)
    assert res["messages"] == expected and not res["intact"]
    assert rerun_check(mcap_path(bag)).returncode == 0
    msgs = rosbags_messages(bag)
    assert len(msgs) == expected
    xs = [m.pose.position.x for _, m in msgs]
    assert xs == [_pose(i)[1].x_m for i in range(expected)]
    assert (bag / "b2_0.mcap.damaged").exists()


def test_repair_of_a_missing_bag_is_a_config_error(tmp_path):
    from kilobot_twin.errors import ConfigError

    with pytest.raises(ConfigError):
        repair_bag(tmp_path / "nothing")


def test_block_writes_are_indexed_as_the_mcap_spec_says(tmp_path):
    """Single messages and blocks (a swarm bundle's way in) over many chunks: mcap's own indexed
    reader, its record parser and rerun agree with what was written; every message-index entry
    and chunk-index offset points where the MCAP spec says (parsed here with struct, not with the
    writer's code)."""
    import struct
    import zlib

    import numpy as np
    import zstandard
    from mcap.reader import make_reader
    from mcap.records import Chunk, ChunkIndex, MessageIndex
    from mcap.stream_reader import StreamReader

    bag = tmp_path / "blocks"
    w = BagWriter(bag, chunk_size=3000)
    types = ["geometry_msgs/msg/PoseStamped", "sensor_msgs/msg/Illuminance", "std_msgs/msg/String"]
    cids = [w.add_topic(f"/kilobot_{i}/x{i % 3}", types[i % 3]) for i in range(7)]
    rng = np.random.default_rng(3)
    expected = []  # (channel id, log time, bytes) in file order
    t = 1_000
    for step in range(60):
        t += int(rng.integers(1, 5))
        if step % 4 == 0:  # a single message of its own size
            cid, data = cids[step % 7], rng.bytes(int(rng.integers(0, 40)))
            w.write(cid, data, t)
            expected.append((cid, t, data))
        else:  # a block: k messages of `size` bytes on a random subset of channels
            size = int(rng.integers(1, 120))
            chosen = [cids[j] for j in rng.choice(7, size=int(rng.integers(1, 8)), replace=False)]
            block = rng.bytes(size * len(chosen))
            w.write_block(np.array(chosen), block, size, t)
            expected += [(c, t, block[i * size:(i + 1) * size]) for i, c in enumerate(chosen)]
    w.close()
    path = mcap_path(bag)
    assert rerun_check(path).returncode == 0

    with open(path, "rb") as f:  # mcap's indexed reader: summary, chunk indexes
        reader = make_reader(f)
        got = [(ch.id, m.log_time, m.data) for _s, ch, m in reader.iter_messages(log_time_order=False)]
        stats = reader.get_summary().statistics
    assert got == expected
    counts = {}
    for cid, _t, _d in expected:
        counts[cid] = counts.get(cid, 0) + 1
    assert dict(stats.channel_message_counts) == counts and stats.message_count == len(expected)
    assert [m.sequence for _s, _c, m in make_reader(open(path, "rb")).iter_messages(log_time_order=False)] == list(
        range(1, len(expected) + 1))

    raw = path.read_bytes()
    chunks, indexes, chunk_indexes = [], {}, []
    for rec in StreamReader(open(path, "rb"), emit_chunks=True, validate_crcs=True).records:
        if isinstance(rec, Chunk):
            chunks.append(rec)
            indexes[len(chunks) - 1] = []
        elif isinstance(rec, MessageIndex):
            indexes[len(chunks) - 1].append(rec)
        elif isinstance(rec, ChunkIndex):
            chunk_indexes.append(rec)
    assert len(chunks) > 5 and len(chunk_indexes) == len(chunks) == stats.chunk_count
    seen = []
    for k, chunk in enumerate(chunks):
        content = zstandard.ZstdDecompressor().decompress(chunk.data, max_output_size=chunk.uncompressed_size)
        assert zlib.crc32(content) == chunk.uncompressed_crc
        for ix in indexes[k]:
            for log_time, offset in ix.records:
                op, length, cid, _seq, log, _pub = struct.unpack_from("<BQHIQQ", content, offset)
                assert (op, cid, log) == (0x05, ix.channel_id, log_time)
                seen.append((offset + k * 10**9, cid, log, content[offset + 31:offset + 9 + length]))
        ci = chunk_indexes[k]
        for cid, off in ci.message_index_offsets.items():
            op, _len, index_cid = struct.unpack_from("<BQH", raw, off)
            assert (op, index_cid) == (0x07, cid)
        assert raw[ci.chunk_start_offset] == 0x06
    assert [(c, t, d) for _o, c, t, d in sorted(seen)] == expected  # every message indexed once
