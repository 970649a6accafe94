"""The main job on embedded defaults: a phototaxis campaign over heading bias and P_R.

It writes ``results.npz`` (+ Parquet), ``phototaxis.png`` (the paper's Fig. 5 layout) and
``summary.json`` / ``summary.md`` with the headline numbers per P_R.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .analysis import phototaxis_summary
from .batch import run_campaign
from .config import config_from_dict
from .plots import cost_vs_bias

#: The demo's configuration (what ``config/demo_phototaxis.yaml`` also holds).
DEMO_CONFIG = {
    "scenario": {"preset": "paper", "behavior": {"kind": "phototaxis"}},
    "swarm": {"population": {"n": 41, "heading_bias": {"dist": "linspace", "low": -0.04, "high": 0.04}}},
    "seed": 2023,
    "runs": 100,
    "grid": {"behavior.p_right": [0.25, 0.5, 1.0]},
}


def run_demo(out: str | Path = "out/demo", quick: bool = False, workers: int | None = None,
             progress: bool = True) -> dict:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    doc = json.loads(json.dumps(DEMO_CONFIG))
    if quick:
        doc["runs"] = 20
    cfg = config_from_dict(doc, source="demo")
    result = run_campaign(cfg.campaign(), out=out / "results.npz", workers=workers, progress=progress,
                          parquet=True, desc="phototaxis demo")
    p_rights = cfg.grid["behavior.p_right"]
    bias = cfg.swarm.heading_bias
    cost = result["summary"]["cost_m"]
    summary = phototaxis_summary(bias, cost, p_rights)
    plot = cost_vs_bias(bias, cost, [f"P_R = {p}" for p in p_rights], out / "phototaxis.png",
                        title=f"Phototaxis: {len(bias)} robots x {cfg.runs} runs, seed {cfg.seed}")
    meta = result["meta"]
    summary_doc = {
        "seed": cfg.seed,
        "runs": cfg.runs,
        "robots": len(bias),
        "robot_steps_per_s": round(meta["robot_steps"] / meta["elapsed_s"]),
        "per_p_right": summary,
    }
    (out / "summary.json").write_text(json.dumps(summary_doc, indent=2))
    lines = [
        "# Phototaxis demo",
        "",
        f"{len(bias)} robots (heading bias {bias.min():+.3f} .. {bias.max():+.3f}) x {cfg.runs} Monte Carlo runs, "
        f"seed {cfg.seed}; {meta['elapsed_s']:.1f} s at {meta['robot_steps'] / meta['elapsed_s'] / 1e6:.1f} M robot-steps/s.",
        "",
        "| P_R | cost at bias 0 (m) | best bias | best cost (m) | mean cost left / right (m) | R_acc (0.75 m) | N_acc |",
        "|---|---|---|---|---|---|---|",
    ]
    for p in p_rights:
        s = summary[f"P_R={p}"]
        lines.append(f"| {p} | {s['cost_at_zero_bias_m']:.3f} | {s['best_bias']:+.3f} | {s['best_cost_m']:.3f} | "
                     f"{s['mean_cost_left_biased_m']:.3f} / {s['mean_cost_right_biased_m']:.3f} | "
                     f"[{s['R_acc'][0]:+.3f}, {s['R_acc'][1]:+.3f}] | {s['N_acc']} |")
    lines += ["", "![cost vs bias](phototaxis.png)", ""]
    (out / "summary.md").write_text("\n".join(lines))
    return {"summary": summary_doc, "plot": str(plot), "summary_path": str(out / "summary.md"),
            "results": str(out / "results.npz"), "cost": cost, "bias": np.asarray(bias)}
