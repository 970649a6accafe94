"""A twin bag (simulated, replayed or imported) -> :class:`SwarmRecording`.

Robot samples are placed on a grid of the robots' own ``header.stamp`` (slot
``round((stamp - t0) / dt)`` with ``dt`` the median stamp step), so lockstep, realtime and
imported (jittered) bags line up; a robot without a sample in a slot has NaN there (a gap).
``led`` carries no stamp: an LED message belongs to the first pose the same robot logged at or
after it (robots publish light, led, clock, then pose). ``/analysis/*`` values are put on the
simulated time the analysis node published with them (``/analysis/time_s``), or for older bags on
the recorded ``/clock`` time of their log time; undefined (NaN) values are left out.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from ..recording.bag import BagReader
from ..recording.topics import parse_robot_topic
from .swarm_data import SwarmRecording


def from_bag(bag_dir: str | Path) -> SwarmRecording:
    from geometry_msgs.msg import PoseStamped
    from rclpy.serialization import deserialize_message
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import Illuminance, Image, TimeReference
    from std_msgs.msg import ColorRGBA, Float64, String

    from ..core.constants import TICK_HZ
    from ..ros import convert
    from ..core.scenarios import parse_world_document, scenario_from_document
    from .swarm_data import blink_period_ticks

    bag_dir = Path(bag_dir)
    pose: dict[int, list] = {}     # id -> [(stamp, log, x, y, theta)]
    light: dict[int, list] = {}    # id -> [(stamp, reading)]
    clock: dict[int, list] = {}    # id -> [(stamp, ticks)]
    led: dict[int, list] = {}      # id -> [(log, led)]
    traits: dict[int, dict] = {}
    clock_log, clock_ns = [], []
    analysis: dict[str, list] = {}
    world_doc, field_img = None, None
    reader = BagReader(bag_dir)
    for topic, _type, log_ns, _pub, data in reader.messages():
        m = parse_robot_topic(topic)
        if m:
            rid, kind = m
            if kind == "pose":
                msg = deserialize_message(data, PoseStamped)
                x, y, th = convert.pose_to_xytheta(msg)
                pose.setdefault(rid, []).append((convert.time_to_ns(msg.header.stamp), log_ns, x, y, th))
            elif kind == "light":
                msg = deserialize_message(data, Illuminance)
                light.setdefault(rid, []).append((convert.time_to_ns(msg.header.stamp), msg.illuminance))
            elif kind == "led":
                led.setdefault(rid, []).append((log_ns, convert.led_from_color(deserialize_message(data, ColorRGBA))))
            elif kind == "clock":
                msg = deserialize_message(data, TimeReference)
                clock.setdefault(rid, []).append((convert.time_to_ns(msg.header.stamp),
                                                  convert.ticks_from_clock(msg, TICK_HZ)))
            else:
                try:
                    traits[rid] = json.loads(deserialize_message(data, String).data)
                except ValueError:
                    pass
        elif topic == "/clock":
            clock_log.append(log_ns)
            clock_ns.append(convert.time_to_ns(deserialize_message(data, Clock).clock))
        elif topic.startswith("/analysis/") and _type == "std_msgs/msg/Float64":
            analysis.setdefault(topic.rsplit("/", 1)[-1], []).append((log_ns, deserialize_message(data, Float64).data))
        elif topic == "/world/scenario":
            world_doc = deserialize_message(data, String).data
        elif topic == "/world/light_field" and field_img is None:
            field_img = convert.image_to_array(deserialize_message(data, Image))
    cl, cn = np.asarray(clock_log, dtype=np.int64), np.asarray(clock_ns, dtype=np.int64)

    def log_to_stamp(log):
        """Recorded time of a log time: the last /clock value logged at or before it."""
        j = np.clip(np.searchsorted(cl, log, side="right") - 1, 0, len(cl) - 1)
        return cn[j]

    if not (pose or light or (led and len(cl))):
        raise ConfigError(str(reader.file), "no /kilobot_<id>/pose, light or led messages",
                          "give a bag of a twin run or an imported dataset")
    ids = np.array(sorted(set(pose) | set(light) | (set(led) if len(cl) else set())), dtype=np.int64)
    stamps = {}
    for r in ids:
        parts = [np.array([p[0] for p in pose.get(r, [])], dtype=np.int64),
                 np.array([q[0] for q in light.get(r, [])], dtype=np.int64)]
        if r not in pose and r not in light and r in led:
            parts.append(log_to_stamp(np.array([q[0] for q in led[r]], dtype=np.int64)))
        stamps[r] = np.unique(np.concatenate(parts))
    t0 = min(int(s.min()) for s in stamps.values() if len(s))
    steps = np.concatenate([np.diff(s) for s in stamps.values() if len(s) > 1] or [np.array([1])])
    steps = steps[steps > 0]
    dt_ns = int(np.median(steps)) if len(steps) else 1
    T = max(int(round((int(s.max()) - t0) / dt_ns)) for s in stamps.values() if len(s)) + 1
    N = len(ids)
    x, y, th, rd, lv, tk = (np.full((N, T), np.nan) for _ in range(6))

    def slot(ns):
        return np.clip(np.rint((np.asarray(ns, dtype=np.float64) - t0) / dt_ns).astype(np.int64), 0, T - 1)

    for i, r in enumerate(ids):
        if r in pose:
            p = np.array([q for q in pose[r]], dtype=np.float64)
            k = slot(p[:, 0].astype(np.int64))
            x[i, k], y[i, k], th[i, k] = p[:, 2], p[:, 3], p[:, 4]
        if r in light:
            a = np.array(light[r], dtype=np.float64)
            rd[i, slot(a[:, 0])] = a[:, 1]
        if r in clock:
            a = np.array(clock[r], dtype=np.float64)
            tk[i, slot(a[:, 0])] = a[:, 1]
        if r in led:
            a = np.array(led[r], dtype=np.float64)
            if r in pose:
                plog = p[:, 1]
                j = np.clip(np.searchsorted(plog, a[:, 0], side="left"), 0, len(plog) - 1)
                lv[i, k[j]] = a[:, 1]
            elif len(cl):
                lv[i, slot(log_to_stamp(a[:, 0].astype(np.int64)))] = a[:, 1]

    scenario = None
    if world_doc:
        try:
            scenario = scenario_from_document(parse_world_document(world_doc))
        except (ConfigError, KeyError, ValueError, TypeError):
            scenario = None
    extent = None
    if scenario is not None:
        a = scenario.arena
        extent = (-a.width_m / 2, a.width_m / 2, -a.height_m / 2, a.height_m / 2)
    bias = np.array([float(traits.get(int(r), {}).get("traits", {}).get("heading_bias", np.nan)) for r in ids])

    recorded = {}
    times = analysis.pop("time_s", None)
    for name, vals in analysis.items():
        a = np.array(vals, dtype=np.float64)
        if times is not None and len(times) == len(a):
            # The analysis node's k-th value of every metric belongs to its k-th time_s (simulated time).
            t = np.array([v for _log, v in times]) - t0 / 1e9
        elif len(cl):
            j = np.clip(np.searchsorted(cl, a[:, 0], side="right") - 1, 0, len(cl) - 1)
            t = (cn[j] - t0) / 1e9
        else:
            t = (a[:, 0] - a[0, 0]) / 1e9
        keep = np.isfinite(a[:, 1])  # NaN: undefined at that time (e.g. no blink program)
        if keep.any():
            recorded[name] = (t[keep], a[keep, 1])

    meta = reader.metadata()
    return SwarmRecording(
        name=bag_dir.name, robot_ids=ids, t_s=np.arange(T) * dt_ns / 1e9, x=x, y=y, theta=th, led=lv, reading=rd,
        ticks=tk, heading_bias=bias, traits={int(k): v for k, v in traits.items()},
        light_center=tuple(scenario.light.center) if scenario is not None else _center_from_meta(meta),
        light_field=field_img, field_extent=extent, recorded_metrics=recorded,
        period_ticks=blink_period_ticks(scenario) if scenario is not None else None,
        meta={"source": str(bag_dir), "t0_ns": t0, "dt_ns": dt_ns, **({"damage": reader.note} if reader.note else {}),
              **{k: v for k, v in meta.items()}})


def _center_from_meta(meta: dict):
    """Light centre written by the importer (``kilobot_twin.import`` metadata), if any."""
    doc = meta.get("kilobot_twin.import", {})
    if "light_center" in doc:
        try:
            c = json.loads(doc["light_center"])
            return float(c[0]), float(c[1])
        except (ValueError, TypeError, IndexError):
            return None
    return None
