"""``kilobot-twin import``: a measured dataset (measured-v1) -> a bag with the twin's topics and
types, so that ``view``, ``replay`` and the gap workflow take measured and simulated runs alike.

The layout (trials one after another in time, ``kilobot_twin.import`` metadata, which topic each
kind of dataset fills, gaps kept) is described in the README ("Replay, view, import"). Header
stamps and log times are the measured times plus the trial offset (from 0: measured time, not
wall time). Bad input is reported by :func:`kilobot_twin.recording.measured.load`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import __version__
from ..errors import ConfigError
from .bag import BagReader
from .cdr import float64_cdr
from .measured import Dataset, load
from .twin_bag import TwinBagWriter

NS = 1_000_000_000


def heading_from_motion(x: np.ndarray, y: np.ndarray, min_step_m: float = 1e-4) -> np.ndarray:
    """Heading (rad) at each sample from the direction of travel (central difference where possible).

    Samples where the robot did not move more than ``min_step_m`` keep the previous heading
    (the first moving direction is used before any movement). NaN if the robot never moved.
    """
    n = len(x)
    if n < 2:
        return np.full(n, np.nan)
    xp = np.concatenate([[x[0]], x, [x[-1]]])
    yp = np.concatenate([[y[0]], y, [y[-1]]])
    dx, dy = xp[2:] - xp[:-2], yp[2:] - yp[:-2]
    moving = np.hypot(dx, dy) > min_step_m
    th = np.where(moving, np.arctan2(dy, dx), np.nan)
    if not moving.any():
        return th
    idx = np.where(moving, np.arange(n), -1)
    idx = np.maximum.accumulate(idx)
    first = int(np.argmax(moving))
    idx[idx < 0] = first
    return th[idx]


def trial_period_s(ds: Dataset) -> float:
    return ds.span_s + max(1.0, 2.0 * ds.dt_s)


def import_dataset(dataset: str | Path, out: str | Path) -> dict:
    """Write the bag ``out`` from the dataset folder; returns a summary (messages per topic, trials)."""
    from ..analysis import heading_bias_from_track

    out = Path(out)
    if (out / "metadata.yaml").exists() or any(out.glob("*.mcap")):
        raise ConfigError("--out", f"{out} already holds a bag", "choose a new bag name or delete the old one")
    ds = load(dataset)  # validates: one-line error with file, line and column
    period_ns = int(round(trial_period_s(ds) * NS))
    kind = ds.kind
    # Every event as (stamp_ns, order, robot, payload) so that the bag is written in time order.
    events: list[tuple[int, int, int, tuple]] = []
    bias_by_robot: dict[int, list[float]] = {}
    for (trial, robot), tr in ds.tracks.items():
        off = trial * period_ns
        stamps = off + np.rint(tr.t_s * NS).astype(np.int64)
        if kind == "motion":
            x, y = tr.values["x_m"], tr.values["y_m"]
            th = tr.values["theta_rad"] if "theta_rad" in tr.values else heading_from_motion(x, y)
            for k in range(len(tr)):
                events.append((int(stamps[k]), 1, robot, ("pose", float(x[k]), float(y[k]), float(th[k]))))
            b = float(heading_bias_from_track(tr.t_s, x, y))
            if np.isfinite(b):
                bias_by_robot.setdefault(robot, []).append(b)
        elif kind == "light_sweep":
            for k in range(len(tr)):
                events.append((int(stamps[k]), 1, robot, ("light", float(tr.values["reading"][k]),
                                                          float(tr.values["stimulus"][k]))))
        else:
            for k in range(len(tr)):
                events.append((int(stamps[k]), 1, robot, ("led", int(tr.values["led"][k]))))
    events.sort(key=lambda e: (e[0], e[1], e[2]))
    trials = [{"trial": k, "start_ns": k * period_ns, "end_ns": k * period_ns + int(round(ds.span_s * NS))}
              for k in range(ds.trials)]

    w = TwinBagWriter(out)
    try:
        meta_doc = {"format": "kilobot-twin/import-v1", "version": __version__, "source": str(Path(dataset).resolve()),
                    "kind": kind, "robots": ds.robots, "trials": trials, "trial_period_s": trial_period_s(ds),
                    "dt_s": ds.dt_s, "duration_s": ds.duration_s,
                    "heading": ("measured theta_rad" if any("theta_rad" in t.values for t in ds.tracks.values())
                                else "estimated from motion") if kind == "motion" else "none",
                    "dataset_meta": ds.meta}
        for key in ("light_center", "light_centre"):
            if key in ds.meta:
                meta_doc["light_center"] = ds.meta[key]
        w.bag.add_metadata("kilobot_twin.import", meta_doc)
        w.document("/world/measured", {k: v for k, v in meta_doc.items() if k != "dataset_meta"} | {"meta": ds.meta}, 0)
        for r in ds.robots:
            b = bias_by_robot.get(r)
            doc = {"id": int(r), "measured": True, "behavior": {"kind": ds.meta.get("behavior", kind)}}
            if b:
                doc["traits"] = {"heading_bias": float(np.median(b))}
                doc["traits_source"] = "heading_bias estimated from motion, median over trials"
            w.document(f"/kilobot_{int(r)}/traits", doc, 0)
        next_trial = 0
        last_clock = -1
        for stamp, _o, robot, p in events:
            while next_trial < ds.trials and trials[next_trial]["start_ns"] <= stamp:
                w.document("/world/trial", {"trial": next_trial, "start_ns": trials[next_trial]["start_ns"]},
                           trials[next_trial]["start_ns"], latched=False)
                next_trial += 1
            if stamp != last_clock:
                w.clock(stamp, stamp)
                last_clock = stamp
            if p[0] == "pose":
                w.robot_sample(robot, stamp, stamp, x_m=p[1], y_m=p[2], theta_rad=p[3] if np.isfinite(p[3]) else 0.0)
            elif p[0] == "light":
                w.robot_sample(robot, stamp, stamp, reading=p[1])
                w.bag.write(w.channel(f"/kilobot_{robot}/stimulus", "std_msgs/msg/Float64"),
                            float64_cdr(p[2]), stamp)
            else:
                w.robot_sample(robot, stamp, stamp, led=p[1])
    finally:
        w.close({"kilobot_twin_version": __version__, "source": "measured", "kind": kind})
    return {"path": out, "counts": BagReader(out).counts(), "trials": trials, "kind": kind, "robots": len(ds.robots)}
