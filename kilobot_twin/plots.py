"""Drawing, separate from computing: every function here reads result arrays and writes a PNG.

Colours follow the paper: left-biased robots (negative bias) red, right-biased blue.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def pyplot():
    """matplotlib.pyplot on the Agg backend (files only, no display)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save(fig, path, dpi: int = 110, rect=None) -> Path:
    """Lay out (within ``rect`` of the figure, e.g. to keep room for a figure legend), write and close a figure."""
    fig.tight_layout(rect=rect)
    fig.savefig(path, dpi=dpi)
    pyplot().close(fig)
    return Path(path)


def bias_cmap():
    """The paper's red (left, negative) -> purple -> blue (right, positive) map."""
    from matplotlib.colors import LinearSegmentedColormap

    return LinearSegmentedColormap.from_list("bias", [(1.0, 0.0, 0.0), (0.5, 0.0, 0.5), (0.0, 0.35, 1.0)])


def cost_vs_bias(bias, cost, labels, path, delta_acc=0.75, title="Phototaxis cost vs heading bias",
                 xlabel="heading bias (+ = right)"):
    """Fig. 5 style: one panel per grid point; dots per (run, robot), black mean line.

    Parameters
    ----------
    bias : (N,) heading bias per robot (the scale is named by ``xlabel``)
    cost : (G, R, N) cost per grid point, run, robot (m)
    labels : list of G panel titles
    """
    plt = pyplot()
    G = cost.shape[0]
    fig, axes = plt.subplots(1, G, figsize=(4.2 * G + 1.0, 4.1), sharey=True, squeeze=False)
    order = np.argsort(bias)
    lim = np.max(np.abs(bias)) or 1.0
    for g, ax in enumerate(axes[0]):
        R = cost.shape[1]
        xs = np.tile(bias, R)
        sc = ax.scatter(xs, cost[g].reshape(-1), c=xs, cmap=bias_cmap(), vmin=-lim, vmax=lim, s=6, alpha=0.35, lw=0,
                        label="one run of one robot")
        ax.plot(bias[order], cost[g].mean(axis=0)[order], color="k", lw=2, label="mean over runs")
        ax.axhline(delta_acc, color="tab:green", lw=1.5, ls="--", label=f"delta_acc = {delta_acc} m")
        ax.set_title(labels[g])
        ax.locator_params(axis="x", nbins=5)
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("cost: mean distance to light (m)")
    axes[0][0].legend(loc="upper center", fontsize=7, framealpha=0.9)
    cb = fig.colorbar(sc, ax=axes[0].tolist(), shrink=0.85, pad=0.015)
    cb.solids.set_alpha(1)
    cb.set_label("dot colour: heading bias\n(red = left, blue = right)", fontsize=8)
    fig.supxlabel(xlabel, fontsize=10)
    fig.suptitle(title)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    pyplot().close(fig)
    return Path(path)
