"""Phototaxis vs heading bias and P_R: Figs. 4, 5 and 6.

100 robots with heading biases spread evenly over the paper's [-0.04, 0.04] axis, 100 Monte
Carlo runs that share the same 100 start poses across robots, P_R in {0.25, 0.5, 1.0}; cost =
mean distance to the light centre over the last 100 steps. Biases are stored both on the
paper's axis (``bias_axis``) and as the wheel imbalance the model applies (``bias``).
"""

from __future__ import annotations

import numpy as np

from ..analysis import acceptable_range, mean_cost_by_robot, n_acceptable
from ..batch import Campaign, run_campaign
from ..core import sim
from ..core.traits import SwarmTraits, draw_population
from .common import Check, Outcome, Settings, within

P_RIGHTS = (0.25, 0.5, 1.0)
DELTA_ACC = 0.75
# Fig. 5 mean cost read off the published figure (paper_targets.md), by paper-axis bias.
FIG5_TABLE = {
    -0.04: (1.05, 2.8, 2.95), -0.03: (0.08, 0.75, 3.0), -0.02: (0.09, 0.11, 3.05), -0.01: (0.15, 0.27, 2.9),
    0.00: (0.35, 0.42, 0.25), 0.01: (1.1, 0.27, 0.05), 0.02: (1.25, 0.11, 0.03), 0.03: (2.2, 0.75, 0.03),
    0.04: (2.9, 2.8, 0.35),
}
FIG5_R_ACC = {0.25: (-0.037, 0.006), 0.5: (-0.030, 0.030), 1.0: (-0.005, 0.040)}
FIG5_MEDIANS = {0.25: 0.47, 0.5: 0.0, 1.0: 0.29}


def run_phototaxis(s: Settings) -> Outcome:
    n, runs = (41, 20) if s.quick else (100, 100)
    axis = np.linspace(-0.04, 0.04, n)
    swarm = draw_population({"n": n, "heading_bias": {"dist": "list", "values": (axis * s.bias_scale).tolist()},
                             **s.noise_traits()}, seed=s.seed)
    sc = s.scenario(behavior={"kind": s.scenario().behavior.name})
    res = run_campaign(Campaign(sc, swarm, s.seed, runs, grid={"behavior.p_right": list(P_RIGHTS)}),
                       workers=s.workers, progress=s.progress, desc="phototaxis", scheduler=s.scheduler)
    cost = res["summary"]["cost_m"]  # (3, runs, robots)
    # Fig. 4: noiseless trajectories of a left-, zero- and right-biased robot, P_R = 1.
    ex_axis = np.array([-0.02, 0.0, 0.02])
    ex = SwarmTraits.uniform(3).with_values(heading_bias=ex_axis * s.bias_scale)
    sc1 = s.scenario(behavior={"kind": sc.behavior.name, "p_right": 1.0},
                     start={"kind": "uniform", "half_width_m": 1.0, "heading_rad": None, "shared": True})
    traj = sim.simulate(sc1, ex, s.seed, runs=[3], record_every=10)
    data = {"bias_axis": axis, "bias": swarm.heading_bias, "cost_m": cost, "p_right": np.array(P_RIGHTS),
            "example_bias_axis": ex_axis, "example_x": traj.traj["x"][0], "example_y": traj.traj["y"][0]}
    meta = {"robots": n, "runs": runs, "bias_axis_scale": s.bias_scale, "seed": s.seed,
            "scenario": sc.to_dict(), "elapsed_s": res["meta"]["elapsed_s"]}
    return Outcome("phototaxis", data, meta, phototaxis_checks(data))


def cost_at(axis, mean_cost, b, half_width=0.0025):
    """Mean cost of the robots within +-half_width of paper-axis bias b (smooths the mean line)."""
    sel = np.abs(axis - b) <= half_width + 1e-12
    return float(mean_cost[sel].mean())


def r_acc_curve(axis, cost, deltas):
    """R_acc width and N_acc for each threshold: arrays (len(deltas),)."""
    mc = cost.mean(axis=0)
    widths = np.array([acceptable_range(axis, mc, d)[2] for d in deltas])
    counts = np.array([n_acceptable(cost, d) for d in deltas])
    return widths, counts


def phototaxis_checks(d) -> list[Check]:
    axis, cost = d["bias_axis"], d["cost_m"]
    mc = mean_cost_by_robot(cost)  # (3, N)
    checks = []
    for b, targets in FIG5_TABLE.items():
        for g, p in enumerate(P_RIGHTS):
            ours = cost_at(axis, mc[g], b)
            checks.append(Check("5", f"mean cost at bias {b:+.2f}, P_R = {p}", f"{targets[g]:.2f} m", f"{ours:.2f} m",
                                within(ours, targets[g], 0.15, 0.30), "tolerance +-0.15 m or 30 %"))
    # P_R = 0.5: U-shape, two minima at non-zero |bias|, both >= 2x below the cost at 0.
    g = P_RIGHTS.index(0.5)
    c0 = cost_at(axis, mc[g], 0.0)
    left = axis < -0.005
    right = axis > 0.005
    bl = axis[left][np.argmin([cost_at(axis, mc[g], b) for b in axis[left]])]
    br = axis[right][np.argmin([cost_at(axis, mc[g], b) for b in axis[right]])]
    cl, cr = cost_at(axis, mc[g], bl), cost_at(axis, mc[g], br)
    checks.append(Check("5b", "P_R = 0.5: two minima near |bias| = 0.023, each >= 2x below the cost at bias 0",
                        "minima at +-0.023, ratio <= 0.5",
                        f"minima at {bl:+.3f} ({cl:.2f} m) and {br:+.3f} ({cr:.2f} m); cost at 0: {c0:.2f} m",
                        cl <= 0.5 * c0 and cr <= 0.5 * c0 and 0.012 <= abs(bl) <= 0.034 and 0.012 <= abs(br) <= 0.034))
    for p, side, name in ((1.0, 1, "right"), (0.25, -1, "left")):
        g = P_RIGHTS.index(p)
        fav = mc[g][side * axis > 0.005].mean()
        other = mc[g][side * axis < -0.005].mean()
        checks.append(Check("5", f"P_R = {p} favours {name}-biased robots", f"{name} side lower",
                            f"mean cost {name} {fav:.2f} m vs other side {other:.2f} m", fav < other))
    for p, (lo, hi) in FIG5_R_ACC.items():
        g = P_RIGHTS.index(p)
        a, b, _ = acceptable_range(axis, mc[g], DELTA_ACC)
        checks.append(Check("5", f"R_acc at delta_acc = 0.75 m, P_R = {p}", f"[{lo:+.3f}, {hi:+.3f}]",
                            f"[{a:+.3f}, {b:+.3f}]", abs(a - lo) <= 0.006 and abs(b - hi) <= 0.006,
                            "tolerance +-0.006 per end"))
    g = P_RIGHTS.index(1.0)
    neg = axis[(axis < 0) & (mc[g] > DELTA_ACC)]
    cliff = float(neg.max()) if neg.size else float("nan")
    checks.append(Check("5c", "P_R = 1.0: cliff between -0.009 and -0.005", "-0.009 .. -0.005",
                        f"last failing robot at {cliff:+.4f}", -0.011 <= cliff <= -0.003))
    for p, target in FIG5_MEDIANS.items():
        g = P_RIGHTS.index(p)
        med = float(np.median(cost[g]))
        # One tolerance for all three: the medians are read off the published violins (0-4 m axis,
        # one pixel ~ 0.02 m) to about +-0.05 m, plus the Monte Carlo error of our median (its
        # standard error over 10^4 samples is < 0.02 m) and the unknown part of the authors' set-up;
        # +-0.15 m is what the cost table uses too. 'About 0' therefore means <= 0.15 m.
        checks.append(Check("5d", f"ensemble median, P_R = {p}", f"~{target:.2f} m", f"{med:.2f} m",
                            abs(med - target) <= 0.15, "tolerance +-0.15 m"))
    tail = cost.max(axis=(1, 2))
    checks.append(Check("5d", "heavy upper tail up to ~3-3.9 m", "max 3-3.9 m",
                        ", ".join(f"{t:.1f}" for t in tail), bool(np.all((tail >= 2.7) & (tail <= 4.2)))))
    deltas = np.linspace(0, 4, 81)
    counts = np.array([r_acc_curve(axis, cost[g], deltas)[1] for g in range(3)])
    total = cost.shape[1] * cost.shape[2]
    checks.append(Check("6", "N_acc reaches all experiments at the largest threshold", f"{total}",
                        ", ".join(str(c[-1]) for c in counts), bool(np.all(counts[:, -1] == total))))
    small = deltas <= 1.0
    ranks = np.argsort(-counts[:, small], axis=0)
    changes = int((np.diff(ranks[0]) != 0).sum())
    checks.append(Check("6", "the ranking of the P_R settings changes as delta_acc shrinks below 1 m",
                        "ranking changes", f"{changes} change(s) of the leader for delta_acc in [0, 1]", changes >= 1))
    return checks


def plot_phototaxis(o: Outcome, out_dir):
    from ..plots import pyplot, bias_cmap, cost_vs_bias, save

    plt = pyplot()
    d = o.data
    axis, cost = d["bias_axis"], d["cost_m"]
    scale = o.meta["bias_axis_scale"]
    paths = [cost_vs_bias(axis, cost, [f"P_R = {p}" for p in d["p_right"]], out_dir / "fig5_phototaxis.png",
                          delta_acc=DELTA_ACC, title=f"(5) Phototaxis cost vs heading bias ({o.meta['robots']} robots x "
                          f"{o.meta['runs']} runs)",
                          xlabel=f"heading bias on the paper's axis (+ = right; wheel imbalance b = {scale:g} x axis)")]
    # Fig. 5d: ensemble distributions.
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    fig, ax = plt.subplots(figsize=(5.5, 4.2))
    parts = ax.violinplot([c.ravel() for c in cost], showextrema=False)
    for pc in parts["bodies"]:
        pc.set_facecolor("pink")
    ax.boxplot([c.ravel() for c in cost], widths=0.15, showfliers=False,
               medianprops={"color": "tab:orange", "lw": 2})
    ax.plot(range(1, 4), [c.mean() for c in cost], "g_", markersize=30, mew=2)
    ax.set_xticks(range(1, 4), [f"{p}" for p in d["p_right"]])
    ax.set_xlabel("P_R (probability of turning right)")
    ax.set_ylabel("cost: mean distance to light (m)")
    ax.set_title("(5d) all runs and robots pooled (individuality removed)", fontsize=10)
    ax.legend(handles=[Patch(facecolor="pink", label="distribution (violin)"),
                       Patch(facecolor="none", edgecolor="k", label="quartiles, whiskers 1.5 IQR"),
                       Line2D([], [], color="tab:orange", lw=2, label="median"),
                       Line2D([], [], color="g", lw=2, label="mean")], fontsize=7, loc="upper left")
    paths.append(save(fig, out_dir / "fig5d_ensemble.png"))
    # Fig. 6: R_acc and N_acc vs delta_acc.
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.4))
    total = cost.shape[1] * cost.shape[2]
    for rng_max, ax, name in zip((4.0, 1.0), axes, ("delta_acc from 0 to 4 m", "zoom: delta_acc from 0 to 1 m")):
        deltas = np.linspace(0, rng_max, 161)
        ax2 = ax.twinx()
        for g, p in enumerate(d["p_right"]):
            w, n = r_acc_curve(axis, cost[g], deltas)
            ax.plot(deltas, w, lw=2, label=f"P_R = {p}", color=f"C{g}")
            ax2.plot(deltas, 100.0 * n / total, lw=1.5, ls="--", color=f"C{g}")
        ax.axvline(DELTA_ACC, color="tab:green", lw=1, ls=":")
        ax.set_xlabel("threshold delta_acc (m)")
        ax.set_ylabel("R_acc: width of the acceptable range\n(paper's bias axis; solid)")
        ax2.set_ylabel(f"N_acc: acceptable experiments\n(% of {total}; dashed)")
        ax2.set_ylim(0, 105)
        ax.set_title(name)
        handles = [Line2D([], [], color=f"C{g}", lw=2, label=f"P_R = {p}") for g, p in enumerate(d["p_right"])]
        handles += [Line2D([], [], color="k", lw=2, label="R_acc"), Line2D([], [], color="k", lw=1.5, ls="--", label="N_acc"),
                    Line2D([], [], color="tab:green", lw=1, ls=":", label=f"delta_acc = {DELTA_ACC} m (Fig. 5)")]
        ax.legend(handles=handles, loc="lower right", fontsize=7)
    fig.suptitle("(6) acceptable range R_acc and number N_acc vs the threshold delta_acc")
    paths.append(save(fig, out_dir / "fig6_acceptance.png"))
    # Fig. 4: example trajectories.
    fig, axes = plt.subplots(1, 3, figsize=(12, 4.6), sharex=True, sharey=True)
    cmap = bias_cmap()
    for i, (ax, b) in enumerate(zip(axes, d["example_bias_axis"])):
        ax.plot(d["example_x"][i], d["example_y"][i], color=cmap(0.5 + 12 * b), lw=0.8, label="trajectory")
        ax.plot(d["example_x"][i, 0], d["example_y"][i, 0], "r+", ms=12, mew=2, ls="none", label="start")
        ax.plot(0, 0, "b*", ms=12, ls="none", label="light centre")
        ax.set_title(f"bias {b:+.2f} on the paper's axis (b = {scale * b:+.2f})", fontsize=10)
        ax.set_xlabel("x (m)")
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("y (m)")
    h, lab = axes[0].get_legend_handles_labels()
    fig.legend(h, lab, loc="lower center", ncol=3, fontsize=9)
    fig.suptitle("(4) noise-free trajectories, P_R = 1 (colour: heading bias, red = left, blue = right)")
    paths.append(save(fig, out_dir / "fig4_trajectories.png", rect=(0, 0.07, 1, 1)))
    return paths
