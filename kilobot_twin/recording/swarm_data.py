"""One swarm recording as arrays, whatever it came from (a bag or batch results).

Compute, then draw: :class:`SwarmRecording` holds plain arrays; the Rerun writer only reads
them. A bag is read in two steps: :func:`decode_bag` (the messages -> each robot's samples as
recorded) and :func:`align` (those series -> the regular arrays).

Alignment: robot samples are placed on a grid of the robots' own ``header.stamp`` (slot
``round((stamp - t0) / dt)`` with ``dt`` the median stamp step), so lockstep, realtime and
imported (jittered) bags line up; a robot without a sample in a slot has NaN there (a gap).
``led`` carries no stamp: an LED message belongs to the first pose the same robot logged at or
after it (robots publish light, led, clock, then pose). ``/analysis/*`` values are put on the
simulated time the analysis node published with them (``/analysis/time_s``), or for older bags on
the recorded ``/clock`` time of their log time; undefined (NaN) values are left out.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

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


# --- batch results --------------------------------------------------------------------------------

def from_results(path: str | Path, point: int = 0, run: int = 0) -> SwarmRecording:
    """One (grid point, run) of a batch experiment with recorded trajectories (``record_every > 0``)."""
    from ..batch.campaign import load_results
    from ..core.scenario import scenario_from_dict, with_overrides
    from ..errors import ConfigError

    path = Path(path)
    res = load_results(path)
    meta = res["meta"]
    points = len(meta["points"])
    if not 0 <= point < points:  # (a negative point was read as "no trajectories", as was one past the grid)
        raise ConfigError("--point", f"grid point {point} is not in {path} (points 0..{points - 1})", "pick a grid point")
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


# --- bags -----------------------------------------------------------------------------------------

@dataclass
class BagSeries:
    """A twin bag's samples as recorded (the decode step), per robot id, in log order.

    pose: [(stamp ns, log ns, x m, y m, theta rad)]; light: [(stamp ns, reading)]; clock:
    [(stamp ns, ticks)]; led: [(log ns, led)]; ``clock_log_ns`` / ``clock_ns``: ``/clock``'s log
    times and values; analysis: name -> [(log ns, value)] of ``/analysis/*``.
    """

    name: str
    file: Path
    pose: dict[int, list] = field(default_factory=dict)
    light: dict[int, list] = field(default_factory=dict)
    clock: dict[int, list] = field(default_factory=dict)
    led: dict[int, list] = field(default_factory=dict)
    traits: dict[int, dict] = field(default_factory=dict)
    clock_log_ns: list = field(default_factory=list)
    clock_ns: list = field(default_factory=list)
    analysis: dict[str, list] = field(default_factory=dict)
    world_doc: str | None = None
    light_field: np.ndarray | None = None
    meta: dict = field(default_factory=dict)


def decode_bag(bag_dir: str | Path) -> BagSeries:
    """Every robot sample, ``/clock``, ``/analysis/*`` value and world document of a twin bag."""
    import json
    import math

    from ..core.constants import TICK_HZ
    from . import cdr
    from .bag import BagReader
    from .topics import parse_robot_topic

    bag_dir = Path(bag_dir)
    reader = BagReader(bag_dir)
    s = BagSeries(bag_dir.name, reader.file)
    for topic, type_name, log_ns, _pub, data in reader.messages():
        m = parse_robot_topic(topic)
        if m:
            rid, kind = m
            if kind == "pose":
                stamp, x, y, qz, qw = cdr.pose_stamped(data)
                s.pose.setdefault(rid, []).append((stamp, log_ns, x, y, 2.0 * math.atan2(qz, qw)))
            elif kind == "light":
                s.light.setdefault(rid, []).append(cdr.illuminance(data)[:2])
            elif kind == "led":
                s.led.setdefault(rid, []).append((log_ns, cdr.led(data)))
            elif kind == "clock":
                stamp, ref_ns = cdr.time_reference(data)
                s.clock.setdefault(rid, []).append((stamp, ref_ns / cdr.NS_PER_S * TICK_HZ))
            else:
                try:
                    s.traits[rid] = json.loads(cdr.string(data))
                except ValueError:
                    pass
        elif topic == "/clock":
            s.clock_log_ns.append(log_ns)
            s.clock_ns.append(cdr.clock_ns(data))
        elif topic.startswith("/analysis/") and type_name == "std_msgs/msg/Float64":
            s.analysis.setdefault(topic.rsplit("/", 1)[-1], []).append((log_ns, cdr.float64(data)))
        elif topic == "/world/scenario":
            s.world_doc = cdr.string(data)
        elif topic == "/world/light_field" and s.light_field is None:
            s.light_field = cdr.image_32fc1(data)
    s.meta = {"source": str(bag_dir), **({"damage": reader.note} if reader.note else {}), **reader.metadata()}
    return s


def align(s: BagSeries) -> SwarmRecording:
    """A bag's series on one regular time grid (see the module's docstring)."""
    from ..core.scenarios import parse_world_document, scenario_from_document
    from ..errors import ConfigError

    cl, cn = np.asarray(s.clock_log_ns, dtype=np.int64), np.asarray(s.clock_ns, dtype=np.int64)
    pose, light, clock, led = s.pose, s.light, s.clock, s.led

    def log_to_stamp(log):
        """Recorded time of a log time: the last /clock value logged at or before it."""
        j = np.clip(np.searchsorted(cl, log, side="right") - 1, 0, len(cl) - 1)
        return cn[j]

    if not (pose or light or (led and len(cl))):
        raise ConfigError(str(s.file), "no /kilobot_<id>/pose, light or led messages",
                          "give a bag of a twin run or an imported dataset")
    ids = np.array(sorted(set(pose) | set(light) | (set(led) if len(cl) else set())), dtype=np.int64)
    stamps = {}
    for r in ids:
        parts = [np.array([p[0] for p in pose.get(r, [])], dtype=np.int64),
                 np.array([q[0] for q in light.get(r, [])], dtype=np.int64)]
        if r not in pose and r not in light and r in led:
            parts.append(log_to_stamp(np.array([q[0] for q in led[r]], dtype=np.int64)))
        stamps[r] = np.unique(np.concatenate(parts))
    t0 = min(int(st.min()) for st in stamps.values() if len(st))
    steps = np.concatenate([np.diff(st) for st in stamps.values() if len(st) > 1] or [np.array([1])])
    steps = steps[steps > 0]
    dt_ns = int(np.median(steps)) if len(steps) else 1
    T = max(int(round((int(st.max()) - t0) / dt_ns)) for st in stamps.values() if len(st)) + 1
    N = len(ids)
    x, y, th, rd, lv, tk = (np.full((N, T), np.nan) for _ in range(6))

    def slot(ns):
        return np.clip(np.rint((np.asarray(ns, dtype=np.float64) - t0) / dt_ns).astype(np.int64), 0, T - 1)

    for i, r in enumerate(ids):
        if r in pose:
            p = np.array(pose[r], dtype=np.float64)
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
    if s.world_doc:
        try:
            scenario = scenario_from_document(parse_world_document(s.world_doc))
        except (ConfigError, KeyError, ValueError, TypeError):
            scenario = None
    extent = None
    if scenario is not None:
        ar = scenario.arena
        extent = (-ar.width_m / 2, ar.width_m / 2, -ar.height_m / 2, ar.height_m / 2)
    bias = np.array([float(s.traits.get(int(r), {}).get("traits", {}).get("heading_bias", np.nan)) for r in ids])

    recorded = {}
    analysis = dict(s.analysis)
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

    return SwarmRecording(
        name=s.name, robot_ids=ids, t_s=np.arange(T) * dt_ns / 1e9, x=x, y=y, theta=th, led=lv, reading=rd,
        ticks=tk, heading_bias=bias, traits={int(k): v for k, v in s.traits.items()},
        light_center=tuple(scenario.light.center) if scenario is not None else _center_from_meta(s.meta),
        light_field=s.light_field, field_extent=extent, recorded_metrics=recorded,
        period_ticks=blink_period_ticks(scenario) if scenario is not None else None,
        meta={**s.meta, "t0_ns": t0, "dt_ns": dt_ns})


def from_bag(bag_dir: str | Path) -> SwarmRecording:
    """A twin bag (simulated, replayed or imported) -> :class:`SwarmRecording`."""
    return align(decode_bag(bag_dir))


def _center_from_meta(meta: dict):
    """Light centre written by the importer (``kilobot_twin.import`` metadata), if any."""
    import json

    doc = meta.get("kilobot_twin.import", {})
    if "light_center" in doc:
        try:
            c = json.loads(doc["light_center"])
            return float(c[0]), float(c[1])
        except (ValueError, TypeError, IndexError):
            return None
    return None


def load_source(source: str | Path, point: int = 0, run: int = 0) -> SwarmRecording:
    """A bag directory or a batch results ``.npz`` -> :class:`SwarmRecording`."""
    from ..errors import ConfigError

    src = Path(source)
    if src.suffix == ".npz":
        return from_results(src, point=point, run=run)
    if src.is_dir():
        return from_bag(src)
    raise ConfigError(str(src), "not a bag directory or a results .npz",
                      "give bags/NAME (from `run` or `import`) or results.npz (from `simulate`)")
