"""A :class:`SwarmRecording` -> a Rerun recording (``.rrd``) with a saved blueprint.

Everything time-varying is sent with the columnar API (``rr.send_columns``): one call per
entity for the whole recording instead of one ``rr.log`` per robot per step.

Entities (timeline ``time``, a duration in s):

- ``arena/light_field`` (static Image): the light field, dark (low) to yellow (high);
- ``arena/light_center`` (static Points2D): the light centre;
- ``arena/trajectories`` (static LineStrips2D): each robot's whole path, coloured by its
  heading bias on the paper's map (red = left / negative, blue = right / positive), split at
  tracking gaps;
- ``arena/robots`` (Points2D per step): every robot in its current LED colour (grey: unknown);
- ``arena/headings`` (Arrows2D per step): heading arrows;
- ``light/kilobot_<id>`` (Scalars): each robot's raw light reading;
- ``metrics/<name>`` (Scalars): red / blue LED fraction, order parameter (blink), mean
  distance to the light, computed from the robots' arrays; ``metrics/recorded/<name>``: what
  the analysis node recorded in the bag;
- ``traits`` (static TextDocument): a markdown table of every robot's traits.

The 2-D view is in the light-field image's pixel frame (column = x, row = -y: up on screen
is +y); ``arena`` holds the scale (``px_per_m``) in the text of ``arena/info``.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from .swarm_data import SwarmRecording, bias_colours, led_colours

APP_ID = "kilobot_twin"
TIMELINE = "time"
DEFAULT_PX_PER_M = 100.0  # when the recording has no light field (measured data): 1 px = 1 cm


def blueprint() -> rrb.Blueprint:
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial2DView(origin="arena", name="arena"),
            rrb.Vertical(
                rrb.TimeSeriesView(origin="light", name="light readings (ADC counts)"),
                rrb.TimeSeriesView(origin="metrics", name="swarm metrics"),
                rrb.TextDocumentView(origin="traits", name="traits"),
            ),
            column_shares=[3, 2],
        ),
        collapse_panels=False,
    )


class _Frame:
    """Arena metres -> view pixels (x right, y up on screen)."""

    def __init__(self, rec: SwarmRecording):
        if rec.light_field is not None and rec.field_extent is not None:
            xmin, xmax, ymin, ymax = rec.field_extent
            self.px_per_m = rec.light_field.shape[1] / (xmax - xmin)
        else:
            ok = np.isfinite(rec.x) & np.isfinite(rec.y)
            pad = 0.05
            xmin, xmax = (float(rec.x[ok].min()) - pad, float(rec.x[ok].max()) + pad) if ok.any() else (-1, 1)
            ymin, ymax = (float(rec.y[ok].min()) - pad, float(rec.y[ok].max()) + pad) if ok.any() else (-1, 1)
            if rec.light_center is not None:
                xmin, xmax = min(xmin, rec.light_center[0] - pad), max(xmax, rec.light_center[0] + pad)
                ymin, ymax = min(ymin, rec.light_center[1] - pad), max(ymax, rec.light_center[1] + pad)
            self.px_per_m = DEFAULT_PX_PER_M
        self.xmin, self.ymax = xmin, ymax

    def __call__(self, x, y) -> np.ndarray:
        return np.stack([(np.asarray(x) - self.xmin) * self.px_per_m, (self.ymax - np.asarray(y)) * self.px_per_m],
                        axis=-1)


def _field_rgb(field: np.ndarray) -> np.ndarray:
    f = np.asarray(field, dtype=np.float64)
    lo, hi = np.nanmin(f), np.nanmax(f)
    u = (f - lo) / (hi - lo) if hi > lo else np.zeros_like(f)
    dark, bright = np.array([20.0, 20.0, 35.0]), np.array([255.0, 230.0, 120.0])
    return (dark + u[..., None] * (bright - dark)).astype(np.uint8)


def log_recording(rec: SwarmRecording, stream: rr.RecordingStream, arrow_m: float = 0.03) -> None:
    """Log every entity of ``rec`` into ``stream`` (static layers with ``log``, time series with ``send_columns``)."""
    N, T = rec.x.shape
    frame = _Frame(rec)
    px = frame.px_per_m
    times = np.asarray(rec.t_s, dtype=np.float64)
    bias = rec.bias_for_colour()
    bcol = bias_colours(bias)

    # --- static layers -------------------------------------------------------------------
    if rec.light_field is not None:
        stream.log("arena/light_field", rr.Image(_field_rgb(rec.light_field), draw_order=-10.0), static=True)
    if rec.light_center is not None:
        c = frame(*rec.light_center)
        stream.log("arena/light_center", rr.Points2D([c], radii=[0.03 * px], colors=[(255, 200, 0)], labels=["light"],
                                                     draw_order=5.0), static=True)
    strips, strip_cols, strip_labels = [], [], []
    for i in range(N):
        ok = np.isfinite(rec.x[i]) & np.isfinite(rec.y[i])
        if not ok.any():
            continue
        # Contiguous runs of tracked samples: a gap ends a strip (nothing interpolated).
        edges = np.flatnonzero(np.diff(np.concatenate([[0], ok.astype(np.int8), [0]])))
        for a, b in zip(edges[::2], edges[1::2]):
            strips.append(frame(rec.x[i, a:b], rec.y[i, a:b]))
            strip_cols.append(bcol[i])
            strip_labels.append(f"{rec.robot_ids[i]}: b={bias[i]:+.4f}" if np.isfinite(bias[i]) else str(rec.robot_ids[i]))
    if strips:
        stream.log("arena/trajectories", rr.LineStrips2D(strips, colors=strip_cols, radii=[0.002 * px] * len(strips),
                                                         labels=strip_labels, show_labels=False, draw_order=1.0),
                   static=True)
    stream.log("arena/info", rr.TextDocument(
        f"View frame: 1 px = {1 / px:.4g} m; x right, y up on screen. Trajectory colour = heading bias "
        f"(red = left / negative, blue = right / positive). Points = robots in their LED colour."), static=True)
    stream.log("traits", rr.TextDocument(_traits_markdown(rec, bias), media_type=rr.MediaType.MARKDOWN), static=True)

    # --- robots over time: one row per step, one instance per tracked robot -------------
    ok = np.isfinite(rec.x) & np.isfinite(rec.y)          # (N, T)
    lengths = ok.sum(axis=0)                              # robots per step
    okT = ok.T                                            # (T, N): row-major order = step, then robot
    xy = frame(rec.x.T[okT], rec.y.T[okT])
    th = np.where(np.isfinite(rec.theta), rec.theta, 0.0).T[okT]
    cols = led_colours(rec.led.T[okT])
    ids = np.broadcast_to(rec.robot_ids[None, :], (T, N))[okT]
    index = [rr.TimeColumn(TIMELINE, duration=times)]
    stream.send_columns("arena/robots", indexes=index, columns=rr.Points2D.columns(
        positions=xy, colors=cols, radii=np.full(len(xy), 0.017 * px, dtype=np.float32),
        class_ids=ids.astype(np.uint16)).partition(lengths))
    stream.send_columns("arena/headings", indexes=index, columns=rr.Arrows2D.columns(
        origins=xy, vectors=np.stack([np.cos(th), -np.sin(th)], axis=-1) * (arrow_m * px),
        colors=np.repeat(np.array([[240, 240, 240, 255]], dtype=np.uint8), len(xy), axis=0)).partition(lengths))

    # --- time series ---------------------------------------------------------------------
    for i, rid in enumerate(rec.robot_ids):
        good = np.isfinite(rec.reading[i])
        if not good.any():
            continue
        path = f"light/kilobot_{int(rid)}"
        stream.log(path, rr.SeriesLines(colors=[bcol[i]], names=[f"kilobot_{int(rid)}"]), static=True)
        stream.send_columns(path, indexes=[rr.TimeColumn(TIMELINE, duration=times[good])],
                            columns=rr.Scalars.columns(scalars=rec.reading[i, good]))
    for name, values in rec.metrics().items():
        _series(stream, f"metrics/{name}", times, values)
    for name, (t, values) in rec.recorded_metrics.items():
        _series(stream, f"metrics/recorded/{name}", np.asarray(t, float), np.asarray(values, float))


def _series(stream, path: str, t: np.ndarray, v: np.ndarray) -> None:
    good = np.isfinite(v)
    if good.any():
        stream.send_columns(path, indexes=[rr.TimeColumn(TIMELINE, duration=t[good])],
                            columns=rr.Scalars.columns(scalars=v[good]))


def _traits_markdown(rec: SwarmRecording, bias: np.ndarray) -> str:
    keys: list[str] = []
    rows = []
    for i, rid in enumerate(rec.robot_ids):
        doc = rec.traits.get(int(rid), {})
        tr = doc.get("traits", doc) if isinstance(doc, dict) else {}
        tr = {k: v for k, v in tr.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}
        for k in tr:
            if k not in keys:
                keys.append(k)
        rows.append((int(rid), bias[i], tr))
    head = f"# {rec.name}: {rec.n_robots} robots, {rec.n_steps} samples\n\n"
    if not keys:
        head += "No trait records; heading bias estimated from motion.\n\n"
    cols = ["robot", "bias (colour)"] + keys
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for rid, b, tr in rows:
        lines.append("| " + " | ".join([str(rid), f"{b:+.4f}"] + [f"{tr[k]:.6g}" if k in tr else "" for k in keys]) + " |")
    return head + "\n".join(lines) + "\n"


def write_rrd(rec: SwarmRecording, out: str | Path, spawn: bool = False) -> dict:
    """Write ``out`` (.rrd) with the blueprint; ``spawn`` also opens a viewer. Returns timings."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    stream = rr.RecordingStream(APP_ID)
    bp = blueprint()
    if spawn:
        # Start a viewer, then stream to it and to the file at once.
        stream.spawn(connect=False)
        stream.set_sinks(rr.FileSink(str(out)), rr.GrpcSink(), default_blueprint=bp)
    else:
        stream.save(str(out), default_blueprint=bp)
    stream.send_recording_name(rec.name)
    log_recording(rec, stream)
    t_log = time.perf_counter() - t0
    stream.flush()
    stream.disconnect()
    return {"path": out, "log_s": t_log, "total_s": time.perf_counter() - t0}
