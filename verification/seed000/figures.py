"""Fig. 7a-d for one train: the episode picked (the first recorded train whose window shows
a false positive or negative, as the paper's Fig. 7b does), everything the figure shows of
it (`episode_series`: states, actions, rewards, marks, R1/R2, the eq. 14 belief, alphas),
and the drawings, with the bars of time in each zone over the runs.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from monitor.core.types import R_LATCH
from monitor.offline import risk
from monitor.offline.models import model1

from ..fastcore import zone_alphas
from .world import PAPER_REWARDS, Run, STATE_NAMES, ZONE_NAMES


def _marks(run: Run, train: int, start: int, stop: int) -> int:
    """Number of FP and FN marks (as in Fig. 7b) of one recorded train in a window."""
    sl = slice(start, stop)
    braking = run.trace["demand"][sl, train] > 0
    held = (run.episode["reasons"][sl, train] & R_LATCH) != 0
    zone = run.episode["zone"][sl, train]
    moving = run.trace["speed_cms"][sl, train] > 0
    return int((braking & ~held & (zone <= 1) & moving).sum() + (~braking & (zone >= 2)).sum())


def pick_episode(run: Run, before_s: float = 5.0, length_s: float = 60.0) -> tuple[int, int, int]:
    """(train, first step, last step): a window of `length_s` starting `before_s` before the
    first obstacle of a recorded train; the first such train whose window shows a false
    positive or negative (as the paper's Fig. 7b does), else the first such train."""
    dt = run.scenario.dt
    pre, span = int(round(before_s / dt)), int(round(length_s / dt))
    cands = [i for i, s in enumerate(run.appear_step) if s >= pre]
    if not cands:
        return 0, 0, min(run.steps, span)
    full = [i for i in cands if run.appear_step[i] - pre + span <= run.steps] or cands
    windows = [(i, int(run.appear_step[i]) - pre, min(run.steps, int(run.appear_step[i]) - pre + span)) for i in full]
    marked = [w for w in windows if _marks(run, *w) > 0]
    return (marked or windows)[0]


def episode_series(run: Run, train: int, start: int, stop: int) -> dict:
    """Everything Fig. 7 shows for one train: states, observations, actions, rewards,
    FP/FN marks, R1/R2 from the observed distance, the eq. 14 belief, distances and alphas."""
    sc = run.scenario
    cfg = sc.config
    sl = slice(start, stop)
    tr = {k: v[sl, train] for k, v in run.trace.items()}
    ep = {k: v[sl, train] for k, v in run.episode.items()}
    t = np.arange(start, stop) * sc.dt
    a1, a2 = (a / 10.0 for a in zone_alphas(cfg, tr["speed_cms"], tr["speed_cms"], 0))
    obs_m = np.where(tr["present"], tr["distance_dm"] / 10.0, np.nan)
    r1 = np.zeros(len(t))
    r2 = np.zeros(len(t))
    for j in range(len(t)):
        if not tr["present"][j]:
            continue   # no obstacle reported: d -> infinity, R1 = R2 = 0
        if a1[j] > 0:
            r1[j] = risk.r1_logistic(obs_m[j], a1[j])
        else:
            r1[j] = 0.5 if obs_m[j] <= 0 else 0.0   # standstill: alpha1 = 0, the limit of eq. 16
        if a1[j] > a2[j]:
            r2[j] = risk.r2_linear(obs_m[j], a1[j], a2[j])
        else:
            r2[j] = 1.0 if obs_m[j] <= a2[j] else 0.0
    pomdp = model1.build(model1.Model1Params())
    b = pomdp.b0.copy()
    prev_a = 0
    belief = np.zeros((len(t), 4))
    for j in range(len(t)):   # eq. 14 with the demand actually applied in the previous cycle
        if j == 0 and start > 0:
            prev_a = int(run.trace["demand"][start - 1, train])
        b, _ = pomdp.belief_update(b, prev_a, int(tr["observation"][j]))
        belief[j] = b
        prev_a = int(tr["demand"][j])
    held = (ep["reasons"] & R_LATCH) != 0
    braking = tr["demand"] > 0
    fp = braking & ~held & (ep["zone"] <= 1) & (tr["speed_cms"] > 0)
    fn = ~braking & (ep["zone"] >= 2)
    model_R = model1.reward(model1.Model1Params())
    return dict(t=t, zone=ep["zone"], obs=tr["observation"], demand=tr["demand"], node=tr["node"],
                reward=np.array(PAPER_REWARDS)[ep["zone"]], reward_model=model_R[ep["zone"], tr["demand"]],
                fp=fp, fn=fn, r1=r1, r2=r2, belief=belief, obs_m=obs_m,
                true_m=np.where(ep["has"], ep["true_m"], np.nan), a1=a1, a2=a2, speed=ep["speed_mps"],
                reasons=ep["reasons"])


def draw_fig7(s: dict, out_dir: Path, prefix: str, paper_alphas: tuple[float, float]) -> list[str]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = s["t"]
    names = []

    def save(fig, suffix):
        name = f"{prefix}{suffix}.png"
        fig.tight_layout()
        fig.savefig(out_dir / name, dpi=110)
        plt.close(fig)
        names.append(name)

    fig, ax = plt.subplots(figsize=(8, 3.6))
    ax.step(t, s["zone"] + 1, where="post", color="tab:blue", lw=2, label="actual state (true distance)")
    ax.step(t, s["obs"] + 1, where="post", color="tab:red", lw=1, ls="--", label="perceived state (observation)")
    ax.set_yticks([1, 2, 3, 4], [f"s{i}" for i in range(1, 5)])
    ax.set_ylim(0.5, 4.5)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("state")
    ax2 = ax.twinx()
    ax2.step(t, s["demand"] + 1, where="post", color="tab:green", lw=1.2, alpha=0.8, label="action (brake demand)")
    ax2.set_yticks([1, 2, 3], ["a1 maintain", "a2 nominal", "a3 emergency"])
    ax2.set_ylim(0.5, 3.5)
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, loc="upper right", fontsize=8)
    ax.set_title("Fig. 7a: actual and perceived state, action")
    save(fig, "a")

    fig, ax = plt.subplots(figsize=(8, 3.6))
    ax.step(t, s["reward"], where="post", color="tab:blue", lw=1.5, label="reward eq. 13 (actual state)")
    ax.step(t, s["reward_model"], where="post", color="grey", lw=1, ls=":", label="model reward R(s, a)")
    ax.scatter(t[s["fp"]], s["reward"][s["fp"]], color="tab:green", s=18, zorder=3,
               label=f"false positive ({int(s['fp'].sum())})")
    ax.scatter(t[s["fn"]], s["reward"][s["fn"]], color="tab:red", s=18, zorder=3,
               label=f"false negative ({int(s['fn'].sum())})")
    ax.set_yscale("symlog", linthresh=10)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("reward per step")
    ax.legend(loc="lower right", fontsize=8)
    ax.set_title("Fig. 7b: rewards, false positives and false negatives")
    save(fig, "b")

    fig, ax = plt.subplots(figsize=(8, 3.6))
    ax.plot(t, s["r1"], color="magenta", lw=1.2, label="risk estimation 1 (eq. 16)")
    ax.plot(t, s["r2"], color="c", lw=1.2, label="risk estimation 2 (eq. 17)")
    ax.plot(t, s["belief"][:, 2] + s["belief"][:, 3], color="k", lw=1, ls="--",
            label="belief b(AboutToCrash) + b(Crash) (eq. 14)")
    ax.set_ylim(-0.05, 1.05)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("risk / probability")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title("Fig. 7c: risk estimates from the observed distance")
    save(fig, "c")

    fig, ax = plt.subplots(figsize=(8, 3.6))
    ax.plot(t, s["obs_m"], ".", color="tab:purple", ms=2.5, label="observed distance")
    ax.plot(t, s["true_m"], color="k", lw=0.8, alpha=0.6, label="true distance")
    ax.step(t, s["a1"], where="post", color="tab:red", ls="--", lw=1.2, label="alpha1(v) of the monitor")
    ax.step(t, s["a2"], where="post", color="tab:blue", ls="--", lw=1.2, label="alpha2(v) of the monitor")
    ax.axhline(paper_alphas[0], color="tab:red", ls=":", lw=0.8, label=f"paper alpha1 = {paper_alphas[0]:.0f} m")
    ax.axhline(paper_alphas[1], color="tab:blue", ls=":", lw=0.8, label=f"paper alpha2 = {paper_alphas[1]:.0f} m")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("distance (m)")
    ax.set_ylim(bottom=0)
    ax.legend(loc="upper right", fontsize=7, ncol=2)
    ax.set_title("Fig. 7d: observed distance with alpha1 and alpha2")
    save(fig, "d")
    return names


def draw_zone_bars(runs: list[Run], out_dir: Path, name: str) -> str:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 3.4))
    width = 0.8 / len(runs)
    x = np.arange(4)
    for i, r in enumerate(runs):
        frac = r.metrics["zone_true"] / max(1, r.metrics["zone_true"].sum())
        ax.bar(x + i * width, frac, width, label=r.scenario.key)
    ax.set_xticks(x + 0.4 - width / 2, [f"{z}\n({s})" for z, s in zip(ZONE_NAMES, STATE_NAMES)])
    ax.set_yscale("log")
    ax.set_ylabel("fraction of train-steps")
    ax.set_title("Time in each actual zone, all trains")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out_dir / name, dpi=110)
    plt.close(fig)
    return name
