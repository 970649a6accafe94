"""The few CDR layouts read without rclpy (the gap workflow reads bags as plain data).

A serialized ROS 2 message starts with a 4-byte encapsulation header (``00 01`` = CDR little
endian); fields follow, each aligned to its own size counted from the end of that header.
"""

from __future__ import annotations

import struct

from ..core.constants import LED_BLUE, LED_OFF, LED_RED


def _align(offset: int, size: int) -> int:
    return (offset + size - 1) // size * size


def _order(data: bytes) -> str:
    if len(data) < 4 or data[0] != 0 or data[1] not in (0, 1):
        raise ValueError("not a CDR buffer")
    return "<" if data[1] == 1 else ">"


def pose_stamped(data: bytes) -> tuple[int, float, float, float, float]:
    """geometry_msgs/PoseStamped -> (header stamp ns, x m, y m, orientation z, orientation w)."""
    e = _order(data)
    body = memoryview(data)[4:]
    sec, nsec, n = struct.unpack_from(e + "iII", body, 0)   # stamp, then frame_id's length (incl. NUL)
    off = _align(12 + n, 8)
    x, y, _z, _qx, _qy, qz, qw = struct.unpack_from(e + "7d", body, off)
    return sec * 1_000_000_000 + nsec, x, y, qz, qw


def color_rgba(data: bytes) -> tuple[float, float, float, float]:
    """std_msgs/ColorRGBA -> (r, g, b, a)."""
    return struct.unpack_from(_order(data) + "4f", data, 4)


def led_from_rgba(r: float, g: float, b: float, a: float) -> int:
    """The LED state a ColorRGBA shows: off when transparent, else red or blue."""
    if a == 0.0:
        return LED_OFF
    return LED_RED if r >= b else LED_BLUE
