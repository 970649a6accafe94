"""The twin's message types as serialized CDR, read and written without rclpy.

A serialized ROS 2 message (XCDR1) starts with a 4-byte encapsulation header (``00 01`` = CDR
little endian, ``00 00`` = big endian); fields follow, each aligned to its own size counted from
the end of that header. Readers parse from the front, so a buffer that crossed DDS and carries
padding after its last field reads the same; writers write little endian with zero padding.

Robot topics (:data:`~kilobot_twin.recording.topics.ROBOT_TYPES`, frame ``arena``): ``pose`` x, y
in m and the heading as a yaw quaternion; ``light`` the raw reading 0-1023 in ``illuminance`` and
its variance; ``led`` red (1,0,0,1), blue (0,0,1,1), off (0,0,0,0); ``clock`` the robot's own
clock (kilo_ticks / tick rate) in ``time_ref``, world time in ``header.stamp``.
"""

from __future__ import annotations

import struct

import numpy as np

from ..core.constants import LED_BLUE, LED_OFF, LED_RED
from .topics import ROBOT_DATA

NS_PER_S = 1_000_000_000
FRAME_ID = "arena"
#: ColorRGBA of each LED state.
LED_RGBA = {LED_RED: (1.0, 0.0, 0.0, 1.0), LED_BLUE: (0.0, 0.0, 1.0, 1.0), LED_OFF: (0.0, 0.0, 0.0, 0.0)}


def _align(offset: int, size: int) -> int:
    return (offset + size - 1) // size * size


# --- readers ------------------------------------------------------------------------------------

def _order(data: bytes) -> str:
    if len(data) < 4 or data[0] != 0 or data[1] not in (0, 1):
        raise ValueError("not a CDR buffer")
    return "<" if data[1] == 1 else ">"


def _header(data: bytes) -> tuple[str, int, int]:
    """(byte order, header stamp ns, body offset just after a leading std_msgs/Header)."""
    e = _order(data)
    sec, nsec, n = struct.unpack_from(e + "iII", data, 4)  # stamp, then frame_id's length (incl. NUL)
    return e, sec * NS_PER_S + nsec, 12 + n


def _at(data: bytes, e: str, fmt: str, body_offset: int) -> tuple:
    """Primitives of one size (``fmt`` like ``'2d'``) at the first aligned body offset from ``body_offset``."""
    return struct.unpack_from(e + fmt, data, 4 + _align(body_offset, struct.calcsize(fmt[-1])))


def stamp_ns(data: bytes) -> int:
    """``header.stamp`` (ns) of a serialized stamped message."""
    return _header(data)[1]


def pose_stamped(data: bytes) -> tuple[int, float, float, float, float]:
    """geometry_msgs/PoseStamped -> (header stamp ns, x m, y m, orientation z, orientation w)."""
    e, stamp, off = _header(data)
    x, y, _z, _qx, _qy, qz, qw = _at(data, e, "7d", off)
    return stamp, x, y, qz, qw


def illuminance(data: bytes) -> tuple[int, float, float]:
    """sensor_msgs/Illuminance -> (header stamp ns, illuminance, variance)."""
    e, stamp, off = _header(data)
    return (stamp, *_at(data, e, "2d", off))


def time_reference(data: bytes) -> tuple[int, int]:
    """sensor_msgs/TimeReference -> (header stamp ns, time_ref ns)."""
    e, stamp, off = _header(data)
    sec, nsec = _at(data, e, "iI", off)
    return stamp, sec * NS_PER_S + nsec


def color_rgba(data: bytes) -> tuple[float, float, float, float]:
    """std_msgs/ColorRGBA -> (r, g, b, a)."""
    return struct.unpack_from(_order(data) + "4f", data, 4)


def led_from_rgba(r: float, g: float, b: float, a: float) -> int:
    """The LED state a ColorRGBA shows: off when transparent, else red or blue."""
    if a == 0.0:
        return LED_OFF
    return LED_RED if r >= b else LED_BLUE


def led(data: bytes) -> int:
    """The LED state of a serialized std_msgs/ColorRGBA."""
    return led_from_rgba(*color_rgba(data))


def clock_ns(data: bytes) -> int:
    """rosgraph_msgs/Clock -> time in ns."""
    sec, nsec = struct.unpack_from(_order(data) + "iI", data, 4)
    return sec * NS_PER_S + nsec


def float64(data: bytes) -> float:
    """std_msgs/Float64 -> its value."""
    return struct.unpack_from(_order(data) + "d", data, 4)[0]


def string(data: bytes) -> str:
    """std_msgs/String -> its text."""
    (n,) = struct.unpack_from(_order(data) + "I", data, 4)
    return bytes(data[8:8 + n]).rstrip(b"\x00").decode()


def image_32fc1(data: bytes) -> np.ndarray:
    """sensor_msgs/Image with encoding ``32FC1`` -> (height, width) float32 array."""
    e, _stamp, off = _header(data)
    height, width, n = _at(data, e, "3I", off)
    start = 4 + _align(off, 4) + 12
    encoding = bytes(data[start:start + n]).rstrip(b"\x00").decode()
    if encoding != "32FC1":
        raise ValueError(f"expected a 32FC1 image, got {encoding}")
    pos = start + n
    big = data[pos]
    pos = 4 + _align(pos + 1 - 4, 4) + 4  # is_bigendian, then step (uint32)
    (n_bytes,) = struct.unpack_from(e + "I", data, pos)
    return np.frombuffer(data, dtype=">f4" if big else "<f4", count=n_bytes // 4, offset=pos + 4).reshape(height, width)


#: One point of a swarm's robot cloud (``/swarm/robots``, sensor_msgs/PointCloud2), packed in this order.
CLOUD_DTYPE = np.dtype([("id", "<u4"), ("led", "<u4"), ("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("theta", "<f8"),
                        ("reading", "<f8"), ("ticks", "<f8")])


def robot_cloud(data: bytes) -> tuple[int, np.ndarray]:
    """(stamp ns, points as a :data:`CLOUD_DTYPE` array) of a serialized robot cloud.

    Raises ValueError for a PointCloud2 that is not laid out as :data:`CLOUD_DTYPE`.
    """
    e, stamp, pos = _header(data)
    if e != "<":
        raise ValueError("expected little-endian CDR")

    def u32(pos: int) -> tuple[int, int]:
        pos = _align(pos, 4)
        return struct.unpack_from("<I", data, 4 + pos)[0], pos + 4

    height, pos = u32(pos)
    width, pos = u32(pos)
    n_fields, pos = u32(pos)
    names = []
    for _ in range(n_fields):
        n_chars, pos = u32(pos)
        names.append(bytes(data[4 + pos:4 + pos + n_chars]).rstrip(b"\x00").decode())
        pos += n_chars
        _offset, pos = u32(pos)
        pos += 1  # datatype (uint8)
        _count, pos = u32(pos)
    pos += 1  # is_bigendian
    point_step, pos = u32(pos)
    _row_step, pos = u32(pos)
    n_bytes, pos = u32(pos)
    if tuple(names) != CLOUD_DTYPE.names or point_step != CLOUD_DTYPE.itemsize or n_bytes != height * width * point_step:
        raise ValueError(f"not a robot cloud: fields {names}, point_step {point_step}, {n_bytes} data bytes")
    return stamp, np.frombuffer(data, dtype=CLOUD_DTYPE, count=height * width, offset=4 + pos)


# --- writers ------------------------------------------------------------------------------------
#
# A swarm writes every robot's four messages into NumPy record arrays laid out as their CDR and
# publishes slices of one buffer (rclpy's Publisher.publish() takes serialized bytes as they are):
# filling Python message objects costs a validated setter call per field.

_CDR_HEADER = b"\x00\x01\x00\x00"  # CDR_LE, no options


def _cdr_string(text: str) -> bytes:
    raw = text.encode() + b"\x00"
    return len(raw).to_bytes(4, "little") + raw


class _CdrRecord:
    """One message type's CDR layout: constant bytes plus named primitive fields at fixed offsets.

    The bytes end with zeros up to a multiple of 4, as a DDS subscriber receives them (Fast DDS
    pads the serialized payload; a TimeReference of 47 bytes arrives as 48): what a swarm
    publishes, its bundle carries and the bag holds are then the same bytes.
    """

    def __init__(self, constant: bytes, fields: dict[str, tuple[int, str]]):
        constant += bytes(-len(constant) % 4)
        self.template = np.frombuffer(constant, dtype=np.uint8)
        self.dtype = np.dtype({"names": list(fields), "formats": [f for _, f in fields.values()],
                               "offsets": [o for o, _ in fields.values()], "itemsize": len(constant)})

    def empty(self, n: int) -> np.ndarray:
        """``n`` records holding the constant bytes (strings, zero padding)."""
        return np.tile(self.template, n).view(self.dtype)


def _stamped(tail: list[tuple[str, str, int]], tail_bytes: bytes = b"") -> _CdrRecord:
    """Header (frame ``arena``) + primitives ``(name, numpy format, size)`` in order + constant ``tail_bytes``."""
    body = bytearray(bytes(8) + _cdr_string(FRAME_ID))
    fields = {"sec": (4, "<i4"), "nanosec": (8, "<u4")}
    for name, fmt, size in tail:
        start = _align(len(body), size)
        body += bytes(start - len(body) + size)
        fields[name] = (4 + start, fmt)
    return _CdrRecord(_CDR_HEADER + bytes(body + tail_bytes), fields)


_POSE_CDR = _stamped([(k, "<f8", 8) for k in ("x", "y", "z", "qx", "qy", "qz", "qw")])
_LIGHT_CDR = _stamped([("illuminance", "<f8", 8), ("variance", "<f8", 8)])
_CLOCK_CDR = _stamped([("ref_sec", "<i4", 4), ("ref_nanosec", "<u4", 4)], _cdr_string("kilo_ticks"))
_LED_CDR = _CdrRecord(_CDR_HEADER + bytes(16), {c: (4 + 4 * i, "<f4") for i, c in enumerate("rgba")})
_LED_TABLE = np.array([LED_RGBA[k] for k in range(max(LED_RGBA) + 1)], dtype=np.float32)


def _split_ns(ns, n: int) -> tuple[np.ndarray, np.ndarray]:
    return np.divmod(np.broadcast_to(np.asarray(ns, dtype=np.int64), (n,)), NS_PER_S)


def rows(records: np.ndarray) -> list[bytes]:
    """The records as separate ``bytes`` objects (what Publisher.publish takes)."""
    buf = records.tobytes()
    size = records.dtype.itemsize
    return [buf[i:i + size] for i in range(0, len(buf), size)]


def robot_records(stamp_ns, x_m, y_m, theta_rad, reading, reading_variance, led, ticks, tick_hz: float):
    """``(pose, light, led, clock)`` of robots as NumPy record arrays laid out as their CDR (one
    record per robot; ``.tobytes()`` of a record is the serialized message).

    Every argument but ``tick_hz`` is a scalar or an array over the robots (shape ``(n,)``); the
    bytes decode to what :meth:`kilobot_twin.ros.convert.RobotMessages.fill` puts into the messages.
    """
    x_m = np.atleast_1d(np.asarray(x_m, dtype=np.float64))
    n = x_m.shape[0]
    pose, light, clock, colors = _POSE_CDR.empty(n), _LIGHT_CDR.empty(n), _CLOCK_CDR.empty(n), _LED_CDR.empty(n)
    for rec in (pose, light, clock):
        rec["sec"], rec["nanosec"] = _split_ns(stamp_ns, n)
    pose["x"], pose["y"] = x_m, y_m
    half = 0.5 * np.asarray(theta_rad, dtype=np.float64)
    pose["qz"], pose["qw"] = np.sin(half), np.cos(half)
    light["illuminance"], light["variance"] = reading, reading_variance
    rgba = _LED_TABLE[np.asarray(led, dtype=np.int64)]
    for i, c in enumerate("rgba"):
        colors[c] = np.broadcast_to(rgba[..., i], (n,))
    ref_ns = np.rint(np.asarray(ticks, dtype=np.float64) / tick_hz * NS_PER_S).astype(np.int64)
    clock["ref_sec"], clock["ref_nanosec"] = _split_ns(ref_ns, n)
    return pose, light, colors, clock


def robot_cdr(stamp_ns, x_m, y_m, theta_rad, reading, reading_variance, led, ticks, tick_hz: float):
    """Serialized ``(pose, light, led, clock)`` messages of robots, each a list of ``bytes``
    (:func:`robot_records`, one ``bytes`` per robot)."""
    return tuple(rows(r) for r in robot_records(stamp_ns, x_m, y_m, theta_rad, reading, reading_variance, led,
                                                ticks, tick_hz))


# --- a swarm's bundle: every robot message of one step in one message ------------------------------
#
# A batched swarm publishes, after its robots' own messages of a step, the same bytes once more as
# one std_msgs/UInt8MultiArray (``/swarm/bundle``): the recorder writes each slice into the bag
# as the message of its robot topic, so that a step costs one DDS message, not one per robot and
# topic (README, "nodes"). Content, little endian:
#   b"KTB1", u32 robots n, u32 blocks m, u32 ids[n], m x (u32 kind, u32 item bytes),
#   then the m blocks in that order, each n items: item i is robot ids[i]'s serialized message.
# ``kind`` indexes BUNDLE_KINDS (the robot data topic suffixes, :data:`~kilobot_twin.recording.topics.ROBOT_DATA`).

BUNDLE_KINDS = ROBOT_DATA
_BUNDLE_MAGIC = b"KTB1"


def bundle_cdr(ids, blocks) -> bytes:
    """Serialized std_msgs/UInt8MultiArray holding ``blocks`` (``{kind: record array over the robots
    ids}``, e.g. from :func:`robot_records`), in :data:`BUNDLE_KINDS` order."""
    ids = np.ascontiguousarray(np.atleast_1d(ids), dtype="<u4")
    kinds = [k for k in BUNDLE_KINDS if k in blocks]
    head = struct.pack("<4sII", _BUNDLE_MAGIC, ids.shape[0], len(kinds)) + ids.tobytes()
    head += b"".join(struct.pack("<II", BUNDLE_KINDS.index(k), blocks[k].dtype.itemsize) for k in kinds)
    for k in kinds:
        if blocks[k].shape != ids.shape:
            raise ValueError(f"bundle block {k}: {blocks[k].shape[0]} records for {ids.shape[0]} robots")
    body = head + b"".join(blocks[k].tobytes() for k in kinds)
    # UInt8MultiArray: layout.dim (empty sequence), layout.data_offset, then data (length + bytes).
    return _CDR_HEADER + struct.pack("<III", 0, 0, len(body)) + body


def read_bundle(data: bytes) -> list[tuple[str, np.ndarray, memoryview, int]]:
    """A serialized bundle -> ``[(kind, robot ids, block bytes, item bytes), ...]`` (item ``i`` of a
    block is ``block[i * size:(i + 1) * size]``). Raises ValueError for anything else."""
    e = _order(data)
    n_dims, _offset, n_bytes = struct.unpack_from(e + "III", data, 4)
    if e != "<" or n_dims != 0 or 16 + n_bytes > len(data):
        raise ValueError("not a bundle")
    view = memoryview(data)[16:16 + n_bytes]
    magic, n, m = struct.unpack_from("<4sII", view, 0)
    pos = 12 + 4 * n + 8 * m
    if magic != _BUNDLE_MAGIC or pos > n_bytes:
        raise ValueError("not a bundle")
    ids = np.frombuffer(view, dtype="<u4", count=n, offset=12)
    table = np.frombuffer(view, dtype="<u4", count=2 * m, offset=12 + 4 * n).reshape(m, 2)
    out = []
    for kind, size in table.tolist():
        if kind >= len(BUNDLE_KINDS) or pos + n * size > n_bytes:
            raise ValueError("bundle table disagrees with its length")
        out.append((BUNDLE_KINDS[kind], ids, view[pos:pos + n * size], size))
        pos += n * size
    if pos != n_bytes:
        raise ValueError("bundle table disagrees with its length")
    return out


def string_cdr(text: str) -> bytes:
    """A serialized std_msgs/String."""
    return _CDR_HEADER + _cdr_string(text)


def float64_cdr(value: float) -> bytes:
    """A serialized std_msgs/Float64."""
    return _CDR_HEADER + struct.pack("<d", value)


def clock_cdr(ns: int) -> bytes:
    """A serialized rosgraph_msgs/Clock."""
    return _CDR_HEADER + struct.pack("<iI", *divmod(int(ns), NS_PER_S))


def image_cdr(intensity: np.ndarray, stamp_ns: int) -> bytes:
    """A light-field raster (rows top = +y, as in a picture) as a serialized 32FC1 sensor_msgs/Image."""
    img = np.ascontiguousarray(intensity, dtype="<f4")
    body = bytearray(struct.pack("<iI", *divmod(int(stamp_ns), NS_PER_S)) + _cdr_string(FRAME_ID))
    body += bytes(_align(len(body), 4) - len(body)) + struct.pack("<II", *img.shape) + _cdr_string("32FC1") + b"\x00"
    body += bytes(_align(len(body), 4) - len(body)) + struct.pack("<II", 4 * img.shape[1], img.nbytes)
    return _CDR_HEADER + bytes(body) + img.tobytes()
