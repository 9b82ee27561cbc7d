"""`railguard cosim SCENARIO --bus ls-bus`: the monitor and the train as network FMUs on our
CAN bus simulation (FMI-LS-BUS), in an fmucontainer FMU run by FMPy (fmu/lsbus_cosim.py)."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from .. import output
from ..errors import UserError
from ..setup import bus_keys, table_bytes

SIGNAL_ONLY = ("fmi", "step", "monitor_fmu", "train_fmu", "demand_delay")


def faults_of(args: argparse.Namespace):
    from fmu.lsbus_cosim import BusFaults

    for name in ("flood_id", "error_id"):
        value = getattr(args, name)
        if value is not None and not 0 <= value <= 0x7FF:
            raise UserError(f"--{name.replace('_', '-')} {value:#x}: an 11-bit CAN identifier is 0x000..0x7FF")
    if args.flood_id is None and (args.flood_start is not None or args.flood_stop is not None):
        raise UserError("--flood-start/--flood-stop need --flood-id")
    start = args.flood_start if args.flood_start is not None else 0.0
    stop = args.flood_stop if args.flood_stop is not None else 1e9
    if stop <= start:
        raise UserError(f"--flood-stop {stop} must be after --flood-start {start}")
    if args.error_id is None and args.error_count:
        raise UserError("--error-count needs --error-id")
    return BusFaults(-1 if args.flood_id is None else args.flood_id, start, stop,
                     -1 if args.error_id is None else args.error_id, args.error_count or (1 if args.error_id else 0))


def summary(run, csv_path, plot_path) -> dict:
    t = run.timing
    brake = t.ids.get(0x10)
    return {
        "scenario": run.scenario, "bus": "ls-bus", "outcome": run.outcome,
        "margin_m": None if run.margin_m is None else round(run.margin_m, 3),
        "stop_position_m": round(run.stop_position_m, 3), "first_brake_s": run.first_brake_s,
        "max_demand": run.max_demand, "receiver_brake_s": run.receiver_brake_s, "secured": run.secured,
        "faults": run.faults.starts(), "simulated_s": run.simulated_s, "wall_s": round(run.wall_s, 3),
        "brake_demand_max_queue_delay_ms": None if brake is None else round(brake.max_delay_s * 1e3, 3),
        "brake_demand_max_gap_ms": None if brake is None else round(brake.max_gap_s * 1e3, 3),
        **t.as_dict(),
        "csv": str(csv_path), "trace": str(run.trace), "plot": None if plot_path is None else str(plot_path),
        "container": str(run.container), "ssp": str(run.ssp),
        "files": output.files_of(csv_path, run.trace, plot_path, run.container, run.ssp),
    }


def cosim_ls_bus(args: argparse.Namespace, scen) -> int:
    from fmu import lsbus_cosim as bus

    given = [f"--{n.replace('_', '-')}" for n in SIGNAL_ONLY
             if getattr(args, n) is not None and getattr(args, n) != args.signal_defaults.get(n)]
    if given:
        raise UserError(f"{', '.join(given)}: options of the signal co-simulation, not of --bus ls-bus")
    faults = faults_of(args)
    out = Path(args.out)
    keys = bus_keys(args, False, out)
    run = bus.run_scenario(scen, table_bytes(args.table or scen.table), out / f"lsbus-{scen.name}", keys, faults)
    csv_path = bus.write_csv(run, out / f"cosim-lsbus-{scen.name}.csv")
    plot_path = None if args.no_plot else bus.plot(run, out / f"cosim-lsbus-{scen.name}.png")
    data = summary(run, csv_path, plot_path)
    if args.json:
        print(json.dumps(data))
        return 0
    margin = "" if run.margin_m is None else f", margin {run.margin_m:.1f} m"
    first = "never braked" if run.first_brake_s is None else f"first brake demand at {run.first_brake_s:.1f} s"
    receiver = ("" if run.receiver_brake_s is None else
                f"; the train's brake receiver braked on silence at {run.receiver_brake_s:.2f} s")
    print(f"{scen.name} on the simulated CAN bus (FMI-LS-BUS, {'secured CAN FD' if run.secured else 'classical'} "
          f"frames, 500 kbit/s): {run.outcome}{margin}, stands at {run.stop_position_m:.1f} m; {first}{receiver}")
    print(f"bus load {run.timing.load:.1%} (peak {run.timing.peak_load:.0%} per 100 ms); "
          f"{run.simulated_s:g} s simulated in {run.wall_s:.2f} s")
    print("ID     frames  errors  dropped  queue delay max / mean (ms)  longest gap (ms)")
    for row in data["ids"]:
        print(f"{row['id']:<6} {row['frames']:>6}  {row['errors']:>6}  {row['dropped']:>7}  "
              f"{row['max_queue_delay_ms']:>14.3f} / {row['mean_queue_delay_ms']:<10.4f} {row['max_gap_ms']:>12.1f}")
    output.wrote([csv_path, run.trace, plot_path, run.container, run.ssp])
    return 0
