"""The campaign as a verification part: `section(out_dir, quick, progress, ...)` runs it,
draws the heatmap, judges it by its checks (nothing unsafe, no crash, collisions unavoidable
only where an object appears suddenly, false braking under issue 11's limit, ghosts that
never stop the train, every fault kind detected, the bus and vcan0 samples), writes
campaign.json and returns the report section; `main` is `python -m verification.campaign`
(and the sandbox guest's entry, `--vcan-guest`).
"""
from __future__ import annotations

import json
import os
import sys
from pathlib import Path
from typing import Optional

from monitor.core.config import Config

from ..report import Check, Progress, Section
from ..scale import Cluster
from ..world_train import WorldTrain
from .catalogue import CATALOGUE, HOSTILE, HOSTILE_KINDS, KINDS, PLAYER_KINDS, TABLE_KINDS
from .bus import secured_kind
from .figures import heatmap
from .report import markdown, pct
from .sandbox import vcan_guest
from .scenarios import SCENARIOS, UNAVOIDABLE
from .summary import run


FALSE_BRAKING_LIMIT = 0.05     # issue 11: at most 5 % of the runs brake falsely


def checks(summary: dict) -> list[Check]:
    core = summary["core"]
    quick = summary["mode"] == "quick"
    out = [
        Check("campaign: the world's train never reaches an obstacle it could stop for (core-level runs)",
              core["unsafe"] == 0,
              f"{core['unsafe']} unsafe runs in {core['runs']:,} runs ({core['collisions']} collisions, "
              f"{core['unavoidable']} unavoidable)", {"examples": core["unsafe_examples"]}),
        Check("campaign: a world train outside the braking declaration causes no collision a declared train "
              "would have avoided", not summary.get("world_broken_bounds") or core.get("beyond_declaration", 0) == 0,
              (f"the world's train breaks {'; '.join(summary['world_broken_bounds'])}; "
               f"{core.get('beyond_declaration', 0)} of its {core['collisions']} collisions a train at the "
               "declaration's corner would have avoided") if summary.get("world_broken_bounds")
              else "the world's train lies inside the declaration", {"broken": summary.get("world_broken_bounds", [])}),
        Check("campaign: no crash or exception (core-level runs)", core["crashes"] == 0,
              f"{core['crashes']} crashes in {core['runs']:,} runs", {"examples": core["crash_examples"]}),
    ]
    if not quick:
        out.append(Check("campaign: at least 10,000 core-level runs (full mode)", core["runs"] >= 10_000,
                         f"{core['runs']:,} >= 10,000 in {core['seconds']:.0f} s"))
    sudden = {s.name for s in SCENARIOS if any(o.appear_s > 0 for o in s.obstacles)}
    elsewhere = {name: c["unavoidable"] for name, c in core["by_scenario"].items() if name not in sudden}
    out.append(Check(f"campaign: the world finds collisions unavoidable only where an object appears suddenly, and in {UNAVOIDABLE}",
                     sum(elsewhere.values()) == 0 and core["by_scenario"].get(UNAVOIDABLE, {}).get("unavoidable", 0) > 0,
                     f"{sum(elsewhere.values())} unavoidable where the obstacle is there from the start; "
                     f"{core['by_scenario'].get(UNAVOIDABLE, {}).get('unavoidable', 0)} in {UNAVOIDABLE}",
                     {"by_scenario": elsewhere}))
    none = core["single"].get("none", {"runs": 0, "brake_without_obstacle": 0})
    out.append(Check("campaign: fault-free runs never brake without an obstacle",
                     none["runs"] > 0 and none["brake_without_obstacle"] == 0,
                     f"{none['brake_without_obstacle']} of {none['runs']} fault-free runs"))
    out.append(Check(f"campaign: false braking at most {FALSE_BRAKING_LIMIT:.0%} of the core-level runs, none unsafe (issue 11)",
                     core["runs"] > 0 and core["false_braking_rate"] <= FALSE_BRAKING_LIMIT and core["unsafe"] == 0,
                     f"{pct(core['false_braking_rate'])} ({core['false_braking']:,} of {core['runs']:,}), {core['unsafe']} unsafe; "
                     f"braking without an obstacle, fault reactions included: {pct(core['brake_without_obstacle_rate'])}",
                     {"examples": core["false_braking_examples"]}))
    if "ghost" in summary:
        g = summary["ghost"]
        out.append(Check("campaign: a 0.3 s ghost on one channel beyond SBI never stops the train (clear track, 40 m/s)",
                         g["runs"] > 0 and not g["stopped"] and g["unsafe"] == 0 and not g["undiagnosed"],
                         f"{g['runs']} runs: lowest speed {g['min_speed_mps']:.1f} m/s, highest demand {g['max_demand']}, "
                         f"{len(g['stopped'])} stopped, {len(g['undiagnosed'])} without the dispute diagnostic",
                         {"stopped": g["stopped"], "undiagnosed": g["undiagnosed"]}))
    for k in KINDS:
        d = core["detection"][k]
        ok = d["manifest"] > 0 and d["detected"] == d["manifest"]
        lat = f", within {d['max_latency']} cycles" if k not in TABLE_KINDS else ""
        out.append(Check(f"campaign: {k} detected ({CATALOGUE[k].short})", ok,
                         f"{d['detected']} of {d['manifest']} single-fault runs in which it manifested "
                         f"({d['single_runs']} runs){lat}", {"missed": d["missed"]}))
    pr = core["pairs"]
    out.append(Check("campaign: every pair run with a manifested fault shows a diagnostic", pr["detected"] == pr["manifest"],
                     f"{pr['detected']} of {pr['manifest']}", {"missed": pr["missed"]}))
    if "bus" in summary:
        b = summary["bus"]
        need = 12 if quick else 50
        out.append(Check(f"campaign: virtual-bus sample through runner, codec and player (>= {need})",
                         b["runs"] >= need and b["unsafe"] == 0 and b["crashes"] == 0 and b["collisions_avoidable"] == 0,
                         f"{b['runs']} runs, {b['unsafe']} unsafe, {b['crashes']} crashes, {b['collisions']} collisions "
                         f"({b['collisions_avoidable']} outside {UNAVOIDABLE})",
                         {"unsafe": b["unsafe_examples"], "crashes": b["crash_examples"]}))
        missing = sorted(k for k in PLAYER_KINDS + ("deadline_overrun",) + TABLE_KINDS if not b["detected"].get(k))
        out.append(Check("campaign: virtual bus: every injected fault kind detected", not missing,
                         "all detected" if not missing else f"not detected: {', '.join(missing)}", {"detected": b["detected"]}))
        for k in HOSTILE_KINDS:                   # (their runs are safe by the sample's check above)
            out.append(Check(f"campaign: virtual bus: a hostile node, {HOSTILE[k].label}, detected ({HOSTILE[k].short})",
                             bool(b["detected"].get(k)), "detected" if b["detected"].get(k) else "not detected"))
            sk = secured_kind(k)                  # the same attack on the secured bus (issue 39), keyless
            out.append(Check(f"campaign: secured virtual bus: a keyless hostile node, {HOSTILE[k].label}, detected "
                             f"({HOSTILE[k].short}; its frames fail the authenticator)",
                             bool(b["detected"].get(sk)), "detected" if b["detected"].get(sk) else "not detected"))
    if "vcan" in summary:
        v = summary["vcan"]
        need = 1 if quick else 5
        if "error" in v:
            if os.environ.get("CI") == "true" or not _sandbox_unavailable(v["error"]):
                out.append(Check(f"campaign: vcan0 sample in the sandbox (>= {need})", False, v["error"]))
        else:
            missed = sorted(k for k, ok in v["detected"].items() if not ok)
            out.append(Check(f"campaign: vcan0 sample in the sandbox (>= {need})",
                             v["runs"] >= need and v["unsafe"] == 0 and v["crashes"] == 0 and not missed,
                             f"{v['runs']} runs, {v['unsafe']} unsafe, {v['crashes']} crashes, "
                             f"faults detected: {len(v['detected']) - len(missed)} of {len(v['detected'])}, {v['seconds']:.0f} s",
                             {"crashes": v["crash_examples"], "unsafe": v["unsafe_examples"]}))
    return out


def _sandbox_unavailable(error: str) -> bool:
    return error.startswith("SandboxError") and "apt-get" in error


def section(out_dir, quick: bool, progress: Progress, config: Optional[Config] = None,
            world: Optional[WorldTrain] = None, margin_m: float = 0.0, cluster: Cluster = Cluster()) -> Section:
    """The campaign as a report part; `config` (default Config()) carries the braking
    declaration, `world` the world's train (None: drawn inside the declaration), `cluster`
    where the runs go."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    summary = run(quick, progress, config=config, world=world, margin_m=margin_m, cluster=cluster)
    fig = heatmap(summary["core"], out / "campaign_false_braking.png")
    found = checks(summary)
    summary["passed"] = all(c.passed for c in found)
    (out / "campaign.json").write_text(json.dumps(summary, indent=1, default=str))
    headline = {"runs": summary["runs"], "unsafe": summary["unsafe"], "collisions": summary["collisions"],
                "workers": cluster.scheduler or cluster.size(),
                "runs_digest": summary["runs_digest"], "world_train": summary["world_train"], "margin_m": margin_m}
    return Section("Fault-injection campaign", markdown(summary, fig.name), found, [fig.name], summary["seconds"],
                   headline)


def main(argv: Optional[list] = None) -> int:
    import argparse

    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["--vcan-guest"]:
        return vcan_guest(argv[1], argv[2])
    doc = sys.modules[__package__].__doc__          # the package's: the campaign in one line
    ap = argparse.ArgumentParser(prog="python -m verification.campaign", description=doc.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--out", default="railguard-out/campaign")
    args = ap.parse_args(argv)

    def progress(msg: str) -> None:
        if not args.json:
            print(msg, file=sys.stderr, flush=True)

    sec = section(Path(args.out), args.quick, progress)
    if args.json:
        print(json.dumps({"passed": all(c.passed for c in sec.checks),
                          "checks": [{"name": c.name, "passed": bool(c.passed), "figure": c.figure} for c in sec.checks]}))
    else:
        for c in sec.checks:
            print(c.line())
    return 0 if all(c.passed for c in sec.checks) else 1
