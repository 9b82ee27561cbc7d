"""Issue 31 item 6 as a verification part: seed 000's Fig. 7c and seed 001's risk accuracy
from the live signal. The monitor runs as `railguard run` runs it (the shell, the in-process
bus, a candump recording); the figures are read back from the recorded MonitorRisk frames
with python-can and cantools, each log is also replayed (`railguard replay`'s path) to the
same values, and the world's truth comes from the world, not from the monitor.
"""
from __future__ import annotations

import math
import shutil
import time
from pathlib import Path

import numpy as np

from ..report import Check, Progress, Section, md_table
from ..seed001.metrics import PAPER
from ..seed001.world import load_setup
from .players import NOISE_M
from .measure import (
    ZONE_ABOUT_TO_CRASH, Episode, accuracy_figures, replay_agrees, scratch, seed000_episodes, seed000_figures,
    seed001_trains,
)

TITLE = "The papers' risk from the live signal: seed 000 Fig. 7c and seed 001's risk accuracy off the bus"
SIZES = {True: {"episodes": 4, "world_trains": 24, "played": 2},
         False: {"episodes": 40, "world_trains": 288, "played": 48}}
SEED = 31
KEPT_LOG = "live_risk_seed000.log"           # the plotted episode's recording, kept beside the report
FIGURE = "live_risk_fig7c.png"
R2_ABOUT = (0.3, 0.55)                       # the offline seed000 check's band for "about 0.5"
R1_LOW = 0.1


def section(out_dir: Path, quick: bool, progress: Progress) -> Section:
    out_dir = Path(out_dir)
    size = SIZES[quick]
    t0 = time.perf_counter()
    with scratch() as tmp:
        logs = Path(tmp)
        episodes, setup0 = seed000_episodes(size["episodes"], SEED, logs, progress)
        replay0 = [replay_agrees(setup0, e.log, e.signals) for e in episodes]
        shutil.copyfile(episodes[0].log, out_dir / KEPT_LOG)
        live = seed001_trains(size["world_trains"], size["played"], SEED, logs, progress)
    f0 = seed000_figures(episodes)
    acc = accuracy_figures(live)
    draw_fig7c(out_dir / FIGURE, episodes[0])
    setup1, params, _ = load_setup()
    p_exact = 100.0 * float(np.prod([1 - e for e in params.misperception]))
    elapsed = time.perf_counter() - t0

    ok0 = all(ok for ok, _ in replay0)
    checks = [
        Check("live risk: every recorded MonitorRisk replays to the same values (railguard replay's path)",
              ok0 and live.replay_equal,
              f"{sum(n for _, n in replay0):,} seed-000 cycles and {live.replayed:,} seed-001 cycles: R1, R2, score, "
              "category, table risk and demand equal",
              {"seed000_cycles": sum(n for _, n in replay0), "seed001_cycles": live.replayed}),
        Check("live risk: seed 000 Fig. 7c from the bus (R2 about 0.5 at the obstacle's first report, R1 low)",
              R2_ABOUT[0] <= f0["r2_first_mean"] <= R2_ABOUT[1] and f0["r1_first_max"] < R1_LOW
              and f0["seen"] == f0["episodes"],
              f"R2 mean {f0['r2_first_mean']:.3f} ({f0['r2_first_min']:.3f}..{f0['r2_first_max']:.3f}), R1 max "
              f"{f0['r1_first_max']:.3f}, in {f0['seen']} of {f0['episodes']} episodes",
              {k: f0[k] for k in ("r2_first_mean", "r1_first_max", "seen", "episodes")}),
        Check("live risk: seed 000 episodes on the bus end without a collision", f0["collisions"] == 0,
              f"{f0['collisions']} collisions in {f0['episodes']} episodes ({f0['cycles']:,} cycles)"),
        Check("live risk: seed 001's recorded world is what the bus monitor decided (BrakeDemand = the world's demand)",
              live.demand_equal == live.cycles,
              f"{live.demand_equal:,} of {live.cycles:,} cycles of {live.trains} trains"),
        Check("live risk: RiskCategory on the bus = the monitor's picture category of the world run, obstacle cycles",
              live.category_equal_picture == live.obstacle_cycles,
              f"{live.category_equal_picture:,} of {live.obstacle_cycles:,}"),
        Check("live risk: seed 001 accuracy on obstacle cycles >= P(eq. 9 perceives every component right) - 4 SE",
              acc["accuracy_obstacle"] >= p_exact - 4 * acc["accuracy_obstacle_se"],
              f"{acc['accuracy_obstacle']:.2f} % >= {p_exact:.2f} % - 4 x {acc['accuracy_obstacle_se']:.2f}",
              {"accuracy_obstacle": acc["accuracy_obstacle"], "p_exact": p_exact}),
    ]
    md = markdown(f0, acc, live, p_exact, quick, elapsed)
    headline = {"live_r2_first_mean": round(f0["r2_first_mean"], 4), "live_risk_accuracy": round(acc["accuracy_all"], 2)}
    return Section(TITLE, md, checks, [FIGURE], headline=headline)


def markdown(f0: dict, acc: dict, live, p_exact: float, quick: bool, elapsed: float) -> str:
    rows = [
        ["seed 000 Fig. 7c: R2 at the obstacle's first report (AboutToCrash)", "rises to about 0.5",
         f"{f0['r2_first_mean']:.3f} ({f0['r2_first_min']:.3f}..{f0['r2_first_max']:.3f})",
         f"{f0['r2_true_first_mean']:.3f}"],
        ["seed 000 Fig. 7c: R1 at that report", "low", f"max {f0['r1_first_max']:.3f}", f"max {f0['r1_true_first_max']:.3f}"],
        ["seed 000: R2 over all AboutToCrash cycles", "-",
         f"{f0['r2_about_to_crash_mean']:.3f} ({f0['about_to_crash_cycles']:,} cycles)", "-"],
        ["seed 000: R1 outside Crash", "low", f"max {f0['r1_outside_crash_max']:.3f}", "-"],
        ["seed 001: risk-assessment accuracy, all steps", f"{PAPER['accuracy']:.1f} % (of the belief)",
         f"{acc['accuracy_all']:.2f} ± {acc['accuracy_all_se']:.2f} % (of the monitor's picture)",
         f"{acc['picture_accuracy_all']:.2f} % (the twin's picture, same steps)"],
        ["seed 001: accuracy on steps with an obstacle", "-",
         f"{acc['accuracy_obstacle']:.2f} ± {acc['accuracy_obstacle_se']:.2f} %",
         f"eq. 9 perceives all five components right: {p_exact:.2f} %"],
    ]
    return (
        f"The monitor ran as `railguard run` runs it: the shell's receive path and core on python-can's in-process bus, "
        f"every frame recorded to a candump log. The figures below are read back from the logs' **MonitorRisk** and "
        f"**BrakeDemand** frames with python-can's `LogReader` and cantools with `railguard.dbc`, not from the core's "
        f"variables; every log was also replayed through `railguard replay`'s path to the same values. The worlds' truth "
        f"comes from the worlds.\n\n"
        f"- **Seed 000** ({f0['episodes']} episodes, {f0['cycles']:,} cycles, table m1): Table 1's train at 40 m/s "
        f"(braking 1 and 3 m/s^2), a static obstacle appearing uniformly in [(alpha1 + alpha2) / 2, + 50 m] of the "
        f"monitor's zones, {NOISE_M:g} m Gaussian noise on each of the six channels (the paper's one sensor with 10 m of noise, "
        f"copied to six channels with that noise each, would keep the 2oo2 voters in dispute: 10 m tolerance), played by "
        f"the scenario player: the world "
        f"answers the demands the monitor sends. AboutToCrash is the true distance between alpha2 and alpha1 (the "
        f"monitor's EBI and its service curve's EBI at the true speed).\n"
        f"- **Seed 001** ({live.trains} of {SIZES[quick]['world_trains']} trains of the seed-001 world, "
        f"{live.cycles:,} cycles, table m2): each train's sensor and train frames, eq. 9's misperceptions included, "
        f"sent period by period to the monitor on the bus. The world ran with the vectorised twin braking it; the "
        f"monitor on the bus demanded the same on {live.demand_equal:,} of {live.cycles:,} cycles, so the recorded "
        f"truth is the truth of this run. A step with no obstacle counts as right when the bus says 'low' (eq. 11 "
        f"of a free line).\n\n"
        + md_table(["quantity", "paper", "from the bus", "offline, same runs"], rows)
        + f"\nThe paper's 96.3 % is the accuracy of its belief (the MAP state of a Bayes filter); the monitor sends the "
        f"category of its voted picture, which the fixed table does not refine. That accuracy is at least the share of "
        f"steps on which eq. 9 perceives all five components right ({p_exact:.1f} %), and higher because a misperceived "
        f"component often leaves the category unchanged. The seed 001 section reports the belief's accuracy offline.\n\n"
        f"![Fig. 7c from the bus]({FIGURE})\n\n"
        f"The plotted episode's recording is kept as `{KEPT_LOG}`: `railguard replay {KEPT_LOG} --table m1` shows the "
        f"same risk, and `cantools plot railguard.dbc` of it draws the MonitorRisk signals. ({elapsed:.0f} s)\n"
    )


def draw_fig7c(path: Path, e: Episode) -> Path:
    """Fig. 7c from the bus: R1 and R2 as the MonitorRisk frames carried them, eq. 17 on the
    true distance for comparison, the true AboutToCrash cycles shaded."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sig, tr = e.signals, e.truth
    t = sig["tick"] / 1000.0
    fig, ax = plt.subplots(figsize=(9, 3.8))
    atc = tr["zone"] == ZONE_ABOUT_TO_CRASH
    ax.fill_between(t, 0, 1.02, where=atc, step="post", color="orange", alpha=0.18, label="true state AboutToCrash")
    ax.fill_between(t, 0, 1.02, where=tr["zone"] == 3, step="post", color="red", alpha=0.12, label="true state Crash")
    ax.step(t, sig["r2_pct"] / 100, where="post", color="tab:red", lw=1.6, label="R2 (eq. 17), MonitorRisk on the bus")
    ax.step(t, sig["r1_pct"] / 100, where="post", color="tab:blue", lw=1.6, label="R1 (eq. 16), MonitorRisk on the bus")
    with np.errstate(invalid="ignore", divide="ignore"):
        r2_true = np.clip((tr["alpha1_m"] - tr["distance_m"]) / (tr["alpha1_m"] - tr["alpha2_m"]), 0, 1)
    ax.plot(t, r2_true, color="black", ls=":", lw=1.0, label="eq. 17 on the true distance")
    ax.axhline(0.5, color="gray", ls="--", lw=0.8)
    lo = max(0.0, t[e.first] - 2.0) if e.first >= 0 else t[0]
    stop = np.flatnonzero((np.nan_to_num(tr["speed_mps"], nan=1.0) == 0.0) & (np.arange(t.size) > max(e.first, 0)))
    hi = min(t[-1], (t[stop[0]] + 2.0) if stop.size else t[-1])
    ax.set_xlim(lo, hi)
    ax.text(hi, 0.52, "paper: R2 about 0.5 in AboutToCrash ", fontsize=8, color="gray", ha="right")
    ax.set_ylim(0, 1.05)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("risk")
    ax.set_title(f"Fig. 7c from the live signal: {e.name} (outcome: {e.outcome})")
    ax.legend(loc="upper left", fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


__all__ = ["TITLE", "section", "draw_fig7c"]
