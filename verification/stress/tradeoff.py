"""The forgetting time's trade-off (issue 29 item 8): how long the monitor keeps an obstacle no
channel shows, measured on both of its sides.

For each `forget_ms` (and for the design that holds every emergency to standstill), with
the m2 table: the stress search and the importance-sampled P(collision per encounter) in the
edge-30 encounter (an object appearing one cycle of travel beyond EBI at 30 m/s, the world's
train at the declaration's worst corner, the calibrated common-cause blindness), beside the
stops per train-hour without an obstacle (and all stops) in the seed-000 world with Model 1's
2 % phantoms. The figure is docs/supervision_tradeoff.png:

    python -m verification.stress.tradeoff [--quick] [--out DIR] [--json] [--workers N]
"""
from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

from monitor.core.config import Config

from ..scale import Cluster
from .command import run

FORGET_MS = (100, 1000, 2000, 5000, 7500, 10000)
HELD = "held to standstill"


def phantom_stops(cfg: Config, quick: bool) -> dict:
    """Stops per train-hour in the seed-000 world with Model 1's 2 % phantoms (verify's sizes)."""
    from ..seed000.runs import FULL, QUICK, SEEDS, stops_per_hour
    from ..seed000.world import PHANTOMS, simulate

    n, secs = (QUICK if quick else FULL)["shipped_phantoms"]
    r = simulate(replace(PHANTOMS, config=cfg), n, secs, SEEDS["shipped_phantoms"], record=0, progress=lambda m: None)
    return {"stops_no_obstacle": stops_per_hour(r, "stops_no_obstacle"), "stops": stops_per_hour(r)}


def point(label: str, cfg: Config, out: Path, quick: bool, cluster: Cluster, progress) -> dict:
    """One design's two sides: the stress result on edge-30 (m2) and the phantom stops."""
    progress(f"tradeoff: {label}: stress search and rare events")
    r = run("m2", "edge-30", out / label.replace(" ", "-"), quick=quick, cfg=cfg, cluster=cluster, progress=None)
    rare = r["rare_event"]
    found = {k: None if r[k] is None else {"log_likelihood": r[k]["log_likelihood"],
                                          "events": [(e["kind"], e["cycle"]) for e in r[k]["events"]]}
             for k in ("most_likely_failure", "most_likely_failure_after_release")}
    progress(f"tradeoff: {label}: phantom stops")
    return {"label": label, "forget_ms": cfg.forget_ms, "emergency_release": cfg.emergency_release,
            "p_collision": rare["p_importance_sampling"], "ci95": rare["ci95"],
            "effective_failures": rare["effective_failures"], "naive": rare["naive"], **found,
            **phantom_stops(cfg, quick)}


def sweep(out: Path, quick: bool = False, cluster: Cluster = Cluster(), base: Config = Config(),
          forget_ms=FORGET_MS, progress=lambda m: None) -> list[dict]:
    """Every forgetting time, then the held design at the default forgetting time."""
    rows = [point(f"forget {f} ms", base._replace(forget_ms=f), out, quick, cluster, progress) for f in forget_ms]
    rows.append(point(HELD, base._replace(emergency_release=0), out, quick, cluster, progress))
    return rows


def figure(rows: list[dict], path: Path, default_ms: int) -> Path:
    """P(collision per edge encounter) with its 95 % interval against phantom stops per
    train-hour, one point per forgetting time, the held design apart."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    for r in rows:
        held = r["label"] == HELD
        lo, hi = r["ci95"]
        ax.errorbar([r["stops_no_obstacle"]], [r["p_collision"]],
                    yerr=[[r["p_collision"] - lo], [hi - r["p_collision"]]], fmt="s" if held else "o",
                    color="tab:red" if held else ("tab:green" if r["forget_ms"] == default_ms else "tab:blue"),
                    capsize=3)
        name = HELD if held else f"{r['forget_ms'] / 1000:g} s"
        ax.annotate(name, (r["stops_no_obstacle"], r["p_collision"]), textcoords="offset points",
                    xytext=(6, 4) if r["forget_ms"] != 7500 or held else (6, -10), fontsize=8)
    floor = unsurvivable_floor()
    ax.axhline(floor, color="grey", ls="--", lw=1)
    ax.annotate(f"blind from the appearance for 0.9 s or more: no monitor survives ({floor:.2g})", (0.05, floor),
                xycoords=("axes fraction", "data"), textcoords="offset points", xytext=(0, -11), fontsize=7,
                color="grey")
    ax.set_xscale("log")
    ax.set_xlim(0.3, 100.0)
    ax.set_yscale("log")
    ax.set_xlabel("stops per train-hour without an obstacle (seed-000 world, 2 % phantoms)")
    ax.set_ylabel("P(collision per edge-30 encounter), 95 % interval")
    ax.set_title(f"Forgetting time: availability against safety (default {default_ms / 1000:g} s in green)")
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def unsurvivable_floor(cycles: int = 9) -> float:
    """P(every channel blind from the appearance for `cycles` cycles or more) under the
    calibrated blindness chain: in edge-30 the train survives 8 such cycles and not 9
    (tests/test_stress.py), so no release rule can go below this."""
    from .disturbances import BLIND_STAYS, P_BLIND

    return P_BLIND * BLIND_STAYS ** (cycles - 1)


def render(rows: list[dict]) -> str:
    head = (f"{'design':<22}{'P(collision)':>13}{'95 % interval':>22}{'eff. failures':>15}"
            f"{'phantom stops/h':>17}{'all stops/h':>13}  likeliest failure")
    lines = [head]
    for r in rows:
        f = r["most_likely_failure"]
        what = "none found" if f is None else f"{f['log_likelihood']:.2f}: {f['events'][0][0]} from cycle " \
                                              f"{f['events'][0][1]}, {len(f['events'])} events"
        lines.append(f"{r['label']:<22}{r['p_collision']:>13.3g}{'%.2g..%.2g' % tuple(r['ci95']):>22}"
                     f"{r['effective_failures']:>15.1f}{r['stops_no_obstacle']:>17.2f}{r['stops']:>13.1f}  {what}")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m verification.stress.tradeoff", description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true", help="the stress search's and verify's quick sizes")
    p.add_argument("--out", type=Path, default=Path("railguard-out/tradeoff"), help="output folder")
    p.add_argument("--figure", type=Path, default=None, help="where to write the figure (default: OUT/tradeoff.png)")
    p.add_argument("--workers", type=int, default=0, help="dask worker processes (default: one per core)")
    p.add_argument("--json", action="store_true", help="print the rows as JSON")
    a = p.parse_args(argv)
    rows = sweep(a.out, a.quick, Cluster(a.workers), progress=lambda m: print(m, file=sys.stderr, flush=True))
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "tradeoff.json").write_text(json.dumps(rows, indent=1) + "\n", encoding="utf-8")
    figure(rows, a.figure or a.out / "tradeoff.png", Config().forget_ms)
    print(json.dumps(rows, indent=1) if a.json else render(rows) + f"\nno monitor survives a blindness from the "
          f"appearance of 0.9 s or more: P = {unsurvivable_floor():.3g} per encounter")
    return 0


if __name__ == "__main__":
    sys.exit(main())
