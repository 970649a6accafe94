"""Campaigns: a parameter grid x Monte Carlo runs, sharded over local cores or a Dask cluster.

Every (grid point, chunk of runs) is one task; it runs :func:`kilobot_twin.batch.engine.simulate`
(the compiled kernel over all (run, robot) slots of the task, or the core where the kernel
does not apply). Because random streams are keyed by (seed, run, robot), how the runs are
chunked or spread over threads, processes or machines changes nothing in the results.

Where they run: tasks on the compiled kernel go to a pool of ``workers`` threads (the kernel
releases the GIL); tasks on the core to a pool of ``workers`` processes; with ``scheduler``
(``local:N`` or ``tcp://HOST:PORT``, see :mod:`.cluster`) to a Dask cluster. Summaries (grid,
runs, robots) are gathered here (they are small); trajectories, when asked for, are streamed
to one ``.npz`` shard per task instead of being held in memory.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import multiprocessing as mp
import os
import threading
import time
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from .. import __version__
from ..core.scenario import Scenario, with_overrides
from ..core.traits import TRAIT_NAMES, SwarmTraits
from ..errors import ConfigError
from . import engine


@dataclass
class Campaign:
    """A grid of scenario variations, each simulated for ``runs`` Monte Carlo runs.

    Parameters
    ----------
    scenario : Scenario
    swarm : SwarmTraits
    seed : int
    runs : int
    grid : mapping of dotted scenario key -> list of values
        e.g. ``{"behavior.p_right": [0.25, 0.5, 1.0]}``; the cartesian product is simulated.
    record_every : int
        0 for summaries only; otherwise trajectories every this many steps, streamed to disk.
    """

    scenario: Scenario
    swarm: SwarmTraits
    seed: int = 0
    runs: int = 1
    grid: Mapping[str, Sequence[Any]] = field(default_factory=dict)
    record_every: int = 0
    trials_from_runs: bool = False

    def points(self) -> list[dict]:
        keys = list(self.grid)
        return [dict(zip(keys, vals)) for vals in itertools.product(*(self.grid[k] for k in keys))] or [{}]

    def scenario_at(self, point: Mapping[str, Any]) -> Scenario:
        return with_overrides(self.scenario, point, source="grid")


# --- worker side -------------------------------------------------------------------------
_COUNTER = None


def _init_worker(counter):
    global _COUNTER
    _COUNTER = counter


def _bump(n_robot_steps: int):
    if _COUNTER is not None:
        with _COUNTER.get_lock():
            _COUNTER.value += n_robot_steps


def _run_task(task, bump=None):
    """Run one task; report robot-steps to ``bump`` (default: the worker's shared counter)."""
    g, scenario, swarm, seed, runs, trials, record_every, shard = task
    n_robots = len(swarm)
    bump = bump or _bump
    res = engine.simulate(scenario, swarm, seed, runs=runs, trials=trials, record_every=record_every,
                          progress=lambda steps: bump(steps * len(runs) * n_robots))
    if shard is not None and res.traj is not None:
        _write_shard(shard, res.t_s, runs, swarm.ids, res.traj)
    return g, runs, res.summary, res.order


def _run_remote(task):
    """A task on a Dask worker: trajectories travel back with the result (the client writes the
    shard), so workers need no file system shared with the client."""
    g, scenario, swarm, seed, runs, trials, record_every, shard = task
    res = engine.simulate(scenario, swarm, seed, runs=runs, trials=trials, record_every=record_every)
    traj = (res.t_s, res.traj) if shard is not None and res.traj is not None else None
    return g, runs, res.summary, res.order, traj


def _write_shard(shard, t_s, runs, robot_ids, traj):
    np.savez(shard, t_s=t_s, runs=runs, robot_ids=robot_ids, **traj)


def _chunks(n_runs: int, n_robots: int, workers: int, target_robots: int = 2500) -> list[np.ndarray]:
    """Split runs into chunks big enough to vectorise well and many enough to balance cores."""
    per_chunk = max(1, min(n_runs, max(target_robots // max(n_robots, 1), int(np.ceil(n_runs / (2 * workers))))))
    per_chunk = min(per_chunk, int(np.ceil(n_runs / workers))) if workers > 1 else per_chunk
    return [np.arange(i, min(i + per_chunk, n_runs)) for i in range(0, n_runs, per_chunk)]


def run_campaign(c: Campaign, out: str | Path | None = None, workers: int | None = None, progress: bool = True,
                 parquet: bool = False, desc: str = "campaign", scheduler: str | None = None) -> dict:
    """Run a campaign and return its results (and write them if ``out`` is given).

    Parameters
    ----------
    workers : int, optional
        Local threads or processes (default: all cores); ignored with ``scheduler``.
    scheduler : str, optional
        ``local:N`` (a Dask LocalCluster of N worker processes) or ``tcp://HOST:PORT`` (a running
        Dask scheduler); None runs on this machine's pool. The results are the same either way.

    Returns
    -------
    dict
        ``summary``: metric -> (G, R, N) array; ``points``: list of grid points; ``meta``: dict;
        ``order``: (G, R, T) Kuramoto order parameter for blink scenarios.
    """
    dask_client = None
    if scheduler is not None:
        from .cluster import client, worker_threads

        dask_client = client(scheduler)
        workers = worker_threads(dask_client)
    workers = workers or os.cpu_count() or 1
    points = c.points()
    scenarios = [c.scenario_at(p) for p in points]
    n_robots = len(c.swarm)
    chunks = _chunks(c.runs, n_robots, workers)
    out_dir = Path(out).with_suffix("") if out is not None else None
    traj_dir = None
    if c.record_every and out_dir is not None:
        traj_dir = out_dir.parent / (out_dir.name + "_traj")
        traj_dir.mkdir(parents=True, exist_ok=True)
    tasks = []
    for g, sc in enumerate(scenarios):
        for i, runs in enumerate(chunks):
            trials = runs if c.trials_from_runs else None
            shard = str(traj_dir / f"g{g:03d}_c{i:04d}.npz") if traj_dir is not None else None
            tasks.append((g, sc, c.swarm, c.seed, runs, trials, c.record_every, shard))
    total = sum(sc.n_steps for sc in scenarios) * c.runs * n_robots

    summary: dict[str, np.ndarray] = {}
    orders: dict[int, dict] = {}
    t0 = time.perf_counter()
    counter = mp.get_context("fork").Value("q", 0)
    bar = _bar(total, desc) if progress else None
    stop = threading.Event()

    def poll():
        last = 0
        while not stop.wait(0.2):
            v = counter.value
            if bar is not None and v > last:
                bar.update(v - last)
                last = v
        if bar is not None:
            bar.update(counter.value - last)

    poller = threading.Thread(target=poll, daemon=True) if bar is not None else None
    if poller is not None:
        poller.start()

    def collect(g, runs, summ, order):
        for k, v in summ.items():
            if k not in summary:
                summary[k] = np.zeros((len(points), c.runs, n_robots), dtype=v.dtype)
            summary[k][g, runs] = v
        if order is not None:
            orders.setdefault(g, {})[int(runs[0])] = order

    def bump(n_robot_steps):
        with counter.get_lock():
            counter.value += n_robot_steps

    try:
        if dask_client is not None:
            _run_dask(dask_client, tasks, collect, bump, n_robots)
        elif workers == 1 or len(tasks) == 1:
            for t in tasks:
                collect(*_run_task(t, bump))
        elif all(engine.compiled(sc) for sc in scenarios):
            with ThreadPoolExecutor(max_workers=workers) as pool:
                futures = [pool.submit(_run_task, t, bump) for t in tasks]
                for f in as_completed(futures):
                    collect(*f.result())
        else:
            with ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("fork"),
                                     initializer=_init_worker, initargs=(counter,)) as pool:
                futures = [pool.submit(_run_task, t) for t in tasks]
                for f in as_completed(futures):
                    collect(*f.result())
    finally:
        stop.set()
        if poller is not None:
            poller.join()
        if bar is not None:
            bar.close()
    elapsed = time.perf_counter() - t0
    order = None
    if orders:
        order = np.stack([np.concatenate([orders[g][k] for k in sorted(orders[g])], axis=0) for g in range(len(points))])
    meta = {
        "format": "kilobot-twin/campaign-v1",
        "version": __version__,
        "seed": c.seed,
        "runs": c.runs,
        "grid": {k: list(v) for k, v in c.grid.items()},
        "points": points,
        "scenario": c.scenario.to_dict(),
        "traits": c.swarm.to_dict(),
        "elapsed_s": elapsed,
        "robot_steps": total,
        "workers": workers,
        "scheduler": scheduler or "local",
        "trajectories": str(traj_dir) if traj_dir is not None else None,
    }
    result = {"summary": summary, "points": points, "meta": meta, "order": order, "swarm": c.swarm}
    if out is not None:
        save_results(result, out, parquet=parquet)
    return result


def _run_dask(dask_client, tasks, collect, bump, n_robots):
    """Submit every task to the cluster; gather (and write shards) as they complete."""
    from distributed import as_completed as dask_completed

    futures = {dask_client.submit(_run_remote, t, pure=False): t for t in tasks}
    try:
        for f in dask_completed(futures):
            task = futures[f]
            g, runs, summ, order, traj = f.result()
            if traj is not None:
                _write_shard(task[7], traj[0], runs, task[2].ids, traj[1])
            collect(g, runs, summ, order)
            bump(task[1].n_steps * len(runs) * n_robots)
            f.release()
    except BaseException:
        for f in futures:
            f.cancel()
        raise


def _bar(total: int, desc: str):
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=desc, unit="robot-step", unit_scale=True, smoothing=0.1, mininterval=0.5)


def save_results(result: dict, out: str | Path, parquet: bool = False) -> Path:
    """Write ``out`` (.npz): metrics (G, R, N), traits (N,), grid values, and JSON metadata."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    swarm: SwarmTraits = result["swarm"]
    arrays = {f"summary_{k}": v for k, v in result["summary"].items()}
    arrays.update({f"trait_{k}": swarm.values[k] for k in TRAIT_NAMES})
    arrays["robot_ids"] = swarm.ids
    if result.get("order") is not None:
        arrays["order"] = result["order"]
    arrays["meta_json"] = np.array(json.dumps(result["meta"], default=_json_default))
    tmp = out.with_name(out.name + ".partial.npz")
    np.savez_compressed(tmp, **arrays)
    os.replace(tmp, out)
    if parquet:
        write_parquet(result, out.with_suffix(".parquet"))
    return out


def _json_default(o):
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    if dataclasses.is_dataclass(o):
        return dataclasses.asdict(o)
    return str(o)


def load_results(path: str | Path) -> dict:
    """Read a results file written by :func:`save_results`."""
    p = Path(path)
    if not p.is_file():
        raise ConfigError(str(p), "results file not found", "run a campaign or simulate first")
    with np.load(p, allow_pickle=False) as z:
        meta = json.loads(str(z["meta_json"]))
        summary = {k[len("summary_"):]: z[k] for k in z.files if k.startswith("summary_")}
        values = {k[len("trait_"):]: z[k] for k in z.files if k.startswith("trait_")}
        swarm = SwarmTraits(z["robot_ids"], values)
        order = z["order"] if "order" in z.files else None
    return {"summary": summary, "points": meta["points"], "meta": meta, "order": order, "swarm": swarm}


def write_parquet(result: dict, path: str | Path) -> Path:
    """Long table: one row per (grid point, run, robot) with grid values, traits and metrics."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    summary = result["summary"]
    G, R, N = next(iter(summary.values())).shape
    g, r, n = np.meshgrid(np.arange(G), np.arange(R), np.arange(N), indexing="ij")
    cols = {"grid_index": g.ravel(), "run": r.ravel(), "robot_id": result["swarm"].ids[n.ravel()]}
    for key in result["meta"]["grid"]:
        vals = np.array([p[key] for p in result["points"]])
        cols[key] = vals[g.ravel()]
    for k, v in result["swarm"].values.items():
        cols[f"trait_{k}"] = v[n.ravel()]
    for k, v in summary.items():
        cols[k] = v.ravel()
    table = pa.table(cols)
    table = table.replace_schema_metadata({"kilobot_twin": json.dumps(result["meta"], default=_json_default)})
    pq.write_table(table, path)
    return Path(path)
