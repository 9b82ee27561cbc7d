"""The whole campaign, one summary: the core-level runs and the ghosts, the virtual-bus sample
and the vcan0 sessions, aggregated, with the totals and rates over every run, the detection
verdict per kind and the README table.
"""
from __future__ import annotations

import time
from typing import Optional

from monitor.core.config import Config

from .. import world_train
from ..report import Progress
from ..scale import Cluster, map_ordered
from ..world_train import WorldTrain
from .counts import aggregate, bus_summary, runs_digest, vruns_detail
from .bus import bus_plan, bus_work
from .catalogue import KINDS
from .report import faults_table
from .specs import SEEDS, combos, plan
from .runs import ghost_summary, run_core, run_ghosts
from .sandbox import vcan_plan, vcan_sample
from .scenarios import SCENARIOS


def run(quick: bool, progress: Progress, *, bus: bool = True, vcan_runs: bool = True, cluster: Cluster = Cluster(),
        config: Optional[Config] = None, world: Optional[WorldTrain] = None, margin_m: float = 0.0) -> dict:
    """The whole campaign with the monitor's `config` (default Config(), the shipped braking
    declaration) in a world whose train is `world` (None: each run's own, drawn inside the
    declaration, corners included); unsafe: the world's train reaches an obstacle it could
    have stopped for, or comes closer than `margin_m`. Returns the summary (the package docstring)."""
    t0 = time.perf_counter()
    cfg = config or Config()
    specs = plan(quick)
    progress(f"campaign: {len(specs):,} core-level runs ({len(combos()) - 1} fault combinations x "
             f"{len(SCENARIOS)} scenarios{'' if quick else f' x {SEEDS} seeds'})"
             + (f"; world train: {world.describe()}" if world else "; world trains drawn inside the declaration"))
    progress(f"campaign: running on {cluster.describe()}")
    results = run_core(specs, progress, cluster, cfg, world, margin_m)
    progress("campaign: ghost runs (a 0.3 s ghost on one channel beyond SBI, clear track, 40 m/s)")
    ghosts = run_ghosts(quick, cfg, world, margin_m)
    core = aggregate(results + ghosts)
    core["seconds"] = time.perf_counter() - t0
    progress(f"campaign: core runs done in {core['seconds']:.0f} s: {core['unsafe']} unsafe, {core['crashes']} crashes")
    summary = {"mode": "quick" if quick else "full", "core": core, "config": cfg._asdict(), "ghost": ghost_summary(ghosts),
               "world_train": world_train.as_dict(world), "margin_m": margin_m,
               "world_broken_bounds": world_train.broken_bounds(world, cfg) if world else [],
               "runs_digest": runs_digest(results + ghosts)}

    bus_runs: list = []
    if bus:
        t1 = time.perf_counter()
        bspecs = bus_plan(quick)
        progress(f"campaign: {len(bspecs)} runs through the runner, codec and player on the virtual bus")
        chunks = [((s,), cfg, world, margin_m) for s in bspecs]
        bus_runs = [r for res in map_ordered(bus_work, chunks, cluster, progress=progress, label="campaign: bus runs")
                    for r in res]
        summary["bus"] = dict(bus_summary(bus_runs), seconds=time.perf_counter() - t1,
                              runs_detail=[{k: v for k, v in r.items() if k != "unsafe_first"} for r in bus_runs])
    vruns: list = []
    if vcan_runs:
        try:
            v = vcan_sample(vcan_plan(quick), progress, cfg, margin_m)
            vruns = v["runs"]
            summary["vcan"] = dict(bus_summary(vruns), seconds=v["seconds"], timed_out=v["timed_out"], runs_detail=vruns_detail(vruns))
        except Exception as exc:  # noqa: BLE001 - SandboxError or an unexpected failure: reported, never a crash of the campaign
            summary["vcan"] = {"runs": 0, "error": f"{type(exc).__name__}: {exc}"}
    summary["runs"] = core["runs"] + len(bus_runs) + len(vruns)
    summary["unsafe"] = core["unsafe"] + sum(bool(r.get("unsafe")) for r in bus_runs + vruns)
    summary["crashes"] = core["crashes"] + sum(r.get("crash") is not None for r in bus_runs + vruns)
    summary["collisions"] = core["collisions"] + sum(bool(r.get("collision")) for r in bus_runs + vruns)
    for key in ("false_braking", "brake_without_obstacle"):
        count = core[key] + sum(bool(r.get(key)) for r in bus_runs + vruns)
        summary[key + "_rate"] = count / summary["runs"] if summary["runs"] else 0.0
    summary["detection"] = {k: core["detection"][k]["manifest"] > 0 and core["detection"][k]["detected"] == core["detection"][k]["manifest"]
                            for k in KINDS}
    summary["readme_table"] = faults_table(core)
    summary["seconds"] = time.perf_counter() - t0
    return summary
