"""Damaged recordings (issue 16): every verb that reads a bag, on damaged copies of real bags.

Each verb ends cleanly: exit 0 with a line saying what was skipped, or exit 2 with exactly one
line that names the file; never a traceback. ``bag repair`` keeps every intact chunk; the
expected counts come from the ``mcap`` library reading the good file's chunks one by one, and
the repaired bags are read back with ``rosbags``.
"""

from __future__ import annotations

import re
import struct
from collections import Counter
from pathlib import Path

import pytest
import yaml

from kilobot_twin.cli import main
from kilobot_twin.recording.bag import BagReader, BagWriter, mcap_path

from ..nodes.test_run import cli
from ..ros.test_bag import rerun_check, rosbags_messages
from . import damage


# --- the good bags ---------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def bags(tmp_path_factory):
    """A real twin recording (kilobot-twin run), the same messages in 6 KB chunks (so that damage
    hits some chunks and spares others), and an imported measured dataset (for gap)."""
    root = tmp_path_factory.mktemp("good")
    rec = root / "rec"
    res = cli("run", "--scenario", "phototaxis", "--robots", "3", "--duration", "4", "--seed", "7", "--out", str(rec))
    assert res.returncode == 0, res.stdout + res.stderr
    small = root / "small"
    reader = BagReader(rec)
    old = yaml.safe_load((rec / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    with BagWriter(small, chunk_size=6 * 1024) as w:
        ids = {}
        for name, meta in reader.metadata().items():
            w.add_metadata(name, meta)
        qos = {c["topic"]: c["qos"] for c in reader.channels}
        for m in reader.messages():   # channels registered at their first message, as the recorder does
            if m.topic not in ids:
                ids[m.topic] = w.add_topic(m.topic, m.type, qos[m.topic])
            w.write(ids[m.topic], m.data, m.log_time_ns, m.publish_time_ns)
        w.close(base_info=old)   # keeps the run's custom data (seed, mode, version)
    syn = root / "syn"
    assert cli("synth", "--kind", "motion", "--robots", "2", "--trials", "3", "--out", str(syn)).returncode == 0
    imp = root / "imp"
    assert cli("import", str(syn), "--out", str(imp)).returncode == 0
    return {"rec": rec, "small": small, "imp": imp}


def chunks_of(bag: Path) -> list[tuple[int, int, Counter, tuple[dict, set]]]:
    """(start byte, end byte, messages per topic, ({topic: schema id} of the channel records it
    holds, ids of the schema records it holds)) of each chunk, read with the mcap library."""
    from mcap.reader import make_reader
    from mcap.records import Channel, Message, Schema

    f = mcap_path(bag)
    data = f.read_bytes()
    with open(f, "rb") as fh:
        topics = {cid: ch.topic for cid, ch in make_reader(fh).get_summary().channels.items()}
    out, pos = [], 8
    while pos < len(data) - 8:
        op, n = data[pos], struct.unpack_from("<Q", data, pos + 1)[0]
        if op == 0x06:
            records = chunk_records(data[pos:pos + 9 + n])
            c = Counter(topics[r.channel_id] for r in records if isinstance(r, Message))
            schemas = {r.id for r in records if isinstance(r, Schema)}
            out.append((pos, pos + 9 + n, c, ({r.topic: r.schema_id for r in records if isinstance(r, Channel)}, schemas)))
        pos += 9 + n
    return out


def chunk_records(record: bytes) -> list | None:
    """The records inside one chunk record (opcode and length included), read with the mcap
    library with its CRC checked; None when they do not decode."""
    import io

    from mcap.data_stream import ReadDataStream
    from mcap.records import Chunk
    from mcap.stream_reader import breakup_chunk

    try:
        return list(breakup_chunk(Chunk.read(ReadDataStream(io.BytesIO(record[9:]))), validate_crc=True))
    except Exception:  # noqa: BLE001 - damaged bytes fail in any of the library's ways
        return None


def expected_after(kind: str, good: Path, dst: Path, seed: int) -> tuple[Counter, int]:
    """Messages per topic in the chunks that the damage did not touch (exact for these kinds) whose
    channel record survived, and the number of those whose channel record did not."""
    size = mcap_path(good).stat().st_size
    damaged = mcap_path(dst).read_bytes()
    original = mcap_path(good).read_bytes()
    if kind in ("truncated", "unfinalised"):
        keep = lambda a, b: b <= len(damaged)  # noqa: E731
    else:
        diff = [i for i in range(size) if damaged[i] != original[i]]

        def keep(a: int, b: int) -> bool:
            # Flips in a chunk's start/end time fields (bytes 9..25 of the record) harm nothing. A
            # flip in the compressed records can leave them unchanged (a bit zstd does not use):
            # intact when the mcap library decodes them, CRC checked, to the good chunk's records.
            # Any other flip (opcode, lengths, sizes, CRC, compression name) damages the chunk.
            data_at = a + 41 + struct.unpack_from("<I", original, a + 37)[0] + 8
            hit = [i for i in diff if a <= i < b and not a + 9 <= i < a + 25]
            if not hit:
                return True
            if any(i < data_at for i in hit):
                return False
            return chunk_records(damaged[a:b]) == chunk_records(original[a:b])   # the good one decodes (chunks_of)
    # A message is readable when its chunk is intact and its channel record is somewhere intact:
    # in an intact chunk, or in the summary (repeated there) when no damage reached the summary.
    # The footer (opcode, length, summary start, ...) ends 8 bytes before the file's end.
    summary_start = struct.unpack_from("<Q", original, len(original) - 8 - 20)[0]
    if kind in ("truncated", "unfinalised"):
        summary_intact = len(damaged) == len(original)
    else:
        summary_intact = not any(i >= summary_start for i in diff)
    chunks = [(c, defined) for a, b, c, defined in chunks_of(good) if keep(a, b)]
    schemas = set().union(*(d[1] for _c, d in chunks))
    known = {t for _c, d in chunks for t, sid in d[0].items() if sid in schemas}
    total, unattributed = Counter(), 0
    for c, _defined in chunks:
        total += Counter({t: n for t, n in c.items() if summary_intact or t in known})
        unattributed += sum(n for t, n in c.items() if not (summary_intact or t in known))
    return total, unattributed


# --- the matrix ------------------------------------------------------------------------------------

VARIANTS = [("truncated", 0), ("truncated", 1), ("truncated", 2), ("flipped", 0), ("zeroed", 0), ("zeroed", 1),
            ("random", 0), ("unfinalised", 0), ("unfinalised", 1)]


def run_cli(capfd, *args) -> tuple[int, str, str]:
    code = main([str(a) for a in args])
    out, err = capfd.readouterr()
    return code, out, err


def assert_clean(code: int, out: str, err: str, bag: Path, what: str) -> None:
    assert "Traceback" not in out + err, what
    lines = [ln for ln in err.splitlines() if ln.strip()]
    if code == 2:
        assert len(lines) == 1, (what, err)
        assert str(bag) in lines[0] and lines[0].startswith("kilobot-twin: error: "), (what, err)
    else:
        assert code == 0, (what, code, err)
        assert mcap_path(bag).is_file()
        # A damaged bag read in part says so, naming the file and the repair command.
        warn = [ln for ln in lines if ln.startswith("kilobot-twin: warning: ")]
        assert len(warn) == 1 and "skipped: " in warn[0] and f"kilobot-twin bag repair {bag}" in warn[0], (what, err)


@pytest.mark.parametrize("base", ["rec", "small"])
@pytest.mark.parametrize("kind,seed", VARIANTS)
def test_every_reading_verb_ends_cleanly_and_repair_keeps_every_intact_chunk(bags, base, kind, seed, tmp_path, capfd):
    good = bags[base]
    bag = damage.KINDS[kind](good, tmp_path / f"{kind}{seed}", seed)
    expected, unattributed = expected_after(kind, good, bag, seed)
    results = {}
    for verb, args in {"info": ["bag", "info", bag], "view": ["view", bag, "--out", tmp_path / "v.rrd"],
                       "replay": ["replay", bag, "--rate", "20"],
                       "gap": ["gap", bag, "--out", tmp_path / "gap", "--quiet"]}.items():
        code, out, err = run_cli(capfd, *args)
        assert_clean(code, out, err, bag, verb)
        results[verb] = code
    if kind != "random":
        assert (results["info"] == 0) == (sum(expected.values()) > 0)
    if results["info"] == 0:
        code, out, err = run_cli(capfd, "bag", "info", bag)
        shown = Counter({ln.split()[0]: int(ln.split()[1]) for ln in out.splitlines() if ln.startswith("/")})
        # Every message of an intact chunk is shown, unless the record defining its channel (in a
        # damaged chunk and in a damaged summary) is lost: then the note counts it.
        lost = re.search(r"(\d+) message\(s\) whose channel or schema record is lost", err)
        assert shown == expected and (int(lost[1]) if lost else 0) == unattributed
    assert results["gap"] == 2   # a twin run is one trial: refused in one line, also when damaged

    mcap_before = mcap_path(bag).read_bytes()
    code, out, err = run_cli(capfd, "bag", "repair", bag)
    assert "Traceback" not in out + err
    if not expected:
        assert code == 2 and len(err.strip().splitlines()) == 1 and str(bag) in err
        assert mcap_path(bag).read_bytes() == mcap_before                      # creates nothing
        assert not list(bag.glob("*.damaged")) and not list(bag.glob("*.repairing*"))
        return
    assert code == 0, err
    assert (bag / f"{bag.name}_0.mcap.damaged").read_bytes() == mcap_before  # the damaged file is kept
    # The repaired bag passes rerun's check and reads back, with rosbags, to every intact chunk.
    assert rerun_check(mcap_path(bag)).returncode == 0
    assert Counter(t for t, _ in rosbags_messages(bag)) == expected
    # What the run's metadata said is kept: metadata.yaml (or the MCAP records if there was none).
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    good_info = yaml.safe_load((good / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["custom_data"]["seed"] == "7" and info["custom_data"]["mode"] == "lockstep"
    assert info["custom_data"]["kilobot_twin_version"] == good_info["custom_data"]["kilobot_twin_version"]
    assert info["custom_data"]["repaired"] == "true"
    assert info["message_count"] == sum(expected.values())
    if kind != "unfinalised":
        assert (bag / "metadata.yaml.damaged").read_text() == (good / "metadata.yaml").read_text()
        assert {t["topic_metadata"]["name"] for t in info["topics_with_message_count"]} == {
            t["topic_metadata"]["name"] for t in good_info["topics_with_message_count"]}
    meta, good_meta = BagReader(bag).metadata(), BagReader(good).metadata()
    assert all(meta[k] == good_meta[k] for k in good_meta if k in meta)   # records kept as they were
    if kind != "flipped":   # flipped bytes may hit a metadata record (they carry no CRC)
        assert set(good_meta) <= set(meta)
    # Repaired: every verb reads it without a note; repair again leaves it alone.
    code, out, err = run_cli(capfd, "bag", "info", bag)
    assert code == 0 and err == ""
    code, out, err = run_cli(capfd, "bag", "repair", bag)
    assert code == 0 and "nothing to repair" in out


@pytest.mark.parametrize("kind,seed", [("truncated", 1), ("zeroed", 1), ("flipped", 0), ("unfinalised", 0)])
def test_import_output_damaged_reads_cleanly_in_gap_view_and_info(bags, kind, seed, tmp_path, capfd):
    good = bags["imp"]
    bag = damage.KINDS[kind](good, tmp_path / f"{kind}{seed}", seed)
    expected, unattributed = expected_after(kind, good, bag, seed)
    for verb, args in {"info": ["bag", "info", bag], "view": ["view", bag, "--out", tmp_path / "v.rrd"],
                       "gap": ["gap", bag, "--out", tmp_path / "gap", "--quiet"]}.items():
        code, out, err = run_cli(capfd, *args)
        assert_clean(code, out, err, bag, verb)
        if verb == "info":
            assert (code == 0) == (sum(expected.values()) > 0)


def test_damage_kinds_really_damage(bags, tmp_path):
    """The fixtures are what they say: each copy differs from the good file and is reported damaged;
    the mcap library's own reader fails on the cut and random ones (as it did in every verb)."""
    from mcap.reader import make_reader

    from kilobot_twin.errors import ConfigError

    good = mcap_path(bags["small"]).read_bytes()
    for kind, seed in VARIANTS:
        bag = damage.KINDS[kind](bags["small"], tmp_path / f"{kind}{seed}", seed)
        assert mcap_path(bag).read_bytes() != good
        try:
            assert BagReader(bag, warn=False).damaged, (kind, seed)
        except ConfigError:
            pass
        if kind in ("truncated", "unfinalised", "random"):
            with pytest.raises(Exception):   # noqa: B017 - any of the library's errors
                with open(mcap_path(bag), "rb") as f:
                    for _ in make_reader(f).iter_messages():
                        pass
    assert len(chunks_of(bags["small"])) >= 6


def test_resync_recovers_the_chunks_after_a_damaged_one(bags, tmp_path, capfd):
    """One chunk in the middle is corrupt: every chunk before and after it is read and repaired."""
    good = bags["small"]
    chunks = chunks_of(good)
    a, b, lost, _defined = chunks[len(chunks) // 2]
    bag = tmp_path / "mid"
    f = damage._copy(good, bag)
    data = bytearray(f.read_bytes())
    data[(a + b) // 2] ^= 0xFF   # inside its compressed data
    f.write_bytes(bytes(data))
    code, out, err = run_cli(capfd, "bag", "info", bag)
    k = len(chunks) // 2 + 1
    assert code == 0 and f"read {len(chunks) - 1} of {len(chunks)} chunk(s)" in err and f"chunk {k} is corrupt from byte {a}" in err
    assert run_cli(capfd, "bag", "repair", bag)[0] == 0
    assert Counter(t for t, _ in rosbags_messages(bag)) == sum((c for _, _, c, _ in chunks), Counter()) - lost


def test_not_a_bag_is_one_line(bags, tmp_path, capfd):
    syn = bags["imp"].parent / "syn"
    plain = tmp_path / "notes.txt"
    plain.write_text("hello\n")
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "empty_0.mcap").write_bytes(b"")
    for path, words in ((syn, "kilobot-twin import"), (plain, "not a bag directory"), (tmp_path / "missing", "no such"),
                        (mcap_path(bags["rec"]), "not a bag directory"), (empty, "empty file")):
        for args in (["bag", "info", path], ["bag", "repair", path], ["view", path], ["replay", path]):
            code, out, err = run_cli(capfd, *args)
            assert code == 2 and len(err.strip().splitlines()) == 1 and str(path) in err, (args, err)
            assert words in err or args[0] != "bag", (args, err)
            assert "Traceback" not in err


def test_repair_never_overwrites(bags, tmp_path, capfd):
    """A second repair of a bag damaged again keeps both damaged files and both old metadata files."""
    bag = damage.truncate(bags["small"], tmp_path / "t", 1)
    assert run_cli(capfd, "bag", "repair", bag)[0] == 0
    f = mcap_path(bag)
    f.write_bytes(f.read_bytes()[:-100])
    assert run_cli(capfd, "bag", "repair", bag)[0] == 0
    assert (bag / "t_0.mcap.damaged").exists() and (bag / "t_0.mcap.damaged.1").exists()
    assert (bag / "metadata.yaml.damaged").exists() and (bag / "metadata.yaml.damaged.1").exists()


def test_gap_reads_bags_without_rclpy():
    import ast

    src = Path(__file__).resolve().parents[2] / "kilobot_twin" / "gap" / "bags.py"
    names = {n.module or "" for n in ast.walk(ast.parse(src.read_text())) if isinstance(n, ast.ImportFrom)}
    names |= {a.name for n in ast.walk(ast.parse(src.read_text())) if isinstance(n, ast.Import) for a in n.names}
    assert not any(n.startswith(("rclpy", "viewer", "..viewer", "geometry_msgs", "std_msgs")) or "viewer" in n
                   for n in names), names


def test_only_recording_bag_opens_mcap_files():
    import ast

    root = Path(__file__).resolve().parents[2] / "kilobot_twin"
    users = set()
    for py in root.rglob("*.py"):
        for n in ast.walk(ast.parse(py.read_text())):
            mods = [n.module or ""] if isinstance(n, ast.ImportFrom) else [a.name for a in n.names] if isinstance(
                n, ast.Import) else []
            if any(m == "mcap" or m.startswith("mcap.") for m in mods):
                users.add(py.relative_to(root).as_posix())
    assert users == {"recording/bag.py"}


def test_cdr_decoding_agrees_with_rclpy(bags):
    """The rclpy-free decoders give what rclpy's deserializer gives, on a real recording."""
    from geometry_msgs.msg import PoseStamped
    from rclpy.serialization import deserialize_message
    from std_msgs.msg import ColorRGBA

    from kilobot_twin.recording import cdr

    n = 0
    for m in BagReader(bags["rec"]).messages():
        if m.topic.endswith("/pose"):
            ref = deserialize_message(m.data, PoseStamped)
            assert cdr.pose_stamped(m.data) == (ref.header.stamp.sec * 10**9 + ref.header.stamp.nanosec,
                                                ref.pose.position.x, ref.pose.position.y, ref.pose.orientation.z,
                                                ref.pose.orientation.w)
            n += 1
        elif m.topic.endswith("/led"):
            ref = deserialize_message(m.data, ColorRGBA)
            assert cdr.color_rgba(m.data) == (ref.r, ref.g, ref.b, ref.a)
    assert n == 3 * 41


def test_recording_imports_only_lower_layers():
    """recording/ sits between batch and ros: no rclpy, ROS message packages, ros/, nodes/ or above."""
    import ast

    root = Path(__file__).resolve().parents[2] / "kilobot_twin" / "recording"
    for py in root.glob("*.py"):
        tree = ast.parse(py.read_text())
        mods = [("." * n.level) + (n.module or "") for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
        mods += [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
        for m in mods:
            assert not m.startswith(("rclpy", "geometry_msgs", "std_msgs", "sensor_msgs", "rerun")), (py.name, m)
            assert not any(m.startswith(f"..{up}") for up in ("ros", "nodes", "viewer", "gap", "experiments", "cli")), (
                py.name, m)


@pytest.mark.parametrize("opcode", [0x07, 0x08])
def test_a_damaged_length_outside_chunks_does_not_hide_the_records_after_it(bags, opcode, tmp_path):
    """The length of a record without a CRC (a message index between chunks, a chunk index in the
    summary) damaged so that the record seems to run over the next chunk (over the footer): every
    chunk is still read (counts from the mcap library, chunk by chunk, on the good file), the file
    is still seen as finalised, and the note names the bytes skipped. Found by the damage matrix
    on a recording where a flipped message-index length hid one intact chunk."""
    good = bags["small"]
    data = bytearray(mcap_path(good).read_bytes())
    ends = [b for _a, b, _c, _d in chunks_of(good)]
    footer_at = len(data) - 8 - 29
    pos, target = 8, None
    while pos < len(data) - 8:
        n = struct.unpack_from("<Q", data, pos + 1)[0]
        if data[pos] == opcode and target is None and pos > ends[2]:
            target = pos
            past = min([b for b in ends if b > pos + 9 + n] or [footer_at + 29])
            struct.pack_into("<Q", data, pos + 1, past - pos - 9 + 1)
        pos += 9 + n
    assert target is not None
    bag = tmp_path / "flip"
    f = damage._copy(good, bag)
    f.write_bytes(bytes(data))
    reader = BagReader(bag, warn=False)
    assert Counter(m.topic for m in reader.messages()) == sum((c for _a, _b, c, _d in chunks_of(good)), Counter())
    assert reader.finalised
    assert f"bytes {target}-" in reader.note and "inconsistent" in reader.note


def test_an_opcode_flipped_to_message_is_not_read_as_a_message(bags, tmp_path):
    """A message index (0x07) between chunks and a channel record (0x04) in the summary, each with
    one opcode bit flipped to 0x05, parse as plausible messages (a real channel id, a real time).
    A chunked file holds its messages in chunks (and its summary none), so the reader skips them
    and names their bytes; the counts are the mcap library's, chunk by chunk, on the good file."""
    good = bags["small"]
    data = bytearray(mcap_path(good).read_bytes())
    pos, flipped = 8, {}
    while pos < len(data) - 8:
        n = struct.unpack_from("<Q", data, pos + 1)[0]
        if data[pos] in (0x07, 0x04) and data[pos] not in flipped and pos > 8 + 4096:
            flipped[data[pos]] = pos
            data[pos] = 0x05
        pos += 9 + n
    assert set(flipped) == {0x07, 0x04}
    bag = tmp_path / "op"
    damage._copy(good, bag).write_bytes(bytes(data))
    reader = BagReader(bag, warn=False)
    assert Counter(m.topic for m in reader.messages()) == sum((c for _a, _b, c, _d in chunks_of(good)), Counter())
    assert all(f"bytes {p}-" in reader.note for p in flipped.values()), reader.note


def test_an_unchunked_file_reads_its_messages(tmp_path):
    """MCAP's unchunked layout (messages outside chunks, written by the mcap library) is read
    whole: the rule above applies to chunked files only."""
    from mcap.writer import Writer

    from kilobot_twin.recording.schemas import ros2msg_schema

    bag = tmp_path / "flat"
    bag.mkdir()
    with open(mcap_path(bag), "wb") as f:
        w = Writer(f, use_chunking=False)
        w.start(profile="ros2", library="test")
        sid = w.register_schema("std_msgs/msg/Float64", "ros2msg", ros2msg_schema("std_msgs/msg/Float64").encode())
        cid = w.register_channel("/x", "cdr", sid)
        for k in range(7):
            w.add_message(cid, log_time=k, publish_time=k, sequence=k, data=b"\x00\x01\x00\x00" + struct.pack("<d", k))
        w.finish()
    reader = BagReader(bag, warn=False)
    assert reader.counts() == {"/x": 7} and not reader.damaged
