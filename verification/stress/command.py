"""`railguard stress`: the search, then the likeliest failure (and the likeliest after a
released emergency) written as a candump log, checked by replaying it, and as a
co-simulation scenario, with stress.json and the plot; and its few lines of text.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

from monitor.core.config import Config

from .. import world_train
from ..report import Progress
from ..scale import Cluster
from .artefacts import replay_matches, write_candump, write_cosim_scenario
from .cross_entropy import QUICK, Budget, search
from .disturbances import Disturbance
from .encounters import ENCOUNTERS
from .figures import plot


def run(model: str, encounter: str = "edge-30", out_dir: Path = Path("railguard-out/stress"), *, quick: bool = False,
        cfg: Config = Config(), world=None, margin_m: float = 0.0, seed: int = 0, cluster: Cluster = Cluster(),
        progress: Optional[Progress] = None) -> dict:
    """`railguard stress`: the search, then the likeliest failure (if any) written as a
    candump log, checked by replaying it, and as a co-simulation scenario; stress.json."""
    enc = ENCOUNTERS[encounter]
    world = world or world_train.corners(cfg)[0]
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    result = search(model, enc, world=world, cfg=cfg, budget=QUICK if quick else Budget(), margin_m=margin_m,
                    seed=seed, cluster=cluster, progress=progress)
    files = []
    for key, stem in (("most_likely_failure", "failure"), ("most_likely_failure_after_release", "failure-after-release")):
        f = result[key]
        if f is None:
            continue
        d = Disturbance.from_lists(f["disturbance"])
        log = write_candump(model, enc, d, world, cfg, out / f"{stem}-{model}-{enc.name}.log")
        f["candump"] = str(log)
        f["replay_reproduces"] = replay_matches(model, enc, d, world, cfg, log)
        f["cosim"] = str(write_cosim_scenario(model, enc, d, world, cfg, out / f"{stem}-{model}-{enc.name}.cosim.toml"))
        files += [log, Path(f["cosim"])]
    files.append(plot(result, cfg, out / f"stress-{model}-{enc.name}.png"))
    result["files"] = [str(p) for p in files] + [str(out / "stress.json")]
    (out / "stress.json").write_text(json.dumps(result, indent=1, default=str) + "\n", encoding="utf-8")
    return result


def render(result: dict) -> str:
    enc, rare = result["encounter"], result["rare_event"]
    lines = [f"stress, table {result['table']}, encounter {enc['name']}: {enc['description']} "
             f"(appears {result['appear_m']} m ahead); {result['simulations']:,} closed-loop runs, {result['seconds']:.0f} s",
             f"  world train: {world_train.from_mapping(result['world_train'], 'world').describe()}"]
    for key, title in (("most_likely_failure", "likeliest failure"),
                       ("most_likely_failure_after_release", "likeliest failure after a released emergency")):
        f = result[key]
        if f is None:
            lines.append(f"  {title}: none found")
            continue
        lines.append(f"  {title}: log-likelihood {f['log_likelihood']:.2f} (against the undisturbed run), "
                     f"impact {f['impact_speed_mps']} m/s; {summarise(f['events'])}"
                     + (f"; replay of {f['candump']}: {'reproduces it' if f.get('replay_reproduces') else 'DIFFERS'}"
                        if "candump" in f else ""))
    lines.append(f"  P(collision per encounter): importance sampling {rare['p_importance_sampling']:.3g} "
                 f"(95 % {rare['ci95'][0]:.3g}..{rare['ci95'][1]:.3g}; {rare['failures_in_is_samples']} of "
                 f"{rare['samples']} samples fail, worth {rare['effective_failures']:.1f} equally weighted failures); "
                 f"naive Monte Carlo "
                 f"{rare['naive']['failures']} of {rare['samples']} = {rare['naive']['p']:.3g} "
                 f"(95 % upper {rare['naive']['ci95_upper']:.3g})")
    return "\n".join(lines) + "\n"


def summarise(events: list[dict]) -> str:
    """'blind 1.4-2.5 s; miss ch3 at 0.2 s' from a failure's event list."""
    blind = sorted(e["t_after_appearance_s"] for e in events if e["kind"] == "blind")
    parts = []
    if blind:
        runs, start = [], blind[0]
        for a, b in zip(blind, blind[1:] + [None]):
            if b is None or b - a > 0.1 + 1e-9:
                runs.append(f"{start:.1f}-{a + 0.1:.1f} s")
                start = b
        parts.append("every channel blind " + ", ".join(runs) + " after the obstacle appeared")
    others = [e for e in events if e["kind"] != "blind"]
    if others:
        parts.append(", ".join(f"{e['kind']} {e['channel']}" if e["kind"] in ("module_miss", "object_behind") else
                               f"{e['kind']} ch{e['channel']} at {e['t_after_appearance_s']:.1f} s" for e in others[:8])
                     + (f" and {len(others) - 8} more" if len(others) > 8 else ""))
    return "; ".join(parts) or "no disturbance"
