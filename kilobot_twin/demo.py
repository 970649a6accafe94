"""The main job on embedded defaults: the twin demo.

1. The ROS 2 twin: 20 individual Kilobots doing phototaxis as ROS nodes (world, swarm,
   analysis, recorder processes, lockstep time), recorded to ``bags/twin`` (rosbag2 MCAP);
2. that bag as a Rerun recording ``twin.rrd`` (open it with ``rerun twin.rrd``);
3. the paper's phototaxis campaign (Fig. 5) on the batch engine: ``results.npz`` (+ Parquet),
   ``phototaxis.png`` and the headline numbers per P_R;
4. ``summary.json`` / ``summary.md`` tying them together.

Every run writes into a fresh folder ``OUT/run-<UTC time>/`` and, once finished, points ``OUT/latest`` at it,
so ``make demo`` works every time and never touches an earlier run (or any other bag).
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np

from .analysis import phototaxis_summary
from .batch import run_campaign
from .config import config_from_dict
from .plots import cost_vs_bias

#: The demo's configuration (what ``config/demo_phototaxis.yaml`` also holds).
DEMO_CONFIG = {
    "scenario": {"preset": "paper", "behavior": {"kind": "phototaxis"}},
    # On the paper's heading-bias axis: the paper preset applies wheel imbalance b = 10 x axis.
    "swarm": {"population": {"n": 41, "heading_bias_paper_axis": {"dist": "linspace", "low": -0.04, "high": 0.04}}},
    "seed": 2023,
    "runs": 30,
    "grid": {"behavior.p_right": [0.25, 0.5, 1.0]},
}


TWIN = {"scenario": "phototaxis", "robots": 20, "duration": 120.0, "seed": 2023, "mode": "lockstep"}
QUICK_TWIN_S = 30.0  # simulated seconds of the twin in --quick mode


def run_twin_and_view(out: Path, quick: bool = False, echo=print) -> dict:
    """Run the ROS 2 twin into a bag, convert the bag to a Rerun recording; returns both reports."""
    from .ros.launcher import run_twin
    from .recording.swarm_data import load_source
    from .viewer.rerun_view import write_rrd

    cfg = dict(TWIN, duration=QUICK_TWIN_S if quick else TWIN["duration"])
    bag = out / "bags" / "twin"
    echo(f"twin: {cfg['robots']} robots, {cfg['scenario']}, {cfg['duration']:g} s ({cfg['mode']}) -> {bag}")
    report = run_twin(cfg["scenario"], cfg["robots"], cfg["duration"], cfg["seed"], cfg["mode"], None, str(bag),
                      echo=echo)
    echo(report.text())
    rec = load_source(str(bag))
    view = write_rrd(rec, str(out / "twin.rrd"))
    echo(f"rerun recording: {out / 'twin.rrd'} ({rec.n_robots} robots x {rec.n_steps} samples)")
    return {"bag": str(bag), "rrd": str(out / "twin.rrd"), "run": report, "view": view, "config": cfg}


def rerun_command(rrd: str | Path) -> str:
    """The command that opens ``rrd`` with this environment's viewer (``.venv/bin/rerun`` is not on PATH)."""
    import shutil
    import sys

    exe = Path(sys.executable).parent / "rerun"
    if not exe.exists():
        exe = Path(shutil.which("rerun") or "rerun")
    try:
        exe = exe.relative_to(Path.cwd())
    except ValueError:
        pass
    return f"{exe} {rrd}"


def new_run_dir(root: str | Path) -> Path:
    """A fresh folder ``root/run-YYYYmmdd-HHMMSS[-k]`` (UTC), created here (see :func:`point_latest`)."""
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    stamp = time.strftime("%Y%m%d-%H%M%S", time.gmtime())
    k = 1
    while True:
        run = root / (f"run-{stamp}" if k == 1 else f"run-{stamp}-{k}")
        try:
            run.mkdir()
            break
        except FileExistsError:
            k += 1
    return run


def point_latest(run: Path) -> None:
    """``run.parent/latest`` -> ``run`` (relative, atomic), unless ``latest`` is a real folder of the user's."""
    root = run.parent
    latest = root / "latest"
    if latest.is_symlink() or not latest.exists():
        tmp = root / f".latest-{os.getpid()}"
        tmp.unlink(missing_ok=True)
        tmp.symlink_to(run.name)
        os.replace(tmp, latest)  # atomic: readers see the old or the new run, never none


def run_demo(out: str | Path = "out/demo", quick: bool = False, workers: int | None = None,
             progress: bool = True, twin: bool = True) -> dict:
    """Run the demo into a fresh ``out/run-<time>/``; ``out/latest`` points at it when it is done."""
    out = new_run_dir(out)
    twin_res = run_twin_and_view(out, quick) if twin else None
    doc = json.loads(json.dumps(DEMO_CONFIG))
    if quick:
        doc["runs"] = 10
    cfg = config_from_dict(doc, source="demo")
    result = run_campaign(cfg, out=out / "results.npz", workers=workers, progress=progress,
                          parquet=True, desc="phototaxis demo")
    from .core.scenario import bias_axis_scale

    p_rights = cfg.grid["behavior.p_right"]
    scale = bias_axis_scale(doc["scenario"].get("preset"))
    bias = cfg.swarm.heading_bias / scale  # on the paper's axis
    cost = result["summary"]["cost_m"]
    summary = phototaxis_summary(bias, cost, p_rights)
    plot = cost_vs_bias(bias, cost, [f"P_R = {p}" for p in p_rights], out / "phototaxis.png",
                        title=f"Phototaxis: {len(bias)} robots x {cfg.runs} runs, seed {cfg.seed}",
                        xlabel=f"heading bias on the paper's axis (+ = right; wheel imbalance b = {scale:g} x axis)")
    meta = result["meta"]
    summary_doc = {
        "seed": cfg.seed,
        "runs": cfg.runs,
        "robots": len(bias),
        # Every bias below (best_bias, R_acc) is on the paper's axis; the model applied b = scale x axis.
        "bias_scale": {"axis": "paper", "wheel_imbalance_per_axis_unit": scale},
        "robot_steps_per_s": round(meta["robot_steps"] / meta["elapsed_s"]),
        "per_p_right": summary,
    }
    if twin_res is not None:
        rep = twin_res["run"]
        summary_doc["twin"] = {"bag": twin_res["bag"], "rerun": twin_res["rrd"], **twin_res["config"],
                               "simulated_s": rep.sim_s, "wall_s": rep.wall_s, "real_time_factor": rep.real_time_factor,
                               "messages": int(sum(rep.counts.values())) if getattr(rep, "counts", None) else None}
    (out / "summary.json").write_text(json.dumps(summary_doc, indent=2))
    lines = ["# kilobot_twin demo", ""]
    if twin_res is not None:
        t = summary_doc["twin"]
        lines += ["## The ROS 2 twin", "",
                  f"{t['robots']} individual Kilobots doing phototaxis as ROS 2 nodes ({t['mode']}), "
                  f"{'?' if t['simulated_s'] is None else format(t['simulated_s'], 'g')} of {t['duration']:g} s simulated; "
                  f"bag `{t['bag']}` (rosbag2 MCAP), Rerun recording `{t['rerun']}` (open it with `make view` "
                  f"or `{rerun_command(t['rerun'])}`; without a GPU add `--web-viewer`).", "",
                  "```", twin_res["run"].text(), "```", ""]
    lines += [
        "## Phototaxis campaign (paper Fig. 5, batch engine)",
        "",
        f"{len(bias)} robots (heading bias on the paper's axis {bias.min():+.3f} .. {bias.max():+.3f}, i.e. wheel "
        f"imbalance b = {scale:g} x axis = {bias.min() * scale:+.2f} .. {bias.max() * scale:+.2f}) x {cfg.runs} Monte Carlo "
        f"runs, seed {cfg.seed}; {meta['elapsed_s']:.1f} s at {meta['robot_steps'] / meta['elapsed_s'] / 1e6:.1f} M robot-steps/s.",
        "",
        "- **P_R**: the probability that the phototaxis controller turns right (else left) when the light reading got "
        "worse since its last decision (paper Sec. 4; the authors' controller).",
        f"- **cost**: a robot's mean distance to the light centre over the last {cfg.scenario.cost_window_steps} steps "
        f"({cfg.scenario.cost_window_steps * cfg.scenario.dt_s:g} s) of a {cfg.scenario.duration_s:g} s run, in metres; "
        "the tables give its mean over the Monte Carlo runs.",
        "- **heading bias**: on the paper's axis (+ = curves right); all biases below are on that axis.",
        "- **R_acc** (acceptable range at delta_acc = 0.75 m): the contiguous interval of biases around the best robot "
        "whose mean cost stays below 0.75 m.",
        f"- **N_acc**: the number of (run, robot) experiments, out of {cfg.runs * len(bias)}, whose cost is below 0.75 m.",
        "",
        "| P_R | mean cost at bias 0 (m) | best bias (paper axis) | its mean cost (m) | mean cost left / right-biased (m) "
        "| R_acc, paper axis | N_acc |",
        "|---|---|---|---|---|---|---|",
    ]
    for p in p_rights:
        s = summary[f"P_R={p}"]
        lines.append(f"| {p} | {s['cost_at_zero_bias_m']:.3f} | {s['best_bias']:+.3f} | {s['best_cost_m']:.3f} | "
                     f"{s['mean_cost_left_biased_m']:.3f} / {s['mean_cost_right_biased_m']:.3f} | "
                     f"[{s['R_acc'][0]:+.3f}, {s['R_acc'][1]:+.3f}] | {s['N_acc']} |")
    lines += ["", "![cost vs bias](phototaxis.png)", ""]
    (out / "summary.md").write_text("\n".join(lines))
    point_latest(out)  # only a finished run becomes `latest` (what `make view` opens)
    return {"summary": summary_doc, "plot": str(plot), "summary_path": str(out / "summary.md"), "twin": twin_res,
            "run_dir": str(out),
            "results": str(out / "results.npz"), "cost": cost, "bias": np.asarray(bias)}
