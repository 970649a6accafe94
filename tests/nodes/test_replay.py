"""`replay`: a bag replayed into a fresh recorder gives the same messages, topic by topic, byte for byte."""

import threading

import numpy as np
import pytest
from rclpy.parameter import Parameter

from kilobot_twin.cli import main as cli_main
from kilobot_twin.nodes.recorder import RecorderNode
from kilobot_twin.nodes.replay import ReplayNode, load_bag, qos_from_yaml, topic_selected
from kilobot_twin.recording.topics import DATA_QOS, LATCHED_QOS
from kilobot_twin.recording.twin_bag import TwinBagWriter
from kilobot_twin.recording.bag import BagReader

from ..ros.test_bag import rerun_check, rosbags_messages
from .graph import Graph, overrides


def fixture_bag(path, robots=3, steps=20, dt_ns=50_000_000):
    rng = np.random.default_rng(1)
    w = TwinBagWriter(path)
    t0 = 10**18
    w.document("/world/scenario", {"format": "not-a-world", "note": "fixture"}, t0)
    for r in range(robots):
        w.document(f"/kilobot_{r}/traits", {"id": r, "traits": {"heading_bias": 0.01 * r}}, t0 + 1)
    for k in range(steps):
        w.clock(k * dt_ns, t0 + 2 + k * dt_ns)
        for r in range(robots):
            w.robot_sample(r, k * dt_ns, t0 + 3 + k * dt_ns + r * 1000, *rng.normal(size=3), reading=float(k + r),
                           led=k % 2)
    w.close()
    return path


def by_topic(bag):
    out = {}
    for topic, type_name, _log, _pub, data in BagReader(bag).messages():
        out.setdefault(topic, (type_name, []))[1].append(bytes(data))
    return out


def test_replay_into_a_fresh_recorder_gives_the_same_bag(tmp_path):
    src = fixture_bag(tmp_path / "src")
    out = tmp_path / "copy"
    with Graph() as g:
        rec = g.add(RecorderNode(context=g.context, parameter_overrides=overrides(out=str(out), discovery_period_s=0.05)))
        node = ReplayNode(context=g.context, parameter_overrides=[
            Parameter("bag", value=str(src)), Parameter("rate", value=2.0),
            Parameter("wait_for_subscribers_s", value=20.0)])
        stats = {}
        th = threading.Thread(target=lambda: stats.update(node.play()))
        th.start()
        g.spin_until(lambda: not th.is_alive(), 60)
        total = len(node.bag)
        g.spin_until(lambda: sum(t["count"] for t in rec.bag.topics.values()) >= total, 10)
        rec.close()
        node.destroy_node()
    assert stats["messages"] == total == 1 + 3 + 20 + 3 * 20 * 3
    a, b = by_topic(src), by_topic(out)
    assert sorted(a) == sorted(b)
    for topic, (type_name, msgs) in a.items():
        assert b[topic][0] == type_name, topic
        assert b[topic][1] == msgs, topic  # same bytes, same order
    assert rerun_check(out / "copy_0.mcap").returncode == 0
    # Recorded (simulated) time travels with the data: /clock and the header stamps.
    clocks = [m.clock.sec * 10**9 + m.clock.nanosec for t, m in rosbags_messages(out) if t == "/clock"]
    assert clocks == [k * 50_000_000 for k in range(20)]
    # At rate 2 the 0.95 s recording arrives in about 0.48 s: the receiving recorder's log times
    # (not the replay's own account) span half the source's, within scheduling noise (rate 1: 1.0).
    def robot_span(bag):
        t = [m[2] for m in BagReader(bag).messages() if m[0].startswith("/kilobot_") and not m[0].endswith("/traits")]
        return (max(t) - min(t)) / 1e9
    ratio = robot_span(out) / robot_span(src)
    assert 0.35 < ratio < 0.75, ratio
    assert stats["err_p99_ms"] < 50  # loose: shared CI cores; the benchmark measures the real figure


def test_load_bag_selects_topics_and_keeps_log_order(tmp_path):
    src = fixture_bag(tmp_path / "src")
    bag = load_bag(src, ["/kilobot_1/", "/clock"])
    names = sorted(t["name"] for t in bag.topics)
    assert names == ["/clock", "/kilobot_1/led", "/kilobot_1/light", "/kilobot_1/pose", "/kilobot_1/traits"]
    assert np.all(np.diff(bag.log_ns) >= 0)
    assert topic_selected("/kilobot_12/pose", ["/kilobot_1*"]) and not topic_selected("/kilobot_12/pose", ["/kilobot_1/"])


def test_qos_follows_the_recorded_offer():
    from rclpy.qos import DurabilityPolicy

    assert qos_from_yaml(LATCHED_QOS).durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert qos_from_yaml(DATA_QOS).durability == DurabilityPolicy.VOLATILE


@pytest.mark.parametrize("args,field", [(["--rate", "0"], "--rate"), (["--rate", "inf"], "--rate"), (["--topics", "/nope"], "--topics"),
                                        (["--wait-for-subscribers", "nan"], "--wait-for-subscribers")])
def test_replay_refuses_bad_input_with_one_line(tmp_path, capsys, args, field):
    src = fixture_bag(tmp_path / "src")
    assert cli_main(["replay", str(src), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and field in err[0]
