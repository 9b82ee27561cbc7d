"""Cost of the co-simulation over the simulated CAN bus (issue 42): the monitor node, the train
node and the bus simulation FMU in an fmucontainer FMU run by FMPy (`railguard cosim --bus
ls-bus`), quiet and under a babbling node at 0x000 (a frame every 254 us: the worst event
rate), as simulated seconds per wall second and wall time per frame on the bus. The FMUs and
the containers are built once, outside the timing.

Run: python benchmarks/bench_lsbus.py [--runs N] [--json]
"""
from __future__ import annotations

import argparse
import json
import platform
import statistics
import tempfile
import time
from pathlib import Path

from fmu import lsbus_system as S
from fmu import scenario
from fmu.bus_timing import read_trace
from fmu.network_nodes import build_monitor_node
from fmu.train_node import build_train_node
from monitor import tables


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=5, help="timed runs per case (default: %(default)s)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args()
    scen = scenario.load("static-obstacle")
    out = {"machine": platform.processor() or platform.machine(), "scenario": scen.name,
           "simulated_s": scen.duration_s, "container_step_us": S.STEP_S * 1e6}
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        monitor = build_monitor_node(tables.read(scen.table), d)
        train = build_train_node(d, scen.train)
        bus = S.build_bus(2, d)
        for case, starts in (("quiet", {}), ("flood_0x000_20_to_40_s", {("canbus.fmu", "flood_id"): 0,
                                                                       ("canbus.fmu", "flood_start"): 20.0,
                                                                       ("canbus.fmu", "flood_stop"): 40.0})):
            trace = d / f"{case}.csv"
            container = S.build_container([S.Node(monitor), S.Node(train)], bus, d / f"{case}.fmu", S.STEP_S,
                                          {("canbus.fmu", "trace_file"): str(trace), **starts})
            walls = []
            for _ in range(args.runs):
                t = time.perf_counter()
                S.run_container(container, scen.duration_s, 1.0)
                walls.append(time.perf_counter() - t)
            frames = sum(1 for r in read_trace(trace) if r["kind"] == "delivered")
            wall = statistics.median(walls)
            out[case] = {"wall_s_median": round(wall, 3), "wall_s_min": round(min(walls), 3),
                         "realtime_factor": round(scen.duration_s / wall, 1), "frames_on_the_bus": frames,
                         "wall_us_per_frame": round(wall / frames * 1e6, 2)}
    if args.json:
        print(json.dumps(out))
        return
    print(f"{out['scenario']}, {out['simulated_s']:g} s simulated, container step {out['container_step_us']:g} us, "
          f"median of {args.runs} runs on {out['machine']}:")
    for case in ("quiet", "flood_0x000_20_to_40_s"):
        f = out[case]
        print(f"  {case:<24} {f['wall_s_median']:.3f} s wall = {f['realtime_factor']:,.0f}x real time; "
              f"{f['frames_on_the_bus']:,} frames on the bus, {f['wall_us_per_frame']:.2f} us wall per frame")


if __name__ == "__main__":
    main()
