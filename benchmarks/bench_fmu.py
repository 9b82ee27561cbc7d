"""FMU benchmarks: the C core's cost per cycle, and the closed loop's speed in FMPy.

    python3 benchmarks/bench_fmu.py [--json]

1. C step: rg_core.c with the shipped m1 and m2 tables compiled in (gcc -O2, as in the FMU),
   driven by a C harness over a varied input sequence (obstacle approaching, noise,
   dropouts, disagreements), timed with clock_gettime around 1,000,000 steps; the figure
   is the mean over the run, best of 5 runs. Target: at most 1 us per cycle.
2. Closed loop: `railguard cosim` of the shipped scenarios with 10 ms communication steps
   (train FMU every step, monitor FMU every 100 ms, signals recorded every step), real-time
   factor = simulated time / wall time of the master loop. Target: at least 1,000x.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

HARNESS = r"""
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <time.h>
#include "rg_core.h"
#include "rg_table.h"

static double now(void) { struct timespec ts; clock_gettime(CLOCK_MONOTONIC, &ts); return ts.tv_sec + ts.tv_nsec * 1e-9; }

int main(void)
{
    rg_config cfg; rg_table t; rg_state s; rg_inputs in; rg_outputs out;
    long n = 1000000, k; int run, i; double best = 1e9; long checksum = 0; unsigned x = 12345u;
    char msg[200];
    rg_config_default(&cfg);
    t.bytes = RG_TABLE_BYTES; t.length = RG_TABLE_LENGTH; t.action_offset = RG_TABLE_ACTION_OFFSET;
    t.next_offset = RG_TABLE_NEXT_OFFSET; t.risk_offset = RG_TABLE_RISK_OFFSET; t.nodes = RG_TABLE_NODES; t.observations = RG_TABLE_OBSERVATIONS;
    t.index_bytes = RG_TABLE_INDEX_BYTES; t.start = RG_TABLE_START; t.model = RG_TABLE_MODEL; t.period_ms = RG_TABLE_PERIOD_MS;
    if (rg_table_check(&t, &cfg, msg, sizeof msg)) { printf("table refused: %s\n", msg); return 1; }
    for (run = 0; run < 5; run++) {
        double t0, dt;
        rg_initial_state(&t, &cfg, &s);
        t0 = now();
        for (k = 0; k < n; k++) {
            long phase = k % 600;                     /* a 60 s approach, repeated */
            int32_t dist = (int32_t)(6000 - phase * 10);
            in.train.speed_cms = phase < 500 ? 2000 : 0; in.train.track = 0; in.train.brake = 0; in.overruns = 0;
            for (i = 0; i < 6; i++) {
                x = x * 1103515245u + 12345u;
                in.reports[i].heard = 1;
                in.reports[i].status = (x >> 28) == 0 ? 0 : 1;  /* 1 in 16 reports: a miss */
                in.reports[i].distance_dm = dist + (int32_t)((x >> 16) & 7);
                in.reports[i].closing_cms = 2000;
                in.reports[i].obstacle = 0;
                in.reports[i].tick = (x >> 24) == 0 ? k * 100 - 1000 : k * 100;  /* rare stale report */
            }
            rg_step(&cfg, &t, &s, &in, (int64_t)k * 100, &out);
            checksum += out.demand + out.node;
        }
        dt = now() - t0;
        if (dt < best) best = dt;
    }
    printf("%.3f %ld\n", best / n * 1e9, checksum);
    return 0;
}
"""


def bench_c_step(model: str) -> float:
    from fmu import build, generate
    from monitor.core.table import decode
    from monitor.tables import read

    data = read(model)
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        (d / "rg_table.h").write_text(generate.table_header(decode(data), data))
        (d / "bench.c").write_text(HARNESS)
        exe = d / "bench"
        core = build.C_DIR / "core"
        subprocess.run([build.compiler(), "-std=c99", "-O2", f"-I{core}", f"-I{d}", str(d / "bench.c"),
                        str(core / "rg_core.c"), str(core / "rg_sha256.c"), "-o", str(exe)], check=True)
        out = subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout.split()
    return float(out[0])


def bench_cosim(scenario_name: str, tmp: Path, monitor_fmus: dict, train_fmu: Path) -> dict:
    from fmu import cosim, scenario

    scen = scenario.load(scenario_name)
    result = cosim.run(monitor_fmus[scen.table], train_fmu, scen.train, scen.monitor, scen.duration_s, 0.01)
    return {"scenario": scenario_name, "outcome": result.outcome, "steps": result.steps,
            "simulated_s": result.simulated_s, "wall_s": round(result.wall_s, 4),
            "realtime_factor": round(result.realtime_factor, 1)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = ap.parse_args()
    from fmu import build
    from monitor.tables import read

    figures = {"c_step_ns": {m: round(bench_c_step(m), 1) for m in ("m1", "m2")}, "cosim": []}
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        fmus = {m: build.build_monitor(read(m), 2, t) for m in ("m1", "m2")}
        train = build.build_train(t)
        for name in ("static-600m-20", "train-ahead-500m-25", "no-obstacle"):
            figures["cosim"].append(bench_cosim(name, t, fmus, train))
    if args.json:
        print(json.dumps(figures))
    else:
        for m, ns in figures["c_step_ns"].items():
            print(f"C core step ({m} table): {ns:.1f} ns per cycle (target <= 1000 ns)")
        for r in figures["cosim"]:
            print(f"cosim {r['scenario']:16s} {r['outcome']:12s} {r['steps']} steps of 10 ms in {r['wall_s']:.3f} s "
                  f"= {r['realtime_factor']:,.0f}x real time (target >= 1,000x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
