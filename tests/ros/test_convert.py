"""Serialized publishing: the CDR the swarm builds decodes to the message path's values."""

import numpy as np
import pytest
from geometry_msgs.msg import PoseStamped
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Illuminance, TimeReference
from std_msgs.msg import ColorRGBA

from kilobot_twin.core.constants import LED_BLUE, LED_OFF, LED_RED
from kilobot_twin.ros import convert

TYPES = (PoseStamped, Illuminance, ColorRGBA, TimeReference)


def _samples(n=64, seed=3):
    rng = np.random.default_rng(seed)
    return [convert.RobotSample(robot_id=i, step=7, stamp_ns=int(rng.integers(0, 4 * 10**12)),
                                x_m=float(rng.normal()), y_m=float(rng.normal()),
                                theta_rad=float(rng.uniform(-np.pi, np.pi)), reading=float(rng.uniform(0, 1023)),
                                led=int(rng.choice([LED_RED, LED_BLUE, LED_OFF])), ticks=float(rng.uniform(0, 1e5)),
                                tick_hz=31.0, reading_variance=float(rng.uniform(0, 4)))
            for i in range(n)]


def test_vectorised_cdr_decodes_to_the_message_path():
    samples = _samples()
    cols = [np.array([getattr(s, k) for s in samples]) for k in
            ("stamp_ns", "x_m", "y_m", "theta_rad", "reading", "reading_variance", "led", "ticks")]
    encoded = convert.robot_cdr(*cols, tick_hz=31.0)
    for i, s in enumerate(samples):
        msgs = convert.RobotMessages().fill(s)
        for cls, topic, data in zip(TYPES, ("pose", "light", "led", "clock"), (e[i] for e in encoded)):
            ref = getattr(msgs, topic)
            assert deserialize_message(data, cls) == ref, (i, topic)
            assert len(data) == len(serialize_message(ref))


def test_cdr_readers_match_the_message_readers():
    s = _samples(1)[0]
    pose, _light, led, clock = (e[0] for e in convert.robot_cdr(
        s.stamp_ns, s.x_m, s.y_m, s.theta_rad, s.reading, s.reading_variance, s.led, s.ticks, 31.0))
    msgs = convert.RobotMessages().fill(s)
    assert convert.pose_xy_from_cdr(pose) == convert.pose_to_xytheta(msgs.pose)[:2]
    assert convert.led_from_cdr(led) == convert.led_from_color(msgs.led) == s.led
    assert convert.ticks_from_clock_cdr(clock, 31.0) == convert.ticks_from_clock(msgs.clock, 31.0)
    assert convert.stamp_ns_from_cdr(pose) == s.stamp_ns
    # Readers also take what rclpy serializes (other publishers, other frame ids).
    msgs.pose.header.frame_id = "a_much_longer_frame"
    assert convert.pose_xy_from_cdr(serialize_message(msgs.pose)) == (s.x_m, s.y_m)


def test_publisher_accepts_serialized_bytes():
    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node

    ctx = Context()
    rclpy.init(context=ctx)
    try:
        node = Node("cdr_pub", context=ctx)
        pub = node.create_publisher(PoseStamped, "cdr_test_pose", 10)
        pub.publish(convert.robot_cdr(0, 0.0, 0.0, 0.0, 0.0, 0.0, LED_OFF, 0.0, 31.0)[0][0])
        with pytest.raises(TypeError):
            pub.publish(bytearray(84))
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)
