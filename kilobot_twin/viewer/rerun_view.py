"""A :class:`SwarmRecording` -> a Rerun recording (``.rrd``) with a saved blueprint (what it shows:
README, "Replay, view, import").

Everything time-varying is sent with the columnar API (``rr.send_columns``): one call per
entity for the whole recording instead of one ``rr.log`` per robot per step. Entities (timeline
``time``, a duration in s; the arena in metres, x right, y up): static ``arena`` (view
coordinates), ``arena/light_field`` (textured mesh), ``arena/bounds``, ``arena/light_center``,
``arena/trajectories`` (coloured by heading bias, split at gaps) and ``traits`` (markdown table);
per step ``arena/robots`` (LED colour), ``arena/headings``, ``light/kilobot_<id>``,
``metrics/<name>`` and ``metrics/recorded/<name>`` (what the analysis node recorded).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from ..core.constants import LED_BLUE, LED_OFF, LED_RED
from ..errors import is_number
from ..recording.swarm_data import SwarmRecording

APP_ID = "kilobot_twin"
TIMELINE = "time"


# --- colours -------------------------------------------------------------------------------------

#: The paper's heading-bias map (as kilobot_twin.plots.bias_cmap): red (left, b < 0) -> purple -> blue (right).
_BIAS_STOPS = np.array([[1.0, 0.0, 0.0], [0.5, 0.0, 0.5], [0.0, 0.35, 1.0]])


def bias_colours(bias: np.ndarray, limit: float | None = None) -> np.ndarray:
    """(N, 3) uint8 RGB of heading biases on the paper's map, symmetric around 0 (grey if unknown)."""
    bias = np.asarray(bias, dtype=np.float64)
    ok = np.isfinite(bias)
    lim = limit if limit else (float(np.max(np.abs(bias[ok]))) if ok.any() else 1.0) or 1.0
    u = np.clip((np.where(ok, bias, 0.0) / lim + 1.0) / 2.0, 0.0, 1.0) * 2.0  # 0..2 over two segments
    i = np.minimum(u.astype(int), 1)
    f = (u - i)[:, None]
    rgb = _BIAS_STOPS[i] * (1 - f) + _BIAS_STOPS[i + 1] * f
    rgb[~ok] = 0.5
    return np.round(rgb * 255).astype(np.uint8)


def led_colours(led: np.ndarray) -> np.ndarray:
    """(..., 4) uint8 RGBA of LED states: red, blue, dark grey when off, light grey when unknown."""
    led = np.asarray(led)
    out = np.empty(led.shape + (4,), dtype=np.uint8)
    out[...] = (200, 200, 200, 255)
    out[led == LED_RED] = (230, 20, 20, 255)
    out[led == LED_BLUE] = (20, 60, 240, 255)
    out[led == LED_OFF] = (60, 60, 60, 255)
    return out


def blueprint(rec: SwarmRecording | None = None) -> rrb.Blueprint:
    """Arena (3-D view from above, metres) next to light readings, swarm metrics and traits."""
    xmin, xmax, ymin, ymax = _extent(rec) if rec is not None else (-2.0, 2.0, -2.0, 2.0)
    cx, cy = 0.5 * (xmin + xmax), 0.5 * (ymin + ymax)
    height = 1.25 * max(xmax - xmin, ymax - ymin)
    arena = rrb.Spatial3DView(
        origin="arena", name="arena (m; x right, y up)",
        line_grid=rrb.LineGrid3D(visible=True, spacing=0.5, plane=rr.components.Plane3D.XY, stroke_width=1.0,
                                 color=[110, 110, 110, 120]),
        eye_controls=rrb.EyeControls3D(position=(cx, cy, height), look_target=(cx, cy, 0.0), eye_up=(0.0, 1.0, 0.0)),
    )
    return rrb.Blueprint(
        rrb.Horizontal(
            arena,
            rrb.Vertical(
                rrb.TimeSeriesView(origin="light", name="light readings (ADC counts) vs time (s)"),
                rrb.TimeSeriesView(origin="metrics", name="swarm metrics vs time (s)"),
                rrb.TextDocumentView(origin="traits", name="traits"),
            ),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )


def _extent(rec: SwarmRecording) -> tuple[float, float, float, float]:
    """(xmin, xmax, ymin, ymax) in m: the light field's extent, else the tracks (+ light centre) with a margin."""
    if rec.light_field is not None and rec.field_extent is not None:
        return tuple(float(v) for v in rec.field_extent)
    ok = np.isfinite(rec.x) & np.isfinite(rec.y)
    pad = 0.05
    xmin, xmax = (float(rec.x[ok].min()) - pad, float(rec.x[ok].max()) + pad) if ok.any() else (-1.0, 1.0)
    ymin, ymax = (float(rec.y[ok].min()) - pad, float(rec.y[ok].max()) + pad) if ok.any() else (-1.0, 1.0)
    if rec.light_center is not None:
        xmin, xmax = min(xmin, rec.light_center[0] - pad), max(xmax, rec.light_center[0] + pad)
        ymin, ymax = min(ymin, rec.light_center[1] - pad), max(ymax, rec.light_center[1] + pad)
    return xmin, xmax, ymin, ymax


def _xyz(x, y, z: float = 0.0) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    return np.stack([x, np.asarray(y, dtype=np.float64), np.full(x.shape, z)], axis=-1)


def _field_rgb(field: np.ndarray) -> np.ndarray:
    f = np.asarray(field, dtype=np.float64)
    lo, hi = np.nanmin(f), np.nanmax(f)
    u = (f - lo) / (hi - lo) if hi > lo else np.zeros_like(f)
    dark, bright = np.array([20.0, 20.0, 35.0]), np.array([255.0, 230.0, 120.0])
    return (dark + u[..., None] * (bright - dark)).astype(np.uint8)


def log_recording(rec: SwarmRecording, stream: rr.RecordingStream, arrow_m: float = 0.03) -> None:
    """Log every entity of ``rec`` into ``stream`` (static layers with ``log``, time series with ``send_columns``)."""
    N, T = rec.x.shape
    times = np.asarray(rec.t_s, dtype=np.float64)
    bias = rec.bias_for_colour()
    bcol = bias_colours(bias)
    xmin, xmax, ymin, ymax = _extent(rec)

    # --- static layers (metres; the field just below the tracks, the robots just above) ----
    stream.log("arena", rr.ViewCoordinates.RFU, static=True)
    if rec.light_field is not None:
        corners = _xyz([xmin, xmax, xmax, xmin], [ymax, ymax, ymin, ymin], -0.002)
        stream.log("arena/light_field", rr.Mesh3D(vertex_positions=corners, triangle_indices=[[0, 1, 2], [0, 2, 3]],
                                                  vertex_texcoords=[[0, 0], [1, 0], [1, 1], [0, 1]],  # row 0 = +y
                                                  albedo_texture=_field_rgb(rec.light_field)), static=True)
    stream.log("arena/bounds", rr.LineStrips3D([_xyz([xmin, xmax, xmax, xmin, xmin], [ymin, ymin, ymax, ymax, ymin])],
                                               colors=[(200, 200, 200)], radii=[rr.Radius.ui_points(1.0)]), static=True)
    if rec.light_center is not None:
        stream.log("arena/light_center", rr.Points3D(_xyz([rec.light_center[0]], [rec.light_center[1]], 0.003),
                                                     radii=[0.03], colors=[(255, 200, 0)], labels=["light"]), static=True)
    strips, strip_cols, strip_labels = [], [], []
    for i in range(N):
        ok = np.isfinite(rec.x[i]) & np.isfinite(rec.y[i])
        if not ok.any():
            continue
        # Contiguous runs of tracked samples: a gap ends a strip (nothing interpolated).
        edges = np.flatnonzero(np.diff(np.concatenate([[0], ok.astype(np.int8), [0]])))
        for a, b in zip(edges[::2], edges[1::2]):
            strips.append(_xyz(rec.x[i, a:b], rec.y[i, a:b]))
            strip_cols.append(bcol[i])
            strip_labels.append(f"{rec.robot_ids[i]}: b={bias[i]:+.4f}" if np.isfinite(bias[i]) else str(rec.robot_ids[i]))
    if strips:
        stream.log("arena/trajectories", rr.LineStrips3D(strips, colors=strip_cols,
                                                         radii=[rr.Radius.ui_points(1.5)] * len(strips),
                                                         labels=strip_labels, show_labels=False), static=True)
    stream.log("arena/info", rr.TextDocument(
        f"Arena in metres: x right, y up; {xmax - xmin:.2f} m x {ymax - ymin:.2f} m, grid 0.5 m. Trajectory colour = "
        "heading bias b, the wheel imbalance (red = left / negative, blue = right / positive). Points = robots "
        "(radius 1.7 cm) in their LED colour."), static=True)
    stream.log("traits", rr.TextDocument(_traits_markdown(rec, bias), media_type=rr.MediaType.MARKDOWN), static=True)

    # --- robots over time: one row per step, one instance per tracked robot -------------
    ok = np.isfinite(rec.x) & np.isfinite(rec.y)          # (N, T)
    lengths = ok.sum(axis=0)                              # robots per step
    okT = ok.T                                            # (T, N): row-major order = step, then robot
    xyz = _xyz(rec.x.T[okT], rec.y.T[okT], 0.004)
    th = np.where(np.isfinite(rec.theta), rec.theta, 0.0).T[okT]
    cols = led_colours(rec.led.T[okT])
    ids = np.broadcast_to(rec.robot_ids[None, :], (T, N))[okT]
    index = [rr.TimeColumn(TIMELINE, duration=times)]
    stream.send_columns("arena/robots", indexes=index, columns=rr.Points3D.columns(
        positions=xyz, colors=cols, radii=np.full(len(xyz), 0.017, dtype=np.float32),
        class_ids=ids.astype(np.uint16)).partition(lengths))
    stream.send_columns("arena/headings", indexes=index, columns=rr.Arrows3D.columns(
        origins=xyz, vectors=np.stack([np.cos(th), np.sin(th), np.zeros_like(th)], axis=-1) * arrow_m,
        colors=np.repeat(np.array([[240, 240, 240, 255]], dtype=np.uint8), len(xyz), axis=0)).partition(lengths))

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
        tr = {k: v for k, v in tr.items() if is_number(v, finite=False)}
        for k in tr:
            if k not in keys:
                keys.append(k)
        rows.append((int(rid), bias[i], tr))
    head = f"# {rec.name}: {rec.n_robots} robots, {rec.n_steps} samples\n\n"
    if not keys:
        head += "No trait records; heading bias estimated from motion.\n\n"
    head += ("Heading bias is the wheel imbalance b (paper Eq. 7, + = curves right), the model's scale; "
             "the paper preset reads the paper's axis as b / 10.\n\n")
    names = {"heading_bias": "heading_bias b (wheel imbalance)"}
    cols = ["robot", "b for the colour (wheel imbalance)"] + [names.get(k, k) for k in keys]
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
    bp = blueprint(rec)
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
