"""The hazard figures: P[FN] over (p_n, p_c) as a surface and a heat map (seed 002 Fig. 6a),
HR(3oo3) over the grid with the 1e-7 and 1e-9 /h levels, and the diagonal against the
targets and the SNCF estimate (Fig. 6b).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .numbers import LAMBDA_OD, PAPER_HR, PAPER_P, THR_CATASTROPHIC, THR_SIL3
from .sncf import sncf
from .solve import hazard_rate


def draw_figures(out_dir: Path, pn: list, pc: list, Z: np.ndarray, pfn_paper: float) -> list[str]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib import colors

    X, Y = np.meshgrid([float(v) for v in pn], [float(v) for v in pc])
    HR = hazard_rate(Z)

    fig = plt.figure(figsize=(12, 5))
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    ax.plot_surface(X, Y, Z, cmap="viridis", edgecolor="none", alpha=0.9)
    ax.scatter([PAPER_P], [PAPER_P], [pfn_paper], color="red", s=60, depthshade=False, zorder=10)
    ax.set_xlabel("p_n")
    ax.set_ylabel("p_c")
    ax.set_zlabel("P[FN]")
    ax.set_title("P[FN](p_n, p_c) of one 2oo2 module")
    ax2 = fig.add_subplot(1, 2, 2)
    pcm = ax2.pcolormesh(X, Y, Z, shading="auto", cmap="viridis")
    fig.colorbar(pcm, ax=ax2, label="P[FN]")
    levels = [0.0005, 0.001, 0.0016, 0.0025, 0.005, 0.0075]
    cs = ax2.contour(X, Y, Z, levels=levels, colors="white", linewidths=0.8)
    ax2.clabel(cs, fmt="%.4g", fontsize=7)
    ax2.plot([PAPER_P], [PAPER_P], "r*", ms=12, label=f"paper point: P[FN] = {pfn_paper:.4g}")
    ax2.set_xlabel("p_n (NN perceptor)")
    ax2.set_ylabel("p_c (conventional perceptor)")
    ax2.set_title("P[FN] heat map with contours (seed 002 Fig. 6a)")
    ax2.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(out_dir / "hazard_pfn.png", dpi=110)
    plt.close(fig)

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 5))
    lo = 10 ** math.floor(math.log10(HR.min()))
    hi = 10 ** math.ceil(math.log10(max(HR.max(), THR_SIL3)))
    pcm = a1.pcolormesh(X, Y, HR, shading="auto", cmap="magma", norm=colors.LogNorm(vmin=lo, vmax=hi))
    fig.colorbar(pcm, ax=a1, label="HR(3oo3) per hour (log)")
    cs = a1.contour(X, Y, HR, levels=[THR_CATASTROPHIC, 1e-8, THR_SIL3], colors=["cyan", "white", "lime"],
                    linewidths=1.5)
    a1.clabel(cs, fmt={THR_CATASTROPHIC: "1e-9", 1e-8: "1e-8", THR_SIL3: "1e-7"}, fontsize=8)
    a1.plot([PAPER_P], [PAPER_P], "r*", ms=12)
    if HR.max() < THR_SIL3:
        a1.text(0.98, 0.02, f"1e-7 /h not reached (max {HR.max():.2g})", transform=a1.transAxes,
                ha="right", va="bottom", color="white", fontsize=8)
    a1.set_xlabel("p_n")
    a1.set_ylabel("p_c")
    a1.set_title("HR(3oo3) = lambda_od P[FN]^3 (seed 002 Fig. 6b)")
    diag = np.array([Z[i, i] for i in range(min(Z.shape))])
    pd_ = np.array([float(v) for v in pn[:len(diag)]])
    a2.semilogy(pd_, hazard_rate(diag), "k-", label="HR(3oo3), p_n = p_c")
    a2.semilogy(pd_, LAMBDA_OD * diag, "k--", label="one module alone: lambda_od P[FN]")
    a2.axhline(THR_SIL3, color="green", label="1e-7 /h (SIL 3, THR_OD)")
    a2.axhline(THR_CATASTROPHIC, color="blue", label="1e-9 /h (CSM-DT catastrophic)")
    s = sncf()
    a2.axhspan(*s["ci_hour_normal"], color="orange", alpha=0.3,
               label=f"SNCF ESR rate 95 % CI (seed 004), mean {s['rate']:.2g}")
    a2.plot([PAPER_P], [PAPER_HR], "r*", ms=12, label="paper: 3.413e-10 /h")
    a2.set_xlabel("p_n = p_c")
    a2.set_ylabel("hazard rate per hour")
    a2.set_title("Diagonal slice with the targets")
    a2.legend(fontsize=7, loc="lower right")
    a2.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(out_dir / "hazard_hr.png", dpi=110)
    plt.close(fig)
    return ["hazard_pfn.png", "hazard_hr.png"]
