"""`railguard cosim SCENARIO --bus ls-bus`: the train node and the monitor node (network FMUs
with FMI-LS-BUS CAN terminals) on our bus simulation FMU, packed by fmucontainer and run by
FMPy; the same scenario, the same C core and the same train model as the signal
co-simulation (fmu/cosim.py), with the frames of vcan0 in between. What the bus did to them
(queue delay per ID, bus load) comes from the bus's trace; the system is also written as an
SSP that fmucontainer reads."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

from .bus_timing import BusTiming, read_trace, timing
from .cosim import NO_GAP_M
from .lsbus_ssp import write as write_ssp
from .lsbus_system import BIT_RATE, STEP_S, Node, build_bus, build_container, run_container
from .network_nodes import DEFAULT_PHASE_MS, build_monitor_node
from .train_node import build_train_node

TRAIN_OUT = ["position", "true_speed", "true_distance", "brake_level", "applied_demand", "impact_speed", "collided",
             "receiver_brake", "receiver_brake_time", "frames_rejected"]
MONITOR_OUT = ["brake_demand", "reasons", "mode", "cycle", "voted_distance_dm"]
PERIOD_S = 0.1
BUS_OUT = ["bus_load", "watch_max_delay", "frames", "errors", "dropped"]
COLUMNS = ["time_s"] + [f"train.{n}" for n in TRAIN_OUT] + [f"monitor.{n}" for n in MONITOR_OUT] + \
          [f"bus.{n}" for n in BUS_OUT]


@dataclass(frozen=True)
class BusFaults:
    """What the bus simulation injects: a babbling node and error frames."""
    flood_id: int = -1
    flood_start_s: float = 0.0
    flood_stop_s: float = 1e9
    error_id: int = -1
    error_count: int = 0

    def starts(self) -> dict:
        return {"flood_id": self.flood_id, "flood_start": self.flood_start_s, "flood_stop": self.flood_stop_s,
                "error_id": self.error_id, "error_count": self.error_count}


@dataclass
class BusRun:
    scenario: str
    outcome: str
    margin_m: Optional[float]
    stop_position_m: float
    first_brake_s: Optional[float]
    max_demand: int
    receiver_brake_s: Optional[float]
    timing: BusTiming
    rows: list = field(repr=False)
    trace: Path = None
    container: Path = None
    ssp: Path = None
    secured: bool = False
    simulated_s: float = 0.0
    wall_s: float = 0.0
    faults: BusFaults = BusFaults()


def outcome_of(final: dict, has_obstacle: bool) -> tuple[str, Optional[float]]:
    """As the signal co-simulation judges its end (fmu/cosim.py)."""
    if final["train.collided"]:
        return ("collision" if final["train.impact_speed"] > 0.0 else "struck_at_standstill"), 0.0
    if not has_obstacle:
        return "no_obstacle", None
    distance = final["train.true_distance"]
    gap = float(distance) if distance < NO_GAP_M else None
    return ("stopped" if final["train.true_speed"] == 0.0 else "running"), gap


def run_scenario(scen, table_bytes: bytes, out_dir: Path, keys: Optional[Path] = None,
                 faults: BusFaults = BusFaults(), record_s: float = 0.01) -> BusRun:
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    monitor = build_monitor_node(table_bytes, out_dir, "monitor.fmu", keys=keys)
    train = build_train_node(out_dir, scen.train, keys=keys, name="train.fmu")
    bus = build_bus(2, out_dir)
    trace = out_dir / f"bus-{scen.name}.csv"
    starts = {("canbus.fmu", k): v for k, v in faults.starts().items()}
    if math.isfinite(scen.monitor_stop_s):
        starts[("monitor.fmu", "stop_time")] = scen.monitor_stop_s
    outputs = ([("train.fmu", n, f"train.{n}") for n in TRAIN_OUT] + [("monitor.fmu", n, f"monitor.{n}")
               for n in MONITOR_OUT] + [("canbus.fmu", n, f"bus.{n}") for n in BUS_OUT])
    container = build_container([Node(monitor), Node(train)], bus, out_dir / f"lsbus-{scen.name}.fmu", STEP_S,
                                {("canbus.fmu", "trace_file"): str(trace), **starts}, outputs)
    ssp = write_ssp(out_dir / f"lsbus-{scen.name}.ssp", bus, [("monitor", monitor, "CAN"), ("train", train, "CAN")],
                    {("canbus", k): v for k, v in faults.starts().items()},
                    [(f.split(".")[0].replace("bus", "canbus"), f.split(".", 1)[1], f) for f in COLUMNS[1:]])
    t0 = time.perf_counter()
    result = run_container(container, scen.duration_s, record_s)
    wall = time.perf_counter() - t0
    names = ["time"] + COLUMNS[1:]
    rows = [tuple(round(float(r["time"]), 6) if c == "time" else float(r[c]) for c in names) for r in result]
    final = dict(zip(COLUMNS, rows[-1]))
    outcome, margin = outcome_of(final, has_obstacle=scen.train.get("obstacle.present", 1) != 0)
    demand = COLUMNS.index("monitor.brake_demand")
    # the first demand after the monitor's start-up, at its cycle's tick (it is decided phase_ms later)
    decided = [r for r in rows if r[0] >= DEFAULT_PHASE_MS / 1000 - 1e-9]      # cycle 0 has run
    braking = [round(round((r[0] - DEFAULT_PHASE_MS / 1000) / PERIOD_S) * PERIOD_S, 6) for r in decided
               if r[demand] > 0]
    receiver = final["train.receiver_brake_time"]
    return BusRun(scen.name, outcome, margin, final["train.position"], braking[0] if braking else None,
                  int(max(r[demand] for r in decided)), receiver if receiver >= 0 else None,
                  timing(read_trace(trace), scen.duration_s, bit_rate=BIT_RATE), rows, trace, container, ssp,
                  keys is not None, scen.duration_s, wall, faults)


def write_csv(run: BusRun, path: Path) -> Path:
    import csv
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(COLUMNS)
        w.writerows(run.rows)
    return path


def plot(run: BusRun, path: Path, watch: tuple = (0x10, 0x20, 0x30, 0x40)) -> Path:
    """Speed and demand, the queue delay of the watched IDs, the bus load per 100 ms."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    t = [r[0] for r in run.rows]
    fig, (a, b, c) = plt.subplots(3, 1, figsize=(10, 8), sharex=True)
    a.plot(t, [r[COLUMNS.index("train.true_speed")] for r in run.rows], label="speed (m/s)")
    a.step(t, [r[COLUMNS.index("monitor.brake_demand")] * 5 for r in run.rows], where="post",
           label="monitor demand (x5)")
    a.step(t, [r[COLUMNS.index("train.applied_demand")] * 5 for r in run.rows], where="post", linestyle="--",
           label="demand the train applies (x5)")
    a.set_ylabel("m/s")
    security = "secured CAN FD" if run.secured else "UNSECURED classical frames"
    a.set_title(f"railguard on a simulated CAN bus (FMI-LS-BUS, {security}): {run.scenario}, {run.outcome}")
    for ax in (a, b, c):
        if run.faults.flood_id >= 0:
            ax.axvspan(run.faults.flood_start_s, min(run.faults.flood_stop_s, t[-1]), color="red", alpha=0.08,
                       label=f"babbling node 0x{run.faults.flood_id:03X}" if ax is a else None)
        if run.receiver_brake_s is not None:
            ax.axvline(run.receiver_brake_s, color="red", linestyle=":",
                       label="the train's receiver brakes on silence" if ax is a else None)
    a.legend(loc="upper right", fontsize=8)
    for fid in watch:
        tm = run.timing.ids.get(fid)
        if tm and tm.delays:
            b.plot([q for q, _ in tm.delays], [d * 1e3 for _, d in tm.delays], ".", markersize=2,
                   label=f"0x{fid:03X}")
    b.set_ylabel("queue delay (ms)")
    b.set_yscale("symlog", linthresh=1.0)
    b.legend(loc="upper right", fontsize=8)
    c.step([w for w, _ in run.timing.load_windows], [x * 100 for _, x in run.timing.load_windows], where="pre")
    c.set_ylabel("bus load per 100 ms (%)")
    c.set_xlabel("time (s)")
    c.set_ylim(0, 105)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
