"""The plotting room every shell draws runs with (can_bus's `railguard run`, fmu's co-simulation,
the CLI's replay). One figure of a run (PNG): speed, distance, demand and mode over time (with the
remembered obstacle, DESIGN.md section 14: its predicted distance dashed, the cycles it was held
while no channel showed it shaded), and beside them
the speed-distance diagram ETCS users know: the braking curves EBD, EBI, SBI and warning
for the run's obstacle (monitor.core.braking) with the train's trajectory through them,
coloured by the demand it was under."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from monitor.core.config import Config
from monitor.core.risk import CATEGORY_NAMES
from monitor.core.types import (
    DEMAND_NAMES, MODE_NAMES, TRACK_CONFIRMING, TRACK_FORGOTTEN, TRACK_HELD, TRACK_PASSED,
)

CURVE_STYLE = (("ebd_dm", "EBD", "black", "-"), ("ebi_dm", "EBI", "tab:red", "-"),
               ("sbi_dm", "SBI", "tab:orange", "--"), ("warning_dm", "warning", "goldenrod", ":"))
# trajectory colour by what the monitor asked for: none, warning, service, emergency
STATE_STYLE = (("no demand", "tab:blue"), ("warning", "goldenrod"), ("service", "tab:orange"), ("emergency", "tab:red"))
TRACK_COLOR = "tab:purple"
HELD_LABEL = "track held, no channel shows it"
# a track dropped in this cycle: marker and legend text
TRACK_ENDS = ((TRACK_FORGOTTEN, "X", "track forgotten (evidence)"), (TRACK_PASSED, "^", "track passed"))


@dataclass
class SpeedDistance:
    """What the speed-distance diagram needs from a run. `distance_m` is the true distance
    to the obstacle per sample (None: the run has no obstacle; the trajectory is then drawn
    against `position_m`, without curves)."""

    config: Config
    distance_m: list | None
    position_m: list
    speed_mps: list
    demand: list
    warning: list
    obstacle_speed_mps: float = 0.0       # along the track; negative: oncoming
    track: int = 0                        # conditions the train reported (the curves use them)
    brake: int = 0
    visible_m: float | None = None        # where the sensors first see the obstacle


def curve_points(cfg: Config, v_max_mps: float, obstacle_speed_mps: float = 0.0, track: int = 0, brake: int = 0,
                 step_mps: float = 0.25) -> tuple[list, dict]:
    """(speeds m/s, {"EBD" | "EBI" | "SBI" | "warning": distances m}) of the monitor's curves for an obstacle
    moving at `obstacle_speed_mps` (closing speed = train speed - obstacle speed)."""
    from monitor.core.braking import curves

    speeds = [i * step_mps for i in range(int(v_max_mps / step_mps) + 2)]
    out = {label: [] for _, label, *_ in CURVE_STYLE}
    for v in speeds:
        v_cms = round(v * 100)
        c = curves(cfg, v_cms, track, brake, v_cms - round(obstacle_speed_mps * 100), 0)
        for field, label, *_ in CURVE_STYLE:
            out[label].append(getattr(c, field) / 10)
    return speeds, out


def _state(demand: int, warning: bool) -> int:
    return 1 + demand if demand else int(bool(warning))


def draw_speed_distance(ax, sd: SpeedDistance) -> None:
    """The diagram on a matplotlib axis: distance to the obstacle falls to the right (the
    obstacle at 0), as a driver approaches it."""
    x = sd.distance_m if sd.distance_m is not None else sd.position_m
    states = [_state(d, w) for d, w in zip(sd.demand, sd.warning)]
    v_top = max(sd.speed_mps, default=0.0)
    if sd.distance_m is not None:
        speeds, pts = curve_points(sd.config, max(v_top * 1.15, 5.0), sd.obstacle_speed_mps, sd.track, sd.brake)
        for _, label, color, style in CURVE_STYLE:
            ax.plot(pts[label], speeds, style, color=color, lw=1.6, label=label)
        reach = max(pts["warning"][-1], sd.visible_m or 0.0) * 1.25
        ax.axvline(0.0, color="black", lw=3)
        ax.annotate("obstacle", (0.0, 0.5), xycoords=("data", "axes fraction"), xytext=(-4, 0),
                    textcoords="offset points", rotation=90, ha="right", va="center", fontsize=8)
        if sd.visible_m is not None:
            ax.axvline(sd.visible_m, color="gray", ls="-.", lw=1)
            ax.annotate("first visible", (sd.visible_m, 0.5), xycoords=("data", "axes fraction"), xytext=(-3, 0),
                        textcoords="offset points", rotation=90, ha="right", va="center", fontsize=8, color="gray")
        ax.set_xlim(reach, min(-0.03 * reach, -5.0))
        ax.set_xlabel("distance to the obstacle (m)")
        note = []
        if sd.obstacle_speed_mps < 0:
            note.append(f"oncoming at {-sd.obstacle_speed_mps:g} m/s")
        if sd.track or sd.brake:
            note.append("reported: " + " + ".join(n for n, on in (("slippery", sd.track), ("degraded", sd.brake)) if on))
        if note:
            ax.set_title("curves for an obstacle " + "; ".join(note), fontsize=9)
    else:
        ax.set_xlabel("position (m); no obstacle: no curves")
    # the trajectory, one segment per run of the same state
    start = 0
    drawn = set()
    for i in range(1, len(x) + 1):
        if i == len(x) or states[i] != states[start]:
            label, color = STATE_STYLE[states[start]]
            seg = slice(start, min(i + 1, len(x)))
            ax.plot(x[seg], sd.speed_mps[seg], color=color, lw=3.2, alpha=0.75,
                    label=None if label in drawn else f"train: {label}")
            drawn.add(label)
            start = i
    ax.set_ylim(0, max(v_top * 1.18, 1.0))
    ax.set_ylabel("speed (m/s)")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower left", fontsize=8)


def held_spans(t_s, track_state) -> list:
    """(start, end) times of the runs of cycles whose track was held or confirming (remembered
    while no channel showed it); a run ends where the next cycle begins."""
    spans, start = [], None
    n = len(t_s)
    for i in range(n + 1):
        held = i < n and track_state[i] in (TRACK_HELD, TRACK_CONFIRMING)
        if held and start is None:
            start = i
        elif not held and start is not None:
            end = t_s[i] if i < n else t_s[-1] + (t_s[-1] - t_s[-2] if n > 1 else 0.1)
            spans.append((t_s[start], end))
            start = None
    return spans


def draw_track(ax, t_s, track_m, track_state, label: bool = True) -> None:
    """The remembered obstacle on a time axis: its predicted distance (dashed steps, if
    `track_m` is given) and, if `track_state` is, the cycles it was held unseen (shaded) and
    where it was dropped (markers)."""
    if track_m is not None:
        ax.step(t_s, [float("nan") if d is None else d for d in track_m], where="post", ls="--", lw=1.2,
                color=TRACK_COLOR, label="remembered distance (predicted)" if label else None)
    if track_state is None:
        return
    for k, (start, end) in enumerate(held_spans(t_s, track_state)):
        ax.axvspan(start, end, color=TRACK_COLOR, alpha=0.12, lw=0, label=HELD_LABEL if label and k == 0 else None)
    if track_m is None:
        return
    for state, marker, text in TRACK_ENDS:
        at = [i for i, s in enumerate(track_state) if s == state]
        if at:
            # dropped: no distance this cycle, so the marker sits where the track was the cycle before
            ys = [next((track_m[j] for j in range(i - 1, -1, -1) if track_m[j] is not None), 0.0) for i in at]
            ax.plot([t_s[i] for i in at], ys, marker, color=TRACK_COLOR, ms=7, label=text if label else None)


CATEGORY_COLORS = {2: "gold", 3: "tab:orange", 4: "tab:red"}     # seed 001's moderate, high, critical


LOG_FLOOR = 1e-7       # 0.1 ppm: the bottom of the risk panel's logarithmic axis


def draw_risk(ax, t_s, risk: dict) -> None:
    """The risk panel, drawn like seed 000's Fig. 7c: each estimator as a probability over
    time; the seed 001 category shades the background (none while low); the series under
    "log" (the table's risk, parts per million) on a logarithmic right axis, where a linear
    one would show them as zero."""
    series = {k: v for k, v in risk.items() if k not in ("category", "log")}
    for (label, values), color in zip(series.items(), ("tab:purple", "tab:brown")):
        ax.step(t_s, values, where="post", color=color, lw=1.2, label=label)
    handles = []
    if risk.get("log"):
        right = ax.twinx()
        right.set_yscale("log")
        for label, values in risk["log"].items():
            handles += right.step(t_s, [max(v, LOG_FLOOR) for v in values], where="post", color="black", lw=1.0,
                                  label=f"{label} (right, log)")
        right.set_ylim(LOG_FLOOR, 1.5)
        right.set_ylabel("table risk")
    category = risk.get("category")
    if category:
        shown = set()
        start = 0
        for i in range(1, len(category) + 1):
            if i == len(category) or category[i] != category[start]:
                c = category[start]
                if c in CATEGORY_COLORS:
                    end = t_s[i] if i < len(t_s) else t_s[-1]
                    ax.axvspan(t_s[start], end, color=CATEGORY_COLORS[c], alpha=0.15, lw=0,
                               label=None if c in shown else f"rho {CATEGORY_NAMES[c - 1]}")
                    shown.add(c)
                start = i
    ax.set_ylim(-0.02, 1.02)
    ax.set_ylabel("risk")
    left, labels = ax.get_legend_handles_labels()
    ax.legend(left + handles, labels + [h.get_label() for h in handles], loc="upper left", fontsize=7, ncol=2)


def plot_run(path: str | Path, title: str, t_s, speed_mps, distance_m, voted_m, demand, mode,
             speed_distance: SpeedDistance | None = None, track_m=None, track_state=None, risk: dict | None = None) -> Path:
    """`track_m` is the remembered obstacle's predicted distance per cycle (None: no track),
    `track_state` its state (monitor.core.types.TRACK_NAMES); both optional. `risk` (optional):
    label -> probability per cycle, and "category" -> seed 001's category per cycle (draw_risk)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = 4 if risk is None else 5
    if speed_distance is None:
        fig, axes = plt.subplots(rows, 1, figsize=(10, 2 * rows), sharex=True, constrained_layout=True)
        axes = list(axes)
    else:
        fig = plt.figure(figsize=(17, 2.1 * rows + 0.1), constrained_layout=True)
        grid = fig.add_gridspec(rows, 2, width_ratios=(1.0, 1.15))
        axes = [fig.add_subplot(grid[0, 0])]
        axes += [fig.add_subplot(grid[i, 0], sharex=axes[0]) for i in range(1, rows)]
        draw_speed_distance(fig.add_subplot(grid[:, 1]), speed_distance)
    axes[0].plot(t_s, speed_mps, color="tab:blue")
    axes[0].set_ylabel("speed (m/s)")
    if distance_m is not None:
        axes[1].plot(t_s, [float("nan") if d is None else d for d in distance_m], label="true distance", color="tab:gray")
    axes[1].plot(t_s, [float("nan") if d is None else d for d in voted_m], ".", ms=2, label="voted distance", color="tab:orange")
    draw_track(axes[1], t_s, track_m, track_state)
    draw_track(axes[2], t_s, None, track_state, label=False)
    axes[1].set_ylabel("distance (m)")
    axes[1].legend(loc="upper right", fontsize=8)
    axes[2].step(t_s, demand, where="post", color="tab:red")
    axes[2].set_yticks(range(3), DEMAND_NAMES)
    axes[2].set_ylabel("demand")
    axes[3].step(t_s, mode, where="post", color="tab:green")
    axes[3].set_yticks(range(4), MODE_NAMES)
    axes[3].set_ylabel("mode")
    if risk is not None:
        draw_risk(axes[4], t_s, risk)
    axes[-1].set_xlabel("time (s)")
    for ax in axes[:-1]:
        ax.tick_params(labelbottom=False)
    fig.suptitle(title)
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)
    plt.close(fig)
    return out
