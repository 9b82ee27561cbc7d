"""The campaign's figure: faults x scenarios, coloured by the share of runs that brake
without an obstacle (or brake falsely), single faults beside the fault in a pair.
"""
from __future__ import annotations

from pathlib import Path

from .catalogue import CATALOGUE, KINDS
from .scenarios import SCENARIOS


def heatmap(core: dict, path: Path, measure: str = "brake_without_obstacle") -> Path:
    """Faults x scenarios, coloured by the share of runs with `measure` (braking without an
    obstacle by default: where the fault reactions brake; false braking is in the tables)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    what = {"brake_without_obstacle": "braking without an obstacle", "false_braking": "false braking"}[measure]
    rows = [("none", "none")] + [(k, CATALOGUE[k].label) for k in KINDS]
    fig, axes = plt.subplots(1, 2, figsize=(15, 7.5), sharey=True)
    for ax, prefix, title in ((axes[0], "", "single faults"), (axes[1], "pair:", "the fault in a pair")):
        grid = np.full((len(rows), len(SCENARIOS)), np.nan)
        for i, (key, _) in enumerate(rows):
            k = key if (key == "none" or not prefix) else prefix + key
            for j, s in enumerate(SCENARIOS):
                c = core["cells"].get(f"{k}|{s.name}")
                if c and c["runs"]:
                    grid[i, j] = c[measure] / c["runs"]
        im = ax.imshow(grid, vmin=0, vmax=1, cmap="magma_r", aspect="auto")
        for i in range(grid.shape[0]):
            for j in range(grid.shape[1]):
                if not np.isnan(grid[i, j]):
                    ax.text(j, i, f"{100 * grid[i, j]:.0f}", ha="center", va="center", fontsize=7,
                            color="white" if grid[i, j] > 0.6 else "black")
        ax.set_xticks(range(len(SCENARIOS)), [s.name for s in SCENARIOS], rotation=40, ha="right", fontsize=8)
        ax.set_title(f"{what} (% of runs): {title}")
    axes[0].set_yticks(range(len(rows)), [label for _, label in rows], fontsize=8)
    fig.colorbar(im, ax=axes, shrink=0.7, label=f"runs with {what}")
    fig.suptitle(f"railguard fault campaign: {core['runs']:,} core-level runs, {core['unsafe']} unsafe, "
                 f"{core['crashes']} crashes")
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path
