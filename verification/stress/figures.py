"""The stress test's figure: speed and gap against time for the likeliest failures and the
undisturbed run, the blind windows shaded.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from monitor.core.config import Config

from .. import world_train
from .disturbances import Disturbance
from .encounters import ENCOUNTERS
from .loop import closed_loop


def plot(result: dict, cfg: Config, path: Path) -> Path:
    """Speed and gap against time for the likeliest failures and the undisturbed run, blind
    windows shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    enc = ENCOUNTERS[result["encounter"]["name"]]
    world = world_train.from_mapping(result["world_train"], "world")
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 6), sharex=True, constrained_layout=True)
    runs = [("undisturbed", Disturbance.none(), "tab:gray")]
    for key, label, color in (("most_likely_failure", "likeliest failure", "tab:red"),
                              ("most_likely_failure_after_release", "likeliest after a release", "tab:orange")):
        if result[key] is not None and (key == "most_likely_failure" or
                                        result[key]["disturbance"] != result["most_likely_failure"]["disturbance"]):
            runs.append((label, Disturbance.from_lists(result[key]["disturbance"]), color))
    for label, d, color in runs:
        rows = closed_loop(result["table"], enc, d, world, cfg, result["margin_m"], keep=True)["rows"]
        t = [r[0] / 1000.0 for r in rows]
        ax1.plot(t, [r[4] for r in rows], color=color, label=label)
        ax2.plot([x for x, r in zip(t, rows) if r[5] is not None], [r[5] for r in rows if r[5] is not None], color=color)
        appear = next((x for x, r in zip(t, rows) if r[5] is not None), None)
        if appear is not None and label != "undisturbed":
            for j in np.nonzero(d.blind)[0]:
                ax1.axvspan(appear + j * cfg.period_ms / 1000, appear + (j + 1) * cfg.period_ms / 1000, color=color,
                            alpha=0.15, lw=0)
    ax1.set_ylabel("speed (m/s)")
    ax2.set_ylabel("gap to the obstacle (m)")
    ax2.set_xlabel("time (s)")
    ax2.axhline(0.0, color="black", lw=0.8)
    ax1.legend(loc="upper right")
    ax1.set_title(f"stress {result['table']} {enc.name}: shaded = every channel blind")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
