"""The seed 001 figures: the three metrics and the mean reward, paper against ours
(`figure_metrics`), and one simulated episode with true and estimated risk, brake demand
and speed (`figure_episode`).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .metrics import PAPER
from .world import Run


def figure_metrics(path: Path, main: Run, table: Run) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    m, t = main.metrics, table.metrics
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2), gridspec_kw={"width_ratios": [3, 2]})
    labels = ["time with\nobstacles", "risk accuracy\n(belief)", "risk accuracy\n(monitor's picture)"]
    paper = [PAPER["obstacles"], PAPER["accuracy"], np.nan]
    ours = [m["obstacles"], m["accuracy_belief"], m["accuracy_picture"]]
    alone = [t["obstacles"], t["accuracy_belief"], t["accuracy_picture"]]
    x = np.arange(3)
    for off, vals, name, col in ((-0.27, paper, "paper (seed 001)", "#888888"), (0.0, ours, "ours: monitor", "#1f77b4"),
                                 (0.27, alone, "ours: table alone", "#ff7f0e")):
        bars = ax1.bar(x + off, vals, 0.26, label=name, color=col)
        for b_, v_ in zip(bars, vals):
            if np.isfinite(v_):
                ax1.text(b_.get_x() + b_.get_width() / 2, v_ + 0.5, f"{v_:.1f}", ha="center", va="bottom", fontsize=8)
    ax1.set_xticks(x, labels)
    ax1.set_ylim(50, 105)
    ax1.set_ylabel("per cent of steps")
    ax1.legend(loc="lower left", fontsize=8)
    ax1.set_title("Seed 001 metrics: paper vs ours")
    labels2 = ["eq. 10 as printed", "corrected (solved with)"]
    x2 = np.arange(2)
    for off, vals, col in ((-0.27, [PAPER["reward"], np.nan], "#888888"), (0.0, [m["reward_paper"], m["reward_corrected"]], "#1f77b4"),
                           (0.27, [t["reward_paper"], t["reward_corrected"]], "#ff7f0e")):
        bars = ax2.bar(x2 + off, vals, 0.26, color=col)
        for b_, v_ in zip(bars, vals):
            if np.isfinite(v_):
                ax2.text(b_.get_x() + b_.get_width() / 2, v_ - 0.05, f"{v_:.2f}", ha="center", va="top", fontsize=8)
    ax2.set_xticks(x2, labels2)
    ax2.axhline(0, color="black", lw=0.6)
    ax2.set_ylim(min(-4.5, 1.15 * min(PAPER["reward"], m["reward_paper"], t["reward_paper"], m["reward_corrected"])), 0.3)
    ax2.set_ylabel("mean reward per step")
    ax2.set_title("Mean reward (eq. 10)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def sample_column(run: Run) -> int:
    """The recorded train shown in the episode figure: the one with most high-risk steps."""
    high = (run.sample["true_risk"] >= 3).sum(axis=0)
    return int(np.argmax(high))


def figure_episode(path: Path, run: Run) -> int:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    c = sample_column(run)
    sm = run.sample
    tt = np.arange(run.settings.steps) * 0.1
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(11, 5.5), sharex=True)
    ax1.step(tt, sm["true_risk"][:, c], where="post", color="red", lw=1.4, label="true risk (eq. 11 of the state)")
    ax1.step(tt, sm["belief_risk"][:, c], where="post", color="blue", ls="--", lw=1.0, label="risk of the belief (MAP state)")
    ax1.step(tt, sm["picture_risk"][:, c], where="post", color="green", ls=":", lw=0.8, label="risk of the monitor's picture")
    ax1.set_yticks(range(5), ["none", "low", "moderate", "high", "critical"])
    ax1.set_ylabel("risk category")
    ax1.legend(loc="upper right", fontsize=8)
    ax1.set_title(f"One simulated episode (train {int(run.columns[c])}): risk, braking demand and speed")
    ax2.step(tt, sm["demand"][:, c], where="post", color="darkgreen", lw=1.2, label="brake demand (0 none, 1 service, 2 emergency)")
    ax2.set_ylabel("demand")
    ax2.set_yticks([0, 1, 2])
    ax3 = ax2.twinx()
    ax3.plot(tt, sm["speed_mps"][:, c], color="gray", lw=1.0, label="train speed (m/s)")
    ax3.set_ylabel("speed (m/s)")
    ax2.set_xlabel("time (s)")
    h1, l1 = ax2.get_legend_handles_labels()
    h2, l2 = ax3.get_legend_handles_labels()
    ax2.legend(h1 + h2, l1 + l2, loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return c
