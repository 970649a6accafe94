"""Bags as input to the gap workflow: a bag made by ``kilobot-twin import`` carries the measured
dataset's trial structure in its metadata, so its tracks can be cut back into trials.

The gap workflow needs repeated trials of the same robots; a bag recorded from one twin run is a
single trial and is refused with a one-line error (record several, or compare datasets).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .. import measured
from ..errors import ConfigError


def _json(v):
    try:
        return json.loads(v)
    except (TypeError, ValueError):
        return v


def dataset_from_bag(bag_dir: str | Path) -> measured.Dataset:
    from ..ros.bag import read_metadata

    bag_dir = Path(bag_dir)
    records = read_metadata(bag_dir)
    imp = records.get("kilobot_twin.import")
    if imp is None:
        raise ConfigError(str(bag_dir), "the bag has no trial structure (it was not made by kilobot-twin import)",
                          "the gap workflow needs repeated trials: give the measured dataset folder or an imported bag")
    imp = {k: _json(v) for k, v in imp.items()}
    meta = dict(imp["dataset_meta"])
    kind = meta["kind"]
    if kind == "light_sweep":
        raise ConfigError(str(bag_dir), "light-sweep bags are not read back yet", "give the measured dataset folder")
    # Read the samples themselves (header stamps, exact values) rather than a resampled view.
    from geometry_msgs.msg import PoseStamped
    from rclpy.serialization import deserialize_message
    from std_msgs.msg import ColorRGBA

    from ..ros import convert
    from ..viewer.bag_source import read_bag_messages

    suffix = "/pose" if kind == "motion" else "/led"
    series: dict[int, list] = {}
    for topic, _type, log_ns, _pub, data in read_bag_messages(bag_dir):
        if not (topic.startswith("/kilobot_") and topic.endswith(suffix)):
            continue
        rid = int(topic.split("/")[1].split("_")[1])
        if kind == "motion":
            msg = deserialize_message(data, PoseStamped)
            x, y, _ = convert.pose_to_xytheta(msg)
            series.setdefault(rid, []).append((convert.time_to_ns(msg.header.stamp), x, y))
        else:
            led = convert.led_from_color(deserialize_message(data, ColorRGBA))
            if led <= 1:
                series.setdefault(rid, []).append((log_ns, float(led), 0.0))
    tracks = {}
    for tr in imp["trials"]:
        for rid, rows in series.items():
            a = np.array(rows)
            sel = (a[:, 0] >= tr["start_ns"]) & (a[:, 0] <= tr["end_ns"])
            if not sel.any():
                continue
            t_rel = (a[sel, 0] - tr["start_ns"]) / 1e9
            values = {"x_m": a[sel, 1], "y_m": a[sel, 2]} if kind == "motion" else {"led": a[sel, 1]}
            tracks[(int(tr["trial"]), rid)] = measured.Track(t_rel, values)
    return measured.Dataset(bag_dir, meta, tracks)
