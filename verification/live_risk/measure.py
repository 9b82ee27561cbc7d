"""The runs on the bus and what is read off their logs: `seed000_episodes` (Fig. 7c's R1
and R2 at the obstacle's first report and over the AboutToCrash cycles) and
`seed001_trains` (the risk category the monitor sent against the world's true one), each
log also replayed (`replay_agrees`) to show the figures are the monitor's, recomputable
from the file alone.
"""
from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Optional

import numpy as np

from can_bus import logfile
from can_bus.replay import Replay
from can_bus.runner import per_mille_up
from can_bus.session import run_virtual
from monitor.core import cycle
from monitor.core.config import Config
from monitor.offline.risk import r1_logistic, r2_linear
from monitor.tables import read

from ..seed001.metrics import standard_error
from ..seed001.world import Settings, load_setup, simulate
from .bus_log import database, monitor_signals
from .players import APPEAR_S, seed000_scenarios, true_zones, world_scenario, world_trace_player

ZONE_ABOUT_TO_CRASH, ZONE_CRASH = 2, 3     # seed 000's states as the monitor's zones (fastcore.zone_of)


@dataclass
class Episode:
    """One seed-000 episode as the bus carried it, beside the world's truth."""

    name: str
    log: Path
    outcome: str
    signals: dict                  # bus_log.monitor_signals
    truth: dict                    # players.true_zones
    first: int                     # index of the first cycle whose R1 on the bus is above 0
    r2_true_first: float           # eq. 17 in floats on the true distance, at that cycle
    r1_true_first: float


def replay_agrees(setup, path: Path, signals: dict) -> tuple[bool, int]:
    """Replay the log through the monitor's receive path and core (`railguard replay`) and
    compare every cycle's risk, rounded as MonitorRisk carries it, with the frames sent:
    (all equal, cycles compared)."""
    recs = {r.tick: r for r in Replay(setup, source=str(path)).run(logfile.read(path))}
    compared = 0
    for k, t in enumerate(signals["tick"]):
        r = recs.get(int(t))
        if r is None:
            return False, compared
        sent = (round(signals["r1_pct"][k] * 10), round(signals["r2_pct"][k] * 10), int(signals["category"][k]),
                int(signals["score"][k]), int(signals["table_ppm"][k]), int(signals["level"][k]))
        again = (per_mille_up(r.r1_ppm), per_mille_up(r.r2_ppm), r.risk_category, r.risk_score,
                 r.table_risk_ppm, r.demand)
        if sent != again:
            return False, compared
        compared += 1
    return True, compared


def seed000_episodes(n: int, seed: int, logs: Path, progress: Callable[[str], None]) -> tuple[list[Episode], object]:
    setup = cycle.create(Config(), read("m1"), "m1")
    db = database()
    out = []
    for sc in seed000_scenarios(n, seed):
        res = run_virtual(setup, sc, logs, plot=False)
        path = logs / f"run-{sc.name}.log"
        sig = monitor_signals(path, db)
        truth = true_zones(setup.config, sig["tick"], res.player.trace)
        seen = np.flatnonzero((sig["r1_pct"] > 0) & (sig["tick"] >= APPEAR_S * 1000))
        first = int(seen[0]) if seen.size else -1
        d, a1, a2 = truth["distance_m"][first], truth["alpha1_m"][first], truth["alpha2_m"][first]
        out.append(Episode(sc.name, path, res.summary["outcome"], sig, truth, first,
                           r2_linear(d, a1, a2) if first >= 0 else math.nan,
                           r1_logistic(d, a1) if first >= 0 else math.nan))
    progress(f"live risk: {n} seed-000 episodes played on the bus")
    return out, setup


def seed000_figures(episodes: list[Episode]) -> dict:
    """Fig. 7c's numbers from the bus, and the same from eqs. 16-17 on the true distance."""
    firsts = [e for e in episodes if e.first >= 0]
    r2 = np.array([e.signals["r2_pct"][e.first] / 100 for e in firsts])
    r1 = np.array([e.signals["r1_pct"][e.first] / 100 for e in firsts])
    atc = np.concatenate([e.signals["r2_pct"][e.truth["zone"] == ZONE_ABOUT_TO_CRASH] / 100 for e in episodes])
    r1_out = np.concatenate([e.signals["r1_pct"][e.truth["zone"] < ZONE_CRASH] / 100 for e in episodes])
    return {
        "episodes": len(episodes), "seen": len(firsts),
        "collisions": sum(e.outcome == "collision" for e in episodes),
        "r2_first_mean": float(r2.mean()) if r2.size else math.nan,
        "r2_first_min": float(r2.min()) if r2.size else math.nan, "r2_first_max": float(r2.max()) if r2.size else math.nan,
        "r1_first_max": float(r1.max()) if r1.size else math.nan,
        "r2_true_first_mean": float(np.mean([e.r2_true_first for e in firsts])) if firsts else math.nan,
        "r1_true_first_max": float(np.max([e.r1_true_first for e in firsts])) if firsts else math.nan,
        "r2_about_to_crash_mean": float(atc.mean()) if atc.size else math.nan, "about_to_crash_cycles": int(atc.size),
        "r1_outside_crash_max": float(r1_out.max()) if r1_out.size else math.nan,
        "cycles": int(sum(e.signals["tick"].size for e in episodes)),
    }


@dataclass
class Seed001Live:
    trains: int                    # played on the bus
    cycles: int
    demand_equal: int              # cycles whose BrakeDemand equals the world's recorded demand
    category_equal_picture: int    # obstacle cycles whose RiskCategory equals the twin's picture category
    obstacle_cycles: int
    right_obstacle: np.ndarray     # per train: obstacle cycles whose RiskCategory is the true category
    obst_per_train: np.ndarray
    right_all: np.ndarray          # per train: cycles right, an obstacle-free cycle right if 'low'
    picture_right_all: int         # the same steps judged by the twin's picture (seed001 part's definition)
    replayed: int = 0
    replay_equal: bool = True


def seed001_trains(world_trains: int, played: int, seed: int, logs: Path, progress,
                   replay: int = 2) -> Seed001Live:
    """Simulate the seed-001 world (`world_trains`, the first `played` recorded), play each
    recorded train's sensor frames to the monitor on the bus, and read its MonitorRisk back."""
    run = simulate(Settings(trains=world_trains, record=played, belief_trains=0, seed=seed))
    setup, _, _ = load_setup()
    period = setup.config.period_ms
    db = database()
    cols = run.trace["present"].shape[1]
    res = Seed001Live(cols, 0, 0, 0, 0, np.zeros(cols), np.zeros(cols), np.zeros(cols), 0)
    for i in range(cols):
        name = f"seed001-live-{i:02d}"
        run_virtual(setup, world_scenario(name, run.settings.steps, period), logs, plot=False,
                    player=world_trace_player(run.trace, run.sample, i, setup))
        path = logs / f"run-{name}.log"
        sig = monitor_signals(path, db)
        k = sig["tick"] // period
        present = run.sample["present"][k, i] > 0
        true = run.sample["true_risk"][k, i]
        cat = sig["category"].astype(int)
        res.cycles += k.size
        res.demand_equal += int((sig["level"] == run.trace["demand"][k, i]).sum())
        res.obstacle_cycles += int(present.sum())
        res.category_equal_picture += int((cat == run.sample["picture_risk"][k, i])[present].sum())
        res.right_obstacle[i] = (cat == true)[present].sum()
        res.obst_per_train[i] = present.sum()
        res.right_all[i] = int((cat == true)[present].sum() + (cat == 1)[~present].sum())
        res.picture_right_all += int((run.sample["picture_risk"][k, i] == true).sum())
        if i < replay:
            ok, n = replay_agrees(setup, path, sig)
            res.replay_equal &= ok
            res.replayed += n
    progress(f"live risk: {cols} seed-001 trains played on the bus ({res.cycles:,} cycles)")
    return res


def accuracy_figures(live: Seed001Live) -> dict:
    """Risk accuracy from the bus, in per cent, with standard errors over trains."""
    per_obst = live.right_obstacle / np.maximum(live.obst_per_train, 1)
    steps = live.cycles / max(live.trains, 1)
    per_all = live.right_all / steps
    return {
        "accuracy_all": 100.0 * live.right_all.sum() / max(live.cycles, 1),
        "accuracy_all_se": 100.0 * standard_error(per_all),
        "accuracy_obstacle": 100.0 * live.right_obstacle.sum() / max(live.obstacle_cycles, 1),
        "accuracy_obstacle_se": 100.0 * standard_error(per_obst),
        "picture_accuracy_all": 100.0 * live.picture_right_all / max(live.cycles, 1),
    }


def scratch() -> tempfile.TemporaryDirectory:
    """Where the runs' logs go (all but the one the report keeps)."""
    return tempfile.TemporaryDirectory(prefix="railguard-live-risk-")


__all__ = ["Episode", "Seed001Live", "accuracy_figures", "replay_agrees", "scratch", "seed000_episodes",
           "seed000_figures", "seed001_trains"]
