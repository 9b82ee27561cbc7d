"""Cost of one online `step` (3oo3, six channels) in CPython: median and p99.

Run: python benchmarks/bench_core.py [--cycles N] [--model m1|m2] [--json]
Target (issue 3): median <= 30 us (0.03 % of a core at the 100 ms cycle).
The input sequence is a scripted approach with noise-free reports, a silent channel now
and then, and a stop, so that every branch of the cycle (INIT, NORMAL, DEGRADED, envelope,
latch) is exercised; it is built before timing starts.
"""
from __future__ import annotations

import argparse
import json
import platform
import time
from importlib import resources

from monitor.core import cycle
from monitor.core.config import Config
from monitor.core.types import ABSENT, PRESENT, Inputs, Report, Train


def scenario(cycles: int, period: int) -> list:
    seq = []
    speed = 4000
    for i in range(cycles):
        tick = i * period
        phase = i % 3000
        distance = 12000 - phase * 4            # obstacle approaching, 40 cm per cycle
        present = 200 <= phase < 2800
        reports = []
        for ch in range(6):
            silent = ch == 3 and phase % 500 == 7   # one stale report every 50 s
            rtick = tick - 400 if silent else tick
            reports.append(Report(PRESENT if present else ABSENT, max(0, distance), 3000, 0, rtick))
        speed = 0 if phase == 2900 else (4000 if phase == 0 else speed)
        seq.append((tick, Inputs(tuple(reports), Train(speed, 0, 0), 0)))
    return seq


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cycles", type=int, default=200_000)
    ap.add_argument("--model", choices=["m1", "m2"], default="m2")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    table = resources.files("monitor.tables").joinpath(f"{args.model}.table.rgt").read_bytes()
    setup = cycle.create(Config(), table)
    seq = scenario(args.cycles, setup.config.period_ms)
    state = cycle.initial_state(setup)
    step = cycle.step
    clock = time.perf_counter_ns
    samples = []
    for tick, inputs in seq:
        t0 = clock()
        state, _ = step(setup, state, inputs, tick)
        samples.append(clock() - t0)
    samples.sort()
    n = len(samples)
    res = {
        "model": args.model,
        "cycles": n,
        "median_us": samples[n // 2] / 1000,
        "p99_us": samples[int(n * 0.99)] / 1000,
        "max_us": samples[-1] / 1000,
        "target_median_us": 30.0,
        "python": platform.python_version(),
    }
    if args.json:
        print(json.dumps(res))
    else:
        print(f"core step, 3oo3 six channels, table {args.model}, {n} cycles, CPython {res['python']}")
        print(f"median {res['median_us']:.2f} us   p99 {res['p99_us']:.2f} us   max {res['max_us']:.1f} us   (target median <= 30 us)")


if __name__ == "__main__":
    main()
