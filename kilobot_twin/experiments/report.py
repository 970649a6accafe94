"""`kilobot-twin reproduce`: run all eight experiments and write a report with a
'paper vs ours' table for every shape fact and number of paper_targets.md."""

from __future__ import annotations

import json
import time
from pathlib import Path

from . import EXPERIMENTS, Settings, run_experiment

# Where we differ from the paper and why we think so (shown under the table).
NOTES = {
    "paper": [
        "**Bias axis x10.** The published figures are reproduced when the paper's heading-bias axis is read as one "
        "tenth of the wheel imbalance b that the simulator applies (our `heading_bias`). Three figures agree "
        "independently: Fig. 1c's colour bar spans +-0.02 while its extreme circles have r ~ 0.125 m = 0.025 m / 0.2; "
        "Fig. 5 only takes its shape for scales 8-12 (best 10); Fig. 7's coverage loss needs omega_b tau ~ 1, i.e. "
        "b ~ 0.4 for the authors' walk. Where the factor enters the authors' pipeline we cannot tell.",
        "**Light cone and duration.** The cone reaches 0 at r = 2.83 m (0.7071 x 4 m) and runs last 2000 s, as in the "
        "authors' .argos files; with the 0.707 m cone unbiased robots starting outside it drive away (cost ~5 m), and "
        "with 200 s no robot can travel the ~3 m that the failing robots of Fig. 5 end at.",
        "**P_R = 0.25, right-biased robots** fail more often than in the paper (e.g. 1.6 m vs 1.1 m at +0.01). One "
        "candidate we have not modelled: the authors draw the turn direction from an 8-bit generator "
        "((rand_soft() + offset) % 256 < threshold) whose effective P_R varies per robot.",
        "**Real-robot figures** (1e-f, 2, 8, 9) are measurements; we simulate robots with individual traits drawn from "
        "populations we chose (documented in each experiment module) and check the shape facts, not the data.",
    ],
    "argos-code": [
        "**The shipped code, literally.** The paper's bias axis is taken as the wheel imbalance itself. The phototaxis "
        "curves then stay nearly flat and Figs. 1c and 7c are not reproduced: the published figures need b = 10 x axis "
        "(see the paper preset).",
    ],
}


def reproduce(out: str | Path, preset: str = "paper", quick: bool = False, seed: int = 2023,
              workers: int | None = None, progress: bool = True, scheduler: str | None = None) -> dict:
    from tqdm.auto import tqdm

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    settings = Settings(preset=preset, quick=quick, seed=seed, workers=workers, progress=progress, scheduler=scheduler)
    results = {}
    t_all = time.perf_counter()
    bar = tqdm(list(EXPERIMENTS), desc="reproduce", unit="experiment", disable=not progress)
    for name in bar:
        bar.set_postfix_str(name)
        t0 = time.perf_counter()
        o = run_experiment(name, settings, out)
        results[name] = {"outcome": o, "seconds": time.perf_counter() - t0}
    elapsed = time.perf_counter() - t_all
    doc = _write_report(out, results, settings, elapsed)
    return doc


def _write_report(out: Path, results: dict, s: Settings, elapsed: float) -> dict:
    rows = []
    lines = [
        f"# kilobot_twin vs the paper ({s.preset} preset{', quick' if s.quick else ''})",
        "",
        f"Seed {s.seed}; {elapsed:.0f} s on this machine. Regenerate with "
        f"`kilobot-twin reproduce --preset {s.preset}{' --quick' if s.quick else ''} --out {out}`.",
        "",
        "| experiment | reproduces | checks met | time (s) |",
        "|---|---|---|---|",
    ]
    for name, r in results.items():
        o = r["outcome"]
        met = sum(c.met for c in o.checks)
        lines.append(f"| {name} | {EXPERIMENTS[name][2]} | {met}/{len(o.checks)} | {r['seconds']:.1f} |")
    total = sum(len(r["outcome"].checks) for r in results.values())
    met_all = sum(c.met for r in results.values() for c in r["outcome"].checks)
    lines += ["", f"**{met_all} of {total} checks met.**", "", "## Paper vs ours", "",
              "| fig. | fact | paper | ours | met | note |", "|---|---|---|---|---|---|"]
    for name, r in results.items():
        for c in r["outcome"].checks:
            lines.append(f"| {c.figure} | {c.fact} | {c.paper} | {c.ours} | {'met' if c.met else '**not met**'} | {c.note} |")
            rows.append({"experiment": name, **c.__dict__, "met": bool(c.met)})
    lines += ["", "## Where we differ, and why we think so", ""]
    lines += [f"- {n}" for n in NOTES.get(s.preset, [])]
    lines += ["", "## Figures", ""]
    for name, r in results.items():
        for p in r["outcome"].plots:
            lines.append(f"### {name}: {Path(p).name}\n\n![{name}]({Path(p).name})\n")
    (out / "report.md").write_text("\n".join(lines))
    doc = {"preset": s.preset, "quick": s.quick, "seed": s.seed, "elapsed_s": elapsed, "met": met_all, "total": total,
           "checks": rows, "seconds": {k: v["seconds"] for k, v in results.items()}}
    (out / "report.json").write_text(json.dumps(doc, indent=2, default=str))
    return doc
