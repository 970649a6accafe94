"""Serialized publishing: the CDR the swarm builds decodes to the message path's values."""

import numpy as np
import pytest
from geometry_msgs.msg import PoseStamped
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Illuminance, PointCloud2, TimeReference
from std_msgs.msg import ColorRGBA

from kilobot_twin.core.constants import LED_BLUE, LED_OFF, LED_RED
from kilobot_twin.recording import cdr
from kilobot_twin.ros import convert

from .message_path import RobotMessages, RobotSample

TYPES = (PoseStamped, Illuminance, ColorRGBA, TimeReference)


def _samples(n=64, seed=3):
    rng = np.random.default_rng(seed)
    return [RobotSample(robot_id=i, step=7, stamp_ns=int(rng.integers(0, 4 * 10**12)),
                                x_m=float(rng.normal()), y_m=float(rng.normal()),
                                theta_rad=float(rng.uniform(-np.pi, np.pi)), reading=float(rng.uniform(0, 1023)),
                                led=int(rng.choice([LED_RED, LED_BLUE, LED_OFF])), ticks=float(rng.uniform(0, 1e5)),
                                tick_hz=31.0, reading_variance=float(rng.uniform(0, 4)))
            for i in range(n)]


def test_vectorised_cdr_decodes_to_the_message_path():
    samples = _samples()
    cols = [np.array([getattr(s, k) for s in samples]) for k in
            ("stamp_ns", "x_m", "y_m", "theta_rad", "reading", "reading_variance", "led", "ticks")]
    encoded = cdr.robot_cdr(*cols, tick_hz=31.0)
    for i, s in enumerate(samples):
        msgs = RobotMessages().fill(s)
        for cls, topic, data in zip(TYPES, ("pose", "light", "led", "clock"), (e[i] for e in encoded)):
            ref = getattr(msgs, topic)
            assert deserialize_message(data, cls) == ref, (i, topic)
            # rclpy's serialization's length, padded to 4 bytes as DDS delivers it (the DDS probe
            # test in tests/nodes/test_run.py; rclpy leaves alignment gaps unset, so not its bytes)
            assert len(data) == len(serialize_message(ref)) + (-len(serialize_message(ref)) % 4)


def test_cdr_readers_match_the_message_readers():
    s = _samples(1)[0]
    pose, _light, led, clock = (e[0] for e in cdr.robot_cdr(
        s.stamp_ns, s.x_m, s.y_m, s.theta_rad, s.reading, s.reading_variance, s.led, s.ticks, 31.0))
    msgs = RobotMessages().fill(s)
    p, q = msgs.pose.pose.position, msgs.pose.pose.orientation
    assert cdr.pose_stamped(pose)[1:] == (p.x, p.y, q.z, q.w)
    assert cdr.led(led) == s.led
    assert cdr.time_reference(clock)[1] == msgs.clock.time_ref.sec * 10**9 + msgs.clock.time_ref.nanosec
    assert cdr.stamp_ns(pose) == s.stamp_ns
    # Readers also take what rclpy serializes (other publishers, other frame ids).
    msgs.pose.header.frame_id = "a_much_longer_frame"
    assert cdr.pose_stamped(serialize_message(msgs.pose))[1:3] == (s.x_m, s.y_m)


def test_publisher_accepts_serialized_bytes():
    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node

    ctx = Context()
    rclpy.init(context=ctx)
    try:
        node = Node("cdr_pub", context=ctx)
        pub = node.create_publisher(PoseStamped, "cdr_test_pose", 10)
        pub.publish(cdr.robot_cdr(0, 0.0, 0.0, 0.0, 0.0, 0.0, LED_OFF, 0.0, 31.0)[0][0])
        with pytest.raises(TypeError):
            pub.publish(bytearray(84))
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)


def test_robot_cloud_decodes_with_rclpy_and_our_reader():
    rng = np.random.default_rng(4)
    n = 7
    ids, x, y = np.arange(3, 3 + n), rng.normal(size=n), rng.normal(size=n)
    theta = rng.uniform(-10, 10, n)  # unwrapped, as the core holds it
    reading, led, ticks = rng.uniform(0, 1023, n), rng.integers(0, 3, n), rng.uniform(0, 1e4, n)
    raw = convert.robot_cloud_cdr(12_345_678_901, ids, x, y, theta, reading, led, ticks)
    m = deserialize_message(raw, PointCloud2)
    assert convert.time_to_ns(m.header.stamp) == 12_345_678_901 and m.header.frame_id == "arena"
    assert (m.height, m.width, m.point_step, m.row_step) == (1, n, 56, 56 * n) and m.is_dense
    assert [(f.name, f.offset) for f in m.fields] == [(k, cdr.CLOUD_DTYPE.fields[k][1])
                                                       for k in cdr.CLOUD_DTYPE.names]
    pts = np.frombuffer(bytes(m.data), dtype=cdr.CLOUD_DTYPE)
    stamp, ours = cdr.robot_cloud(raw)
    assert stamp == 12_345_678_901
    for p in (pts, ours):
        np.testing.assert_array_equal(p["id"], ids)
        np.testing.assert_array_equal(p["led"], led)
        np.testing.assert_array_equal(p["x"], x)
        np.testing.assert_array_equal(p["reading"], reading)
        np.testing.assert_array_equal(p["ticks"], ticks)
        np.testing.assert_allclose(np.exp(1j * p["theta"]), np.exp(1j * theta), atol=1e-12)
        assert np.all(np.abs(p["theta"]) <= np.pi)
    # A different swarm size gets its own layout.
    assert cdr.robot_cloud(convert.robot_cloud_cdr(0, [1], 0, 0, 0, 0, 0, 0))[1].shape == (1,)


@pytest.mark.parametrize("dt,period,n_steps,expected", [
    (0.1, 1.0, 30, [0, 10, 20, 30]),        # once per simulated second
    (0.1, 0.0, 5, [0, 1, 2, 3, 4, 5]),      # 0: every step
    (0.5, 0.2, 3, [0, 1, 2, 3]),            # period below the step: every step
    (1 / 31, 1.0, 62, [0, 31, 62]),         # a step that does not divide the period
    (0.3, 1.0, 10, [0, 4, 7, 10]),          # first step of each new second: 1.2 s, 2.1 s, 3.0 s
])
def test_clock_steps(dt, period, n_steps, expected):
    mask = convert.clock_steps(np.arange(n_steps + 1), dt, period)
    assert np.flatnonzero(mask).tolist() == expected
    # Scalar and array calls agree (robots ask step by step, the world for all steps at once).
    assert [bool(convert.clock_steps(k, dt, period)) for k in range(n_steps + 1)] == mask.tolist()


@pytest.mark.parametrize("frame_id", ["arena", "a", "map_frame_x"])
@pytest.mark.parametrize("padding", [0, 3, 7])
def test_robot_cloud_reader_parses_from_the_front(frame_id, padding):
    """A cloud serialized by rclpy from a message object (not by our encoder), with other header
    lengths (other alignments) and the trailing padding a DDS buffer carries between processes."""
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import PointField

    n = 5
    pts = np.zeros(n, dtype=cdr.CLOUD_DTYPE)
    pts["id"], pts["led"] = np.arange(10, 10 + n), [0, 1, 2, 1, 0]
    pts["x"], pts["y"], pts["ticks"] = np.linspace(-1, 1, n), np.linspace(2, 3, n), np.arange(n) * 31.0
    m = PointCloud2()
    m.header.frame_id = frame_id
    m.header.stamp.sec, m.header.stamp.nanosec = 7, 250
    m.height, m.width = 1, n
    m.fields = [PointField(name=k, offset=cdr.CLOUD_DTYPE.fields[k][1], datatype=dt, count=1)
                for k, _, dt in convert.CLOUD_FIELDS]
    m.point_step, m.row_step, m.is_dense = pts.itemsize, pts.nbytes, True
    m.data = pts.tobytes()
    raw = serialize_message(m) + bytes(padding)
    stamp, got = cdr.robot_cloud(raw)
    assert stamp == 7 * 10**9 + 250
    np.testing.assert_array_equal(got, pts)
