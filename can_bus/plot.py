"""One figure of a run: speed, distance, demand and mode over time (PNG)."""
from __future__ import annotations

from pathlib import Path

from monitor.core.types import DEMAND_NAMES, MODE_NAMES


def plot_run(path: str | Path, title: str, t_s, speed_mps, distance_m, voted_m, demand, mode) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(4, 1, figsize=(10, 8), sharex=True, constrained_layout=True)
    axes[0].plot(t_s, speed_mps, color="tab:blue")
    axes[0].set_ylabel("speed (m/s)")
    if distance_m is not None:
        axes[1].plot(t_s, [float("nan") if d is None else d for d in distance_m], label="true distance", color="tab:gray")
    axes[1].plot(t_s, [float("nan") if d is None else d for d in voted_m], ".", ms=2, label="voted distance", color="tab:orange")
    axes[1].set_ylabel("distance (m)")
    axes[1].legend(loc="upper right", fontsize=8)
    axes[2].step(t_s, demand, where="post", color="tab:red")
    axes[2].set_yticks(range(3), DEMAND_NAMES)
    axes[2].set_ylabel("demand")
    axes[3].step(t_s, mode, where="post", color="tab:green")
    axes[3].set_yticks(range(4), MODE_NAMES)
    axes[3].set_ylabel("mode")
    axes[3].set_xlabel("time (s)")
    fig.suptitle(title)
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)
    plt.close(fig)
    return out
