"""One swarm recording as arrays, whatever it came from (a bag, batch results, a measured dataset).

Compute, then draw: :class:`SwarmRecording` holds plain arrays; the Rerun writer only reads
them. No rclpy, mcap or rerun import here.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.constants import LED_BLUE, LED_OFF, LED_RED
from ..core.light import raster
from ..core.metrics import METRICS, swarm_metrics


@dataclass
class SwarmRecording:
    """N robots over T samples on a common time axis; NaN marks a missing sample (tracking gap).

    Attributes
    ----------
    robot_ids : (N,) int
    t_s : (T,) sample times in s (simulated or measured time, starting near 0)
    x, y, theta : (N, T) position in m and heading in rad (counter-clockwise from +x)
    led : (N, T) LED_RED (0), LED_BLUE (1), LED_OFF (2) or NaN (not recorded)
    reading : (N, T) raw light reading (ADC counts) or NaN
    ticks : (N, T) robot clock ticks or NaN (for the blink order parameter)
    heading_bias : (N,) dimensionless, + = clockwise (right); NaN if unknown
    traits : robot id -> document (traits, behaviour, ...) shown in the traits panel
    light_center : (x, y) in m, or None
    light_field : (H, W) light intensity raster (row 0 = +y), or None; ``field_extent`` (xmin, xmax, ymin, ymax) m
    recorded_metrics : name -> (t_s, values) as recorded (e.g. ``/analysis/*``)
    period_ticks : blink period in ticks (order parameter), or None
    """

    name: str
    robot_ids: np.ndarray
    t_s: np.ndarray
    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray
    led: np.ndarray
    reading: np.ndarray
    ticks: np.ndarray | None = None
    heading_bias: np.ndarray | None = None
    traits: dict = field(default_factory=dict)
    light_center: tuple[float, float] | None = None
    light_field: np.ndarray | None = None
    field_extent: tuple[float, float, float, float] | None = None
    recorded_metrics: dict = field(default_factory=dict)
    period_ticks: float | None = None
    meta: dict = field(default_factory=dict)

    @property
    def n_robots(self) -> int:
        return len(self.robot_ids)

    @property
    def n_steps(self) -> int:
        return len(self.t_s)

    def metrics(self) -> dict[str, np.ndarray]:
        """Swarm metrics per sample, (T,) each, over the robots with a value at that sample (NaN if
        none): :func:`kilobot_twin.core.metrics.swarm_metrics` without the coverage; the LED
        fractions only when LEDs were recorded, the order parameter only for blink scenarios."""
        ticks = self.ticks if self.ticks is not None else np.full_like(self.x, np.nan)
        m = swarm_metrics(self.x.T, self.y.T, self.led.T, ticks.T,
                          self.light_center if self.light_center is not None else (np.nan, np.nan),
                          self.period_ticks if np.isfinite(ticks).any() else None)
        keep = [k for k in METRICS if k != "covered_area_m2" and np.isfinite(m[k]).any()]
        return {k: m[k] for k in keep}

    def bias_for_colour(self) -> np.ndarray:
        """Heading bias per robot for the trajectory colour: the known trait, else estimated from motion."""
        bias = np.full(self.n_robots, np.nan) if self.heading_bias is None else np.asarray(self.heading_bias, float)
        missing = ~np.isfinite(bias)
        if missing.any():
            from ..analysis import heading_bias_from_track

            est = heading_bias_from_track(self.t_s, self.x[missing], self.y[missing])
            bias = bias.copy()
            bias[missing] = est
        return bias


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


# --- batch results --------------------------------------------------------------------------------

def from_results(path: str | Path, point: int = 0, run: int = 0) -> SwarmRecording:
    """One (grid point, run) of a batch experiment with recorded trajectories (``record_every > 0``)."""
    from ..batch.campaign import load_results
    from ..core.scenario import scenario_from_dict, with_overrides
    from ..errors import ConfigError

    path = Path(path)
    res = load_results(path)
    meta = res["meta"]
    traj_dir = meta.get("trajectories")
    traj_dir = Path(traj_dir) if traj_dir else path.with_suffix("").parent / (path.stem + "_traj")
    if not traj_dir.is_absolute() and not traj_dir.is_dir():
        traj_dir = path.parent / traj_dir.name
    shards = sorted(traj_dir.glob(f"g{point:03d}_c*.npz")) if traj_dir.is_dir() else []
    if not shards:
        raise ConfigError(str(path), f"no trajectories for grid point {point} (looked in {traj_dir})",
                          "simulate with record_every: 1 (or more) in the config to record trajectories")
    for shard in shards:
        with np.load(shard) as z:
            runs = z["runs"]
            hit = np.nonzero(runs == run)[0]
            if not len(hit):
                continue
            k = int(hit[0])
            t_s = z["t_s"]
            arrays = {n: z[n][k].astype(np.float64) for n in ("x", "y", "theta", "led", "reading") if n in z.files}
            ids = z["robot_ids"]
            break
    else:
        raise ConfigError("--run", f"run {run} is not in {path} (runs 0..{meta['runs'] - 1})", "pick a recorded run")
    scenario = with_overrides(scenario_from_dict(meta["scenario"]), meta["points"][point])
    swarm = res["swarm"]
    traits = {int(i): {k: float(v[j]) for k, v in swarm.values.items()} for j, i in enumerate(swarm.ids)}
    order = {int(i): j for j, i in enumerate(swarm.ids)}
    bias = np.array([swarm.values["heading_bias"][order[int(i)]] for i in ids])
    n = len(ids)
    nan = np.full((n, len(t_s)), np.nan)
    fld, extent = field_raster(scenario)
    return SwarmRecording(
        name=path.stem, robot_ids=np.asarray(ids), t_s=np.asarray(t_s, float), x=arrays["x"], y=arrays["y"],
        theta=arrays.get("theta", nan), led=arrays.get("led", nan), reading=arrays.get("reading", nan),
        heading_bias=bias, traits=traits, light_center=tuple(scenario.light.center), light_field=fld, field_extent=extent,
        period_ticks=blink_period_ticks(scenario), meta={"source": str(path), "point": meta["points"][point], "run": run,
                                              "seed": meta.get("seed")})


def blink_period_ticks(scenario) -> float | None:
    """Blink period in ticks of a blink scenario (None otherwise)."""
    half = getattr(scenario.behavior, "half_period_ticks", None)
    return 2.0 * half if half else None


def field_raster(scenario, pixels: int = 128, t_s: float = 0.0):
    """The scenario's light field on the arena (as the world node rasterises it) and its extent."""
    img, extent = raster(scenario.light, scenario.arena, pixels, t_s)
    return img.astype(np.float32), extent
