"""Campaign throughput on dask.distributed: core-level runs per second against workers.

Run: python benchmarks/bench_campaign.py [--runs N] [--workers 1,2] [--scheduler ADDRESS] [--json]
Target (issue 14): with 2 workers on 2 cores at least 1.8x the runs/s of 1 worker, and the
same runs_digest for every number of workers.

The runs are the first N of the full campaign plan (every fault combination x scenario x
seed). Two rates are printed per worker count: `wall` (from the call to the last result,
the local cluster's start-up included) and `steady` (from the first result to the last,
what a long campaign sees). With 1 worker the runs go in this process, no cluster.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import time

from verification import campaign as cp
from verification.scale import Cluster, map_ordered


def measure(specs: list, cluster: Cluster) -> dict:
    chunks = [(specs[i:i + cp.CHUNK], None, None, 0.0) for i in range(0, len(specs), cp.CHUNK)]
    stamps: list = []          # (time, runs in the job) as results arrive

    t0 = time.perf_counter()
    done = map_ordered(cp._work, chunks, cluster, on_done=lambda i: stamps.append((time.perf_counter(), len(chunks[i][0]))))
    t1 = time.perf_counter()
    runs = [r for chunk in done for r in chunk]
    first = stamps[0][0]
    steady_runs = len(runs) - stamps[0][1]
    return {"workers": cluster.scheduler or cluster.size(), "runs": len(runs), "wall_s": round(t1 - t0, 2),
            "runs_per_s_wall": round(len(runs) / (t1 - t0), 1),
            "runs_per_s_steady": round(steady_runs / (t1 - first), 1) if len(stamps) > 1 and t1 > first else None,
            "runs_digest": cp.runs_digest(runs)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=2000, help="core-level runs per measurement (default %(default)s)")
    ap.add_argument("--workers", default="1,2", help="comma-separated worker counts (default %(default)s)")
    ap.add_argument("--scheduler", help="measure on an existing dask cluster instead")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    plan = cp.plan(False)
    step = max(1, len(plan) // args.runs)
    specs = plan[::step][: args.runs]             # spread over every combination and scenario
    rows = ([measure(specs, Cluster(scheduler=args.scheduler))] if args.scheduler else
            [measure(specs, Cluster(int(w))) for w in args.workers.split(",")])
    base = rows[0]
    for r in rows:
        r["speedup_steady"] = (round(r["runs_per_s_steady"] / base["runs_per_s_steady"], 2)
                               if r["runs_per_s_steady"] and base["runs_per_s_steady"] else None)
        r["speedup_wall"] = round(r["runs_per_s_wall"] / base["runs_per_s_wall"], 2)
    same = len({r["runs_digest"] for r in rows}) == 1
    if args.json:
        print(json.dumps({"machine": platform.machine(), "cores": os.cpu_count(), "results": rows,
                          "same_digest": same}))
        return
    print(f"campaign throughput, {len(specs):,} core-level runs, {os.cpu_count()} cores ({platform.machine()})")
    def shown(value, fmt: str) -> str:     # a steady rate needs two or more jobs (one job of CHUNK runs has none)
        return "-" if value is None else format(value, fmt)

    for r in rows:
        print(f"  workers {r['workers']}: {r['runs_per_s_wall']:7.1f} runs/s wall ({r['wall_s']:.1f} s), "
              f"{shown(r['runs_per_s_steady'], '7.1f')} runs/s steady; speedup {r['speedup_wall']:.2f}x wall, "
              f"{shown(r['speedup_steady'], '.2f')}x steady")
    print(f"  runs_digest {'identical' if same else 'DIFFERENT'}: {rows[0]['runs_digest']}")


if __name__ == "__main__":
    main()
