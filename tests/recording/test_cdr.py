"""The rclpy-free CDR readers and writers against rclpy's own serialisation (a second implementation)."""

import numpy as np
import pytest
from geometry_msgs.msg import PoseStamped
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Illuminance, Image, TimeReference
from std_msgs.msg import ColorRGBA, Float64, String

from kilobot_twin.core.constants import LED_BLUE, LED_OFF, LED_RED
from kilobot_twin.recording import cdr


@pytest.mark.parametrize("frame_id", ["arena", "a", "map_frame_x"])
@pytest.mark.parametrize("padding", [0, 3])
def test_readers_take_what_rclpy_serializes(frame_id, padding):
    """Other header lengths (other alignments) and the trailing padding a DDS buffer may carry."""
    def raw(msg):
        return serialize_message(msg) + bytes(padding)

    pose = PoseStamped()
    pose.header.frame_id = frame_id
    pose.header.stamp.sec, pose.header.stamp.nanosec = 12, 345
    pose.pose.position.x, pose.pose.position.y = -0.125, 0.5
    pose.pose.orientation.z, pose.pose.orientation.w = 0.6, 0.8
    assert cdr.pose_stamped(raw(pose)) == (12_000_000_345, -0.125, 0.5, 0.6, 0.8)
    assert cdr.stamp_ns(raw(pose)) == 12_000_000_345

    light = Illuminance(illuminance=511.5, variance=2.25)
    light.header.frame_id, light.header.stamp.sec = frame_id, 3
    assert cdr.illuminance(raw(light)) == (3_000_000_000, 511.5, 2.25)

    ref = TimeReference(source="kilo_ticks")
    ref.header.frame_id, ref.header.stamp.nanosec = frame_id, 7
    ref.time_ref.sec, ref.time_ref.nanosec = 99, 1
    assert cdr.time_reference(raw(ref)) == (7, 99_000_000_001)

    img = Image(height=2, width=3, encoding="32FC1", step=12)
    img.header.frame_id = frame_id
    values = np.arange(6, dtype="<f4").reshape(2, 3) / 4
    img.data = values.tobytes()
    np.testing.assert_array_equal(cdr.image_32fc1(raw(img)), values)

    clock = Clock()
    clock.clock.sec, clock.clock.nanosec = 5, 6
    assert cdr.clock_ns(raw(clock)) == 5_000_000_006
    assert cdr.float64(raw(Float64(data=-2.5))) == -2.5
    assert cdr.string(raw(String(data=frame_id * 3))) == frame_id * 3


@pytest.mark.parametrize("rgba,expected", [((1, 0, 0, 1), LED_RED), ((0, 0, 1, 1), LED_BLUE), ((0, 0, 0, 0), LED_OFF),
                                           ((0.9, 0, 0.2, 0.5), LED_RED), ((0.1, 0, 0.2, 1), LED_BLUE)])
def test_led_of_a_colour(rgba, expected):
    r, g, b, a = rgba
    assert cdr.led(serialize_message(ColorRGBA(r=float(r), g=float(g), b=float(b), a=float(a)))) == expected


def test_writers_decode_with_rclpy():
    assert deserialize_message(cdr.string_cdr('{"a": 1}'), String).data == '{"a": 1}'
    assert deserialize_message(cdr.float64_cdr(0.1), Float64).data == 0.1
    c = deserialize_message(cdr.clock_cdr(3_000_000_001), Clock).clock
    assert (c.sec, c.nanosec) == (3, 1)
    field = np.linspace(0, 1, 15).reshape(3, 5)
    m = deserialize_message(cdr.image_cdr(field, 2_500_000_000), Image)
    assert (m.height, m.width, m.encoding, m.step, m.is_bigendian) == (3, 5, "32FC1", 20, 0)
    assert (m.header.stamp.sec, m.header.stamp.nanosec, m.header.frame_id) == (2, 500_000_000, "arena")
    np.testing.assert_array_equal(np.frombuffer(bytes(m.data), "<f4").reshape(3, 5), field.astype(np.float32))


def test_bundle_is_a_uint8_multiarray_of_the_robots_own_messages():
    """rclpy's deserializer reads the bundle as a std_msgs/UInt8MultiArray; its header, read here
    with struct from the layout in cdr.py's comment, and every item decode with rclpy to the
    robot's own message (stamp, x, reading, colour)."""
    import struct

    from std_msgs.msg import UInt8MultiArray

    ids = np.array([7, 2, 11])
    x = np.array([0.1, -0.2, 0.3])
    records = cdr.robot_records(5_000_000_001, x, [0.0, 1.0, 2.0], [0.5, 7.0, -3.0], [10.0, 20.0, 30.0], 4.0,
                                [LED_RED, LED_OFF, LED_BLUE], [31.0, 62.0, 93.0], 31.0)
    blocks = dict(zip(cdr.BUNDLE_KINDS, records))
    del blocks["clock"]  # not a clock step
    raw = cdr.bundle_cdr(ids, blocks)
    body = bytes(deserialize_message(raw, UInt8MultiArray).data)
    magic, n, m = struct.unpack_from("<4sII", body)
    assert (magic, n, m) == (b"KTB1", 3, 3)
    assert list(struct.unpack_from("<3I", body, 12)) == [7, 2, 11]
    table = struct.unpack_from("<6I", body, 24)
    sizes = table[1::2]
    assert [cdr.BUNDLE_KINDS[k] for k in table[0::2]] == ["pose", "light", "led"]
    pos = 48
    items = {}
    for kind, size in zip(("pose", "light", "led"), sizes):
        items[kind] = [body[pos + i * size:pos + (i + 1) * size] for i in range(3)]
        pos += 3 * size
    assert pos == len(body)
    for i in range(3):
        p = deserialize_message(items["pose"][i], PoseStamped)
        assert (p.header.stamp.sec, p.header.stamp.nanosec, p.pose.position.x) == (5, 1, x[i])
        assert deserialize_message(items["light"][i], Illuminance).illuminance == [10.0, 20.0, 30.0][i]
        c = deserialize_message(items["led"][i], ColorRGBA)
        assert (c.r, c.b, c.a) == [(1.0, 0.0, 1.0), (0.0, 0.0, 0.0), (0.0, 1.0, 1.0)][i]
    # The reader gives back the same slices.
    got = {kind: [bytes(block[i * size:(i + 1) * size]) for i in range(len(rids))]
           for kind, rids, block, size in cdr.read_bundle(raw)}
    assert got == items
    with pytest.raises(ValueError):
        cdr.read_bundle(serialize_message(UInt8MultiArray(data=list(b"KTB1" + bytes(20)))))
