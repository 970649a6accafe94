"""Every conversion between ROS messages and the core's values lives here (and only here).

Robot topics (namespace ``kilobot_<id>``, frame ``arena``):

===========  =========================  =====================================================
``pose``     geometry_msgs/PoseStamped  x, y in m, heading as a yaw quaternion
``light``    sensor_msgs/Illuminance    raw ADC reading 0-1023 in ``illuminance``; variance of
                                        the averaged reading in ``variance``
``led``      std_msgs/ColorRGBA         red (1,0,0,1), blue (0,0,1,1), off (0,0,0,0)
``clock``    sensor_msgs/TimeReference  ``time_ref`` = the robot's own clock, kilo_ticks /
                                        31 Hz; ``header.stamp`` = world time (clock drift is
                                        ``time_ref - stamp``)
``traits``   std_msgs/String            JSON: id, traits, behaviour, seed, run (transient-local)
===========  =========================  =====================================================
"""

from __future__ import annotations

import json
import math
import struct
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Illuminance, Image, TimeReference
from std_msgs.msg import ColorRGBA, String

from ..core.constants import LED_BLUE, LED_OFF, LED_RED
from ..core.traits import RobotTraits, traits_from_mapping

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


# --- traits ------------------------------------------------------------------------------------

def traits_to_msg(robot_id: int, traits: RobotTraits, behavior: Mapping[str, Any], seed: int, run: int) -> String:
    from dataclasses import asdict

    return String(data=json.dumps({"id": int(robot_id), "traits": asdict(traits), "behavior": dict(behavior),
                                   "seed": int(seed), "run": int(run)}, sort_keys=True))


def traits_from_msg(msg: String) -> tuple[int, RobotTraits, dict]:
    """(robot id, traits, the whole document) from a ``traits`` message."""
    doc = json.loads(msg.data)
    return int(doc["id"]), traits_from_mapping(doc["traits"], "traits."), doc


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
    m.data = img.tobytes()
    return m


def image_to_array(msg: Image) -> np.ndarray:
    if msg.encoding != "32FC1":
        raise ValueError(f"expected a 32FC1 image, got {msg.encoding}")
    return np.frombuffer(bytes(msg.data), dtype=">f4" if msg.is_bigendian else "<f4").reshape(msg.height, msg.width)


def json_msg(doc: Mapping[str, Any] | str) -> String:
    return String(data=doc if isinstance(doc, str) else json.dumps(doc, sort_keys=True))
