"""The recorder's hand-over from a robot's own topics to its swarm's bundle (no DDS traffic: the
callbacks are called as the executor would call them, in an order a race can produce)."""

import numpy as np
from std_msgs.msg import String

from kilobot_twin.nodes.recorder import RecorderNode
from kilobot_twin.recording import cdr
from kilobot_twin.recording.bag import BagReader
from kilobot_twin.recording.topics import DATA_QOS

from .graph import Graph, overrides

STEP_NS = 100_000_000


def _step(k: int, ids):
    """Robots ``ids``' messages of step k (their x = 10 * id + k, to tell them apart)."""
    ids = np.asarray(ids)
    return cdr.robot_records(k * STEP_NS, 10.0 * ids + k, 0.0, 0.0, 500.0, 1.0, 0, 31.0 * k, 31.0)


def test_robot_topics_hand_over_to_the_bundle_without_loss_or_duplicate(tmp_path):
    out = tmp_path / "b"
    with Graph() as g:
        rec = g.add(RecorderNode(context=g.context, parameter_overrides=overrides(
            out=str(out), topics="/kilobot_", discovery_period_s=60.0)))
        own_pose = rec._callback("/kilobot_0/pose", "geometry_msgs/msg/PoseStamped", DATA_QOS)
        for k in range(5):                       # robot 0 on its own topic: steps 0..4
            own_pose(cdr.rows(_step(k, [0])[0])[0])
        rec._on_members("/swarm", "/swarm/members", String(data='{"robots": [0, 1]}'))
        own_pose(cdr.rows(_step(5, [0])[0])[0])  # late on the old subscription: the bundle has it
        for k in range(3, 8):                    # bundles of steps 3..7 (3 and 4 already written)
            pose, light, led, _clock = _step(k, [0, 1])
            rec._on_bundle(cdr.bundle_cdr([0, 1], {"pose": pose, "light": light, "led": led}))
        acked = rec.robot_messages
        rec.close()
    reader = BagReader(out)
    x = {}
    for m in reader.messages():
        x.setdefault(m.topic, []).append(round(cdr.pose_stamped(m.data)[1], 9) if m.topic.endswith("/pose")
                                         else cdr.stamp_ns(m.data) // STEP_NS if m.topic.endswith("/light")
                                         else cdr.led(m.data))
    assert x["/kilobot_0/pose"] == [0, 1, 2, 3, 4, 5, 6, 7]           # each step once, in order
    assert x["/kilobot_1/pose"] == [13, 14, 15, 16, 17]
    assert x["/kilobot_0/light"] == x["/kilobot_1/light"] == [3, 4, 5, 6, 7]
    assert x["/kilobot_0/led"] == x["/kilobot_1/led"] == [0] * 5
    assert acked == sum(len(v) for v in x.values()) == 8 + 5 + 4 * 5


def test_bundle_items_follow_the_topics_prefixes(tmp_path):
    """``topics`` selects robot topics written from a bundle as it selects subscribed ones."""
    for prefixes, expected in (("/world", set()), ("/kilobot_1/", {"/kilobot_1/pose", "/kilobot_1/light"}),
                               ("/kilobot_", {f"/kilobot_{i}/{k}" for i in (0, 1, 2) for k in ("pose", "light")})):
        out = tmp_path / prefixes.strip("/").replace("/", "_")
        with Graph() as g:
            rec = g.add(RecorderNode(context=g.context, parameter_overrides=overrides(
                out=str(out), topics=prefixes, discovery_period_s=60.0)))
            rec._on_members("/swarm", "/swarm/members", String(data='{"robots": [0, 1, 2]}'))
            for k in range(3):
                pose, light, _led, _clock = _step(k, [0, 1, 2])
                rec._on_bundle(cdr.bundle_cdr([0, 1, 2], {"pose": pose, "light": light}))
            written = rec.robot_messages
            rec.close()
        counts = BagReader(out).counts() if out.exists() else {}
        assert set(counts) == expected and all(n == 3 for n in counts.values()), (prefixes, counts)
        assert written == 3 * len(expected)
        if expected == {"/kilobot_1/pose", "/kilobot_1/light"}:  # the right robot's bytes
            assert [round(cdr.pose_stamped(m.data)[1], 9) for m in BagReader(out).messages()
                    if m.topic == "/kilobot_1/pose"] == [10.0, 11.0, 12.0]
