"""Every conversion between ROS message objects and the core's values lives here (and only here).

The robot topics and their layout are described in :mod:`kilobot_twin.recording.cdr`, which reads
and writes the same messages as serialized CDR without rclpy. ``clock`` (sensor_msgs/TimeReference)
goes out at step 0 and then once per ``clock_period_s`` of simulated time (world document, default
1 s; 0 = every step): see :func:`clock_steps`. ``traits`` (std_msgs/String, transient-local) is
JSON: id, traits, behaviour, seed, run.

A batched ``swarm`` process also publishes all its robots' state of a step as one
sensor_msgs/PointCloud2 (``/swarm/robots``, one point per robot, fields :data:`CLOUD_FIELDS`,
published after the robots' own messages of that step) and, transient-local, the ids it
covers (``/swarm/members``, JSON): nodes that need the whole swarm each step (the world's
lockstep handshake, the analysis) take one message per step instead of one per robot and topic.
"""

from __future__ import annotations

import array
import json
import struct
from typing import Any, Mapping

import numpy as np
from builtin_interfaces.msg import Time
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import String

from ..core.traits import RobotTraits
from ..recording.cdr import CLOUD_DTYPE, FRAME_ID, NS_PER_S


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


# --- the swarm's state of a step as one PointCloud2 --------------------------------------------------

#: :data:`~kilobot_twin.recording.cdr.CLOUD_DTYPE` as PointCloud2 fields: (name, numpy format, PointField datatype).
CLOUD_FIELDS = tuple((name, CLOUD_DTYPE[name].str, PointField.UINT32 if CLOUD_DTYPE[name].kind == "u" else PointField.FLOAT64)
                     for name in CLOUD_DTYPE.names)

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


def members_msg(ids) -> String:
    """The ids a swarm process covers (``/swarm/members``)."""
    return json_msg({"robots": [int(i) for i in ids]})


# --- traits ------------------------------------------------------------------------------------

def traits_to_msg(robot_id: int, traits: RobotTraits, behavior: Mapping[str, Any], seed: int, run: int) -> String:
    from dataclasses import asdict

    return String(data=json.dumps({"id": int(robot_id), "traits": asdict(traits), "behavior": dict(behavior),
                                   "seed": int(seed), "run": int(run)}, sort_keys=True))


# --- the world ----------------------------------------------------------------------------------

def json_msg(doc: Mapping[str, Any] | str) -> String:
    return String(data=doc if isinstance(doc, str) else json.dumps(doc, sort_keys=True))
