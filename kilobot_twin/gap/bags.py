"""Bags as input to the gap workflow: a bag made by ``kilobot-twin import`` carries the measured
dataset's trial structure in its metadata, so its tracks can be cut back into trials.

The gap workflow needs repeated trials of the same robots; a bag recorded from one twin run is a
single trial and is refused with a one-line error (record several, or compare datasets).
Bags are read as plain data (:mod:`kilobot_twin.recording`): no rclpy here.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..recording import measured
from ..errors import ConfigError
from ..recording import cdr
from ..recording.bag import BagReader
from ..recording.topics import parse_robot_topic


def _json(v):
    try:
        return json.loads(v)
    except (TypeError, ValueError):
        return v


def dataset_from_bag(bag_dir: str | Path) -> measured.Dataset:
    bag_dir = Path(bag_dir)
    reader = BagReader(bag_dir)
    imp = reader.metadata().get("kilobot_twin.import")
    if imp is None:
        raise ConfigError(str(bag_dir), "the bag has no trial structure (it was not made by kilobot-twin import)",
                          "the gap workflow needs repeated trials: give the measured dataset folder or an imported bag")
    imp = {k: _json(v) for k, v in imp.items()}
    try:
        meta = dict(imp["dataset_meta"])
        kind = meta["kind"]
        trials = [(int(tr["trial"]), int(tr["start_ns"]), int(tr["end_ns"])) for tr in imp["trials"]]
    except (KeyError, TypeError, ValueError):
        raise ConfigError(str(reader.file), "the kilobot_twin.import metadata record is damaged",
                          "import the measured dataset again") from None
    if kind == "light_sweep":
        raise ConfigError(str(bag_dir), "light-sweep bags are not read back yet", "give the measured dataset folder")
    # Read the samples themselves (header stamps, exact values) rather than a resampled view.
    suffix = "pose" if kind == "motion" else "led"
    series: dict[int, list] = {}
    for topic, _type, log_ns, _pub, data in reader.messages():
        rt = parse_robot_topic(topic)
        if rt is None or rt[1] != suffix:
            continue
        if kind == "motion":
            stamp_ns, x, y, _qz, _qw = cdr.pose_stamped(data)
            series.setdefault(rt[0], []).append((stamp_ns, x, y))
        else:
            led = cdr.led(data)
            if led <= 1:
                series.setdefault(rt[0], []).append((log_ns, float(led), 0.0))
    tracks = {}
    for trial, start_ns, end_ns in trials:
        for rid, rows in series.items():
            a = np.array(rows)
            sel = (a[:, 0] >= start_ns) & (a[:, 0] <= end_ns)
            if not sel.any():
                continue
            t_rel = (a[sel, 0] - start_ns) / 1e9
            values = {"x_m": a[sel, 1], "y_m": a[sel, 2]} if kind == "motion" else {"led": a[sel, 1]}
            tracks[(trial, rid)] = measured.Track(t_rel, values)
    return measured.Dataset(bag_dir, meta, tracks)
