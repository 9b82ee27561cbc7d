"""The core-level runs as jobs: chunks of specs through `world.simulate` on the cluster (order
kept, each run drawing from its own key, so the results do not depend on the workers), and
the ghost runs (a short phantom on one channel beyond SBI on a clear track) with their verdict.
"""
from __future__ import annotations

from typing import Optional

from monitor.core.braking import curves
from monitor.core.config import Config

from ..report import Progress
from ..scale import Cluster, map_ordered
from ..world_train import WorldTrain
from .specs import Fault, RunSpec
from .scenarios import GHOST_SCENARIO, RANGE_M
from .world import simulate


GHOST_S = 0.3


def _work(job: tuple) -> list:
    specs, cfg, world, margin_m = job
    out = []
    for spec in specs:
        r = simulate(spec, config=cfg, world=world, margin_m=margin_m)
        r.pop("trace", None)
        out.append(r)
    return out


CHUNK = 40           # core-level runs per dask task


def run_core(specs: list[RunSpec], progress: Progress, cluster: Cluster = Cluster(), config: Optional[Config] = None,
             world: Optional[WorldTrain] = None, margin_m: float = 0.0) -> list[dict]:
    """Every spec through `simulate` with `config` (default Config()) and `world` (None: each
    run's own train inside the declaration), on `cluster` (order kept). Each run draws its
    faults, noise and world train from its own key, so the results do not depend on the
    number of workers."""
    cfg = config or Config()
    chunks = [(specs[i:i + CHUNK], cfg, world, margin_m) for i in range(0, len(specs), CHUNK)]
    done = map_ordered(_work, chunks, cluster, progress=progress, label="campaign: core runs",
                       weight=lambda job: len(job[0]))
    return [r for chunk in done for r in chunk]


def ghost_plan(quick: bool, cfg: Config) -> list[tuple]:
    """(spec, faults) of the ghost runs: on a clear track at 40 m/s, one channel reports a
    static obstacle for GHOST_S at a fixed distance beyond SBI (just beyond, half-way to the
    warning curve, just beyond the warning curve, far), every channel in turn, with the m1
    and m2 tables alternating (full mode: both tables)."""
    scen = GHOST_SCENARIO
    v = round(scen.train.speed_mps * 100)
    c = curves(cfg, v, 0, 0, v, cfg.period_ms)          # a report up to one period old (the world's phase)
    far = int(RANGE_M * 10) - 100
    distances = sorted({min(x, far) for x in (c.sbi_dm + 1, (c.sbi_dm + c.warning_dm) // 2, c.warning_dm + 1, far)})
    out = []
    for ch in range(6):
        for i, d in enumerate(distances):
            start = round(2.0 + 0.7 * i + 0.3 * ch, 1)
            for model in (("m1", "m2")[(i + ch) % 2],) if quick else ("m1", "m2"):
                spec = RunSpec(("ghost",), scen.name, 100 * ch + i, model)
                out.append((spec, [Fault("ghost", ch, start, round(start + GHOST_S, 1), (d,))]))
    return out


def run_ghosts(quick: bool, cfg: Optional[Config] = None, world: Optional[WorldTrain] = None,
               margin_m: float = 0.0) -> list[dict]:
    """The ghost runs through `simulate` (each result also carries the ghost's distance)."""
    cfg = cfg or Config()
    out = []
    for spec, faults in ghost_plan(quick, cfg):
        r = simulate(spec, config=cfg, faults=faults, world=world, margin_m=margin_m)
        r.pop("trace", None)
        out.append(dict(r, ghost_dm=faults[0].variant[0]))
    return out


def ghost_summary(runs: list[dict]) -> dict:
    """The ghosts' verdict: the train never stands still, nothing unsafe, and the monitor shows
    the disagreement (reason bit `dispute`)."""
    stopped = [r["key"] for r in runs if r["crash"] or not r.get("min_speed_mps")]
    return {"runs": len(runs), "stopped": stopped, "unsafe": sum(bool(r["unsafe"]) for r in runs),
            "false_braking": sum(bool(r["false_braking"]) for r in runs),
            "undiagnosed": [r["key"] for r in runs if "dispute" not in r.get("reasons_seen", ())],
            "min_speed_mps": min((r.get("min_speed_mps") or 0.0 for r in runs), default=0.0),
            "max_demand": max((r.get("max_demand") or 0 for r in runs), default=0),
            "distances_dm": sorted({r["ghost_dm"] for r in runs})}
