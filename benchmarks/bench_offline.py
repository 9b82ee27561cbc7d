"""Solve-plus-compile wall time and table size per model, with the default settings.

Run: python benchmarks/bench_offline.py [--json] [--repeat N]
Targets (issue 2): Model 1 <= 5 s, Model 2 <= 60 s, Model 2 table <= 64 KiB.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time

from monitor.offline import models, pipeline

TARGETS = {"m1": (5.0, None), "m2": (60.0, 64 * 1024)}


def bench(name: str, repeat: int) -> dict:
    model, plan = models.load(name)
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        result = pipeline.run(model, plan)
        times.append(time.perf_counter() - t0)
    f = pipeline.figures(result)
    secs, size = TARGETS[name]
    return {
        "model": name,
        "seconds_median": statistics.median(times),
        "seconds_all": times,
        "target_seconds": secs,
        "table_bytes": f["table_bytes"],
        "target_table_bytes": size,
        "nodes": f["nodes"],
        "controller_value": f["controller_value"],
        "lower_bound": f["lower_bound"],
        "upper_bound": f["upper_bound"],
        "iterations": f["iterations"],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="one JSON object instead of a table")
    ap.add_argument("--repeat", type=int, default=1, help="runs per model (median reported)")
    ap.add_argument("--models", nargs="+", default=list(TARGETS), choices=list(TARGETS))
    args = ap.parse_args()
    rows = [bench(m, args.repeat) for m in args.models]
    machine = f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}"
    if args.json:
        print(json.dumps({"machine": machine, "results": rows}))
        return
    print(f"offline solve + compile ({machine})")
    print(f"{'model':<6}{'seconds':>10}{'target':>8}{'table B':>10}{'target':>8}{'nodes':>7}{'value':>12}{'lower':>12}{'upper':>12}")
    for r in rows:
        tb = r["target_table_bytes"] or "-"
        print(f"{r['model']:<6}{r['seconds_median']:>10.2f}{r['target_seconds']:>8.0f}{r['table_bytes']:>10}{tb!s:>8}"
              f"{r['nodes']:>7}{r['controller_value']:>12.4f}{r['lower_bound']:>12.4f}{r['upper_bound']:>12.4f}")


if __name__ == "__main__":
    main()
