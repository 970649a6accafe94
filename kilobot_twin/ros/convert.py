"""Every conversion between ROS messages and the core's values lives here (and only here).

Robot topics (namespace ``kilobot_<id>``, frame ``arena``):

===========  =========================  =====================================================
``pose``     geometry_msgs/PoseStamped  x, y in m, heading as a yaw quaternion
``light``    sensor_msgs/Illuminance    raw ADC reading 0-1023 in ``illuminance``; variance of
                                        the averaged reading in ``variance``
``led``      std_msgs/ColorRGBA         red (1,0,0,1), blue (0,0,1,1), off (0,0,0,0)
``clock``    sensor_msgs/TimeReference  ``time_ref`` = the robot's own clock, kilo_ticks /
                                        31 Hz; ``header.stamp`` = world time (clock drift is
                                        ``time_ref - stamp``); at step 0 and then once per
                                        ``clock_period_s`` of simulated time (world document,
                                        default 1 s; 0 = every step): see
                                        :func:`clock_steps`
``traits``   std_msgs/String            JSON: id, traits, behaviour, seed, run (transient-local)
===========  =========================  =====================================================

A batched ``swarm`` process also publishes all its robots' state of a step as one
sensor_msgs/PointCloud2 (``/swarm/robots``, one point per robot, fields :data:`CLOUD_FIELDS`,
published after the robots' own messages of that step) and, transient-local, the ids it
covers (``/swarm/members``, JSON): nodes that need the whole swarm each step (the world's
lockstep handshake, the analysis) take one message per step instead of one per robot and topic.
"""

from __future__ import annotations

import array
import json
import math
import struct
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Illuminance, Image, PointCloud2, PointField, TimeReference
from std_msgs.msg import ColorRGBA, String

from ..core.constants import LED_BLUE, LED_OFF, LED_RED
from ..core.traits import RobotTraits

FRAME_ID = "arena"
NS_PER_S = 1_000_000_000

_LED_RGBA = {LED_RED: (1.0, 0.0, 0.0, 1.0), LED_BLUE: (0.0, 0.0, 1.0, 1.0), LED_OFF: (0.0, 0.0, 0.0, 0.0)}


@dataclass
class RobotSample:
    """What one robot reports after a step (plain values, no ROS types)."""

    robot_id: int
    step: int
    stamp_ns: int
    x_m: float
    y_m: float
    theta_rad: float
    reading: float
    led: int
    ticks: float
    tick_hz: float
    reading_variance: float = 0.0


# --- time ------------------------------------------------------------------------------

def step_stamp_ns(step: int, dt_s: float) -> int:
    """Simulated time of a step in integer nanoseconds (exact for the lockstep handshake)."""
    return int(round(step * dt_s * NS_PER_S))


def ns_to_time(ns: int, msg: Time | None = None) -> Time:
    msg = msg if msg is not None else Time()
    msg.sec, msg.nanosec = divmod(int(ns), NS_PER_S)
    return msg


def time_to_ns(t: Time) -> int:
    return int(t.sec) * NS_PER_S + int(t.nanosec)


def clock_msg(ns: int) -> Clock:
    m = Clock()
    ns_to_time(ns, m.clock)
    return m


def stamp_ns_from_cdr(data: bytes) -> int:
    """``header.stamp`` of a serialized stamped message (CDR) without deserialising it.

    After the 4-byte encapsulation header, a std_msgs/Header starts with stamp.sec (int32)
    and stamp.nanosec (uint32); the byte order is given by the encapsulation id.
    """
    little = data[1] == 1
    sec, nsec = struct.unpack_from("<iI" if little else ">iI", data, 4)
    return sec * NS_PER_S + nsec


def clock_steps(steps, dt_s: float, period_s: float) -> np.ndarray:
    """Whether a robot publishes its ``clock`` at each of ``steps`` (step indices): at step 0 and at
    the first step of every new ``period_s`` of simulated time (in integer ns, so that robots, the
    world and the recorder agree exactly); every step when ``period_s <= 0``."""
    k = np.asarray(steps, dtype=np.int64)
    if period_s <= 0:
        return np.ones(k.shape, dtype=bool)
    p = int(round(period_s * NS_PER_S))
    t = np.rint(k * dt_s * NS_PER_S).astype(np.int64)
    t_prev = np.rint((k - 1) * dt_s * NS_PER_S).astype(np.int64)
    return (k == 0) | (t // p != t_prev // p)


# --- robot messages ------------------------------------------------------------------------

def yaw_from_quaternion(z: float, w: float) -> float:
    return 2.0 * math.atan2(z, w)


class RobotMessages:
    """Reusable messages of one robot, filled from a :class:`RobotSample` (no per-step allocation)."""

    def __init__(self):
        self.pose = PoseStamped()
        self.pose.header.frame_id = FRAME_ID
        self.light = Illuminance()
        self.light.header.frame_id = FRAME_ID
        self.led = ColorRGBA()
        self.clock = TimeReference()
        self.clock.header.frame_id = FRAME_ID
        self.clock.source = "kilo_ticks"

    def fill(self, s: RobotSample) -> "RobotMessages":
        for h in (self.pose.header, self.light.header, self.clock.header):
            ns_to_time(s.stamp_ns, h.stamp)
        p = self.pose.pose
        p.position.x = float(s.x_m)
        p.position.y = float(s.y_m)
        half = 0.5 * float(s.theta_rad)
        p.orientation.z = math.sin(half)
        p.orientation.w = math.cos(half)
        self.light.illuminance = float(s.reading)
        self.light.variance = float(s.reading_variance)
        self.led.r, self.led.g, self.led.b, self.led.a = _LED_RGBA[int(s.led)]
        ns_to_time(int(round(s.ticks / s.tick_hz * NS_PER_S)), self.clock.time_ref)
        return self


def pose_to_xytheta(msg: PoseStamped) -> tuple[float, float, float]:
    """(x m, y m, heading rad in (-pi, pi])."""
    p = msg.pose
    return p.position.x, p.position.y, yaw_from_quaternion(p.orientation.z, p.orientation.w)


def led_from_color(msg: ColorRGBA) -> int:
    if msg.a == 0.0:
        return LED_OFF
    return LED_RED if msg.r >= msg.b else LED_BLUE


def ticks_from_clock(msg: TimeReference, tick_hz: float) -> float:
    """The robot's kilo_ticks (to 1 ns of its clock) from its ``clock`` message."""
    return time_to_ns(msg.time_ref) / NS_PER_S * tick_hz


# --- robot messages as serialized CDR ---------------------------------------------------------------
#
# rclpy's Publisher.publish() also takes the serialized bytes of a message (published as they are).
# Filling Python message objects costs a validated setter call per field plus a conversion to C
# per publish; a swarm instead writes every robot's four messages into NumPy record arrays laid
# out as their CDR (little endian, XCDR1: 4-byte encapsulation header, then each primitive aligned
# to its size counted from the end of that header) and publishes slices of one buffer.

_CDR_HEADER = b"\x00\x01\x00\x00"  # CDR_LE, no options


def _align(offset: int, size: int) -> int:
    return (offset + size - 1) // size * size


def _cdr_string(text: str) -> bytes:
    raw = text.encode() + b"\x00"
    return len(raw).to_bytes(4, "little") + raw


def _header_layout(frame_id: str) -> tuple[bytes, int]:
    """A std_msgs/Header with a zero stamp (body bytes) and the body offset where it ends."""
    body = bytes(8) + _cdr_string(frame_id)
    return body, len(body)


class _CdrRecord:
    """One message type's CDR layout: constant bytes plus named primitive fields at fixed offsets."""

    def __init__(self, constant: bytes, fields: dict[str, tuple[int, str]]):
        self.size = len(constant)
        self.template = np.frombuffer(constant, dtype=np.uint8)
        self.dtype = np.dtype({"names": list(fields), "formats": [f for _, f in fields.values()],
                               "offsets": [o for o, _ in fields.values()], "itemsize": self.size})

    def empty(self, n: int) -> np.ndarray:
        """``n`` records holding the constant bytes (strings, zero padding)."""
        return np.tile(self.template, n).view(self.dtype)


def _stamped(frame_id: str, tail: list[tuple[str, str, int]], tail_bytes: bytes = b"") -> _CdrRecord:
    """Header + primitives ``(name, numpy format, size)`` in order + constant ``tail_bytes``."""
    header, end = _header_layout(frame_id)
    fields = {"sec": (4, "<i4"), "nanosec": (8, "<u4")}
    body = bytearray(header)
    for name, fmt, size in tail:
        start = _align(len(body), size)
        body += bytes(start - len(body) + size)
        fields[name] = (4 + start, fmt)
    body += tail_bytes
    return _CdrRecord(_CDR_HEADER + bytes(body), fields)


_POSE_CDR = _stamped(FRAME_ID, [(k, "<f8", 8) for k in ("x", "y", "z", "qx", "qy", "qz", "qw")])
_LIGHT_CDR = _stamped(FRAME_ID, [("illuminance", "<f8", 8), ("variance", "<f8", 8)])
_CLOCK_CDR = _stamped(FRAME_ID, [("ref_sec", "<i4", 4), ("ref_nanosec", "<u4", 4)],
                      _cdr_string("kilo_ticks"))
_LED_CDR = _CdrRecord(_CDR_HEADER + bytes(16), {c: (4 + 4 * i, "<f4") for i, c in enumerate("rgba")})
_LED_TABLE = np.zeros((max(_LED_RGBA) + 1, 4), dtype=np.float32)
for _code, _rgba in _LED_RGBA.items():
    _LED_TABLE[_code] = _rgba


def _split_ns(ns: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    sec, nsec = np.divmod(np.asarray(ns, dtype=np.int64), NS_PER_S)
    return sec, nsec


def _rows(records: np.ndarray) -> list[bytes]:
    """The records as separate ``bytes`` objects (what Publisher.publish takes)."""
    buf = records.tobytes()
    size = records.dtype.itemsize
    return [buf[i:i + size] for i in range(0, len(buf), size)]


def robot_cdr(stamp_ns, x_m, y_m, theta_rad, reading, reading_variance, led, ticks, tick_hz: float):
    """Serialized ``(pose, light, led, clock)`` messages of robots, each a list of ``bytes``.

    Every argument but ``tick_hz`` is a scalar or an array over the robots (shape ``(n,)``); the
    bytes decode to what :meth:`RobotMessages.fill` puts into the message objects.
    """
    x_m = np.atleast_1d(np.asarray(x_m, dtype=np.float64))
    n = x_m.shape[0]
    sec, nsec = _split_ns(np.broadcast_to(np.asarray(stamp_ns, dtype=np.int64), (n,)))
    pose = _POSE_CDR.empty(n)
    light = _LIGHT_CDR.empty(n)
    clock = _CLOCK_CDR.empty(n)
    for rec in (pose, light, clock):
        rec["sec"], rec["nanosec"] = sec, nsec
    pose["x"], pose["y"] = x_m, y_m
    half = 0.5 * np.asarray(theta_rad, dtype=np.float64)
    pose["qz"], pose["qw"] = np.sin(half), np.cos(half)
    light["illuminance"], light["variance"] = reading, reading_variance
    colors = _LED_CDR.empty(n)
    rgba = _LED_TABLE[np.asarray(led, dtype=np.int64)]
    for i, c in enumerate("rgba"):
        colors[c] = np.broadcast_to(rgba[..., i], (n,))
    ref_ns = np.rint(np.asarray(ticks, dtype=np.float64) / tick_hz * NS_PER_S).astype(np.int64)
    clock["ref_sec"], clock["ref_nanosec"] = _split_ns(np.broadcast_to(ref_ns, (n,)))
    return _rows(pose), _rows(light), _rows(colors), _rows(clock)


def _header_end(data: bytes) -> int:
    """Offset (in the whole buffer) just after a serialized std_msgs/Header."""
    return 4 + 12 + int.from_bytes(data[12:16], "little")


def _check_le(data: bytes) -> None:
    if data[1] != 1:
        raise ValueError("expected little-endian CDR")


def pose_xy_from_cdr(data: bytes) -> tuple[float, float]:
    """(x m, y m) of a serialized geometry_msgs/PoseStamped (little-endian CDR)."""
    _check_le(data)
    start = 4 + _align(_header_end(data) - 4, 8)
    return struct.unpack_from("<dd", data, start)


def led_from_cdr(data: bytes) -> int:
    """The LED code of a serialized std_msgs/ColorRGBA (as :func:`led_from_color`)."""
    _check_le(data)
    r, _g, b, a = struct.unpack_from("<ffff", data, 4)
    if a == 0.0:
        return LED_OFF
    return LED_RED if r >= b else LED_BLUE


def ticks_from_clock_cdr(data: bytes, tick_hz: float) -> float:
    """The robot's kilo_ticks from a serialized sensor_msgs/TimeReference (as :func:`ticks_from_clock`)."""
    _check_le(data)
    start = 4 + _align(_header_end(data) - 4, 4)
    sec, nsec = struct.unpack_from("<iI", data, start)
    return (sec * NS_PER_S + nsec) / NS_PER_S * tick_hz


# --- the swarm's state of a step as one PointCloud2 --------------------------------------------------

#: One point per robot: (name, numpy format, PointField datatype), packed in this order.
CLOUD_FIELDS = (("id", "<u4", PointField.UINT32), ("led", "<u4", PointField.UINT32),
                ("x", "<f8", PointField.FLOAT64), ("y", "<f8", PointField.FLOAT64), ("z", "<f8", PointField.FLOAT64),
                ("theta", "<f8", PointField.FLOAT64), ("reading", "<f8", PointField.FLOAT64),
                ("ticks", "<f8", PointField.FLOAT64))
CLOUD_DTYPE = np.dtype([(name, fmt) for name, fmt, _ in CLOUD_FIELDS])

_cloud_templates: dict[int, tuple[bytes, int]] = {}


def _cloud_template(n: int) -> tuple[bytes, int]:
    """Serialized PointCloud2 of ``n`` zero points, stamp 0, and the offset of its point data."""
    if n not in _cloud_templates:
        from rclpy.serialization import serialize_message

        m = PointCloud2()
        m.header.frame_id = FRAME_ID
        m.height, m.width = 1, n
        offsets = np.cumsum([0] + [np.dtype(f).itemsize for _, f, _ in CLOUD_FIELDS])
        m.fields = [PointField(name=name, offset=int(o), datatype=dt, count=1)
                    for (name, _, dt), o in zip(CLOUD_FIELDS, offsets)]
        m.is_bigendian = False
        m.point_step = CLOUD_DTYPE.itemsize
        m.row_step = n * CLOUD_DTYPE.itemsize
        m.data = array.array("B", bytes(n * CLOUD_DTYPE.itemsize))
        m.is_dense = True
        raw = serialize_message(m)
        # The point data is the last sequence, followed only by the one-byte is_dense.
        _cloud_templates[n] = (raw, len(raw) - 1 - n * CLOUD_DTYPE.itemsize)
    return _cloud_templates[n]


def robot_cloud_cdr(stamp_ns: int, ids, x_m, y_m, theta_rad, reading, led, ticks) -> bytes:
    """Serialized sensor_msgs/PointCloud2 of the robots' state (arrays over the robots; heading
    wrapped to (-pi, pi], ticks = the robot's kilo_ticks)."""
    ids = np.atleast_1d(np.asarray(ids))
    pts = np.zeros(ids.shape[0], dtype=CLOUD_DTYPE)
    pts["id"], pts["led"], pts["x"], pts["y"] = ids, led, x_m, y_m
    theta_rad = np.asarray(theta_rad, dtype=np.float64)
    pts["theta"] = np.arctan2(np.sin(theta_rad), np.cos(theta_rad))  # as the pose's quaternion holds it
    pts["reading"], pts["ticks"] = reading, ticks
    raw, start = _cloud_template(ids.shape[0])
    buf = bytearray(raw)
    struct.pack_into("<iI", buf, 4, *divmod(int(stamp_ns), NS_PER_S))
    buf[start:start + pts.nbytes] = pts.tobytes()
    return bytes(buf)


def robot_cloud_from_cdr(data: bytes) -> tuple[int, np.ndarray]:
    """(stamp ns, points as a :data:`CLOUD_DTYPE` array) of a serialized robot cloud.

    Parsed from the front, field by field: a buffer that crossed DDS between processes may
    carry padding after the last field (``is_dense``), so nothing is located from the end.
    Raises ValueError for a PointCloud2 that is not laid out as :data:`CLOUD_FIELDS`.
    """
    _check_le(data)

    def u32(pos: int) -> tuple[int, int]:
        pos = 4 + _align(pos - 4, 4)
        return struct.unpack_from("<I", data, pos)[0], pos + 4

    height, pos = u32(_header_end(data))
    width, pos = u32(pos)
    n_fields, pos = u32(pos)
    names = []
    for _ in range(n_fields):
        n_chars, pos = u32(pos)
        names.append(data[pos:pos + n_chars].rstrip(b"\x00").decode())
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
    return stamp_ns_from_cdr(data), np.frombuffer(data, dtype=CLOUD_DTYPE, count=height * width, offset=pos)


def members_msg(ids) -> String:
    """The ids a swarm process covers (``/swarm/members``)."""
    return json_msg({"robots": [int(i) for i in ids]})


# --- traits ------------------------------------------------------------------------------------

def traits_to_msg(robot_id: int, traits: RobotTraits, behavior: Mapping[str, Any], seed: int, run: int) -> String:
    from dataclasses import asdict

    return String(data=json.dumps({"id": int(robot_id), "traits": asdict(traits), "behavior": dict(behavior),
                                   "seed": int(seed), "run": int(run)}, sort_keys=True))


# --- the world ----------------------------------------------------------------------------------

def field_image_msg(intensity: np.ndarray, stamp_ns: int) -> Image:
    """A light-field raster (rows top = +y, as in a picture) as a 32FC1 image in light units."""
    img = np.ascontiguousarray(intensity, dtype="<f4")
    m = Image()
    ns_to_time(stamp_ns, m.header.stamp)
    m.header.frame_id = FRAME_ID
    m.height, m.width = img.shape
    m.encoding = "32FC1"
    m.is_bigendian = 0
    m.step = 4 * img.shape[1]
    m.data = array.array("B", img.tobytes())  # (bytes take the setter's per-element check)
    return m


def image_to_array(msg: Image) -> np.ndarray:
    if msg.encoding != "32FC1":
        raise ValueError(f"expected a 32FC1 image, got {msg.encoding}")
    return np.frombuffer(bytes(msg.data), dtype=">f4" if msg.is_bigendian else "<f4").reshape(msg.height, msg.width)


def json_msg(doc: Mapping[str, Any] | str) -> String:
    return String(data=doc if isinstance(doc, str) else json.dumps(doc, sort_keys=True))
