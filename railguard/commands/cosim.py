"""`railguard cosim`: the train-dynamics FMU and the monitor FMU closed in FMPy."""
from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

from .. import options, output
from ..errors import UserError
from ..setup import table_bytes
from .scenarios import shipped_help


def _summary(scen, result, args: argparse.Namespace, csv_path, plot_path) -> dict:
    from fmu.cosim import risk_summary

    return {
        "scenario": scen.name, "outcome": result.outcome,
        "margin_m": None if result.margin_m is None else round(result.margin_m, 3),
        "steps": result.steps, "monitor_cycles": result.monitor_cycles, "step_s": args.step,
        "simulated_s": round(result.simulated_s, 3), "wall_s": round(result.wall_s, 4),
        "realtime_factor": round(result.realtime_factor, 1),
        "first_brake_s": result.first_brake_s, "max_demand": result.max_demand,
        "demand_delay_cycles": result.demand_delay_cycles,
        "stop_margin_m": None if result.stop_margin_m is None else round(result.stop_margin_m, 3),
        "impact_speed": round(result.impact_speed, 3),
        "receiver_brake": result.receiver_brake,   # the train's brake receiver braked: the monitor's cycle stopped
        "risk": risk_summary(result),
        "csv": str(csv_path), "plot": None if plot_path is None else str(plot_path),
        "files": output.files_of(csv_path, plot_path),
    }


def cosim(args: argparse.Namespace) -> int:
    from fmu import build, scenario
    from fmu import cosim as loop
    from monitor.risk_summary import risk_line

    scen = scenario.load(args.scenario)
    if args.braking:
        from monitor.declaration import load

        scen = scenario.with_braking(scen, load(args.braking), args.braking)
    if args.bus == "ls-bus":
        from .cosim_bus import cosim_ls_bus

        return cosim_ls_bus(args, scen)
    bus_only = [f"--{n.replace('_', '-')}" for n in ("flood_id", "flood_start", "flood_stop", "error_id", "error_count",
                                                      "keys", "unsecured") if getattr(args, n) is not None and getattr(args, n) is not False]
    if bus_only:
        raise UserError(f"{', '.join(bus_only)}: options of --bus ls-bus (the signal co-simulation has no frames)")
    out = Path(args.out)
    with tempfile.TemporaryDirectory(prefix="railguard-cosim-") as tmp:
        monitor_fmu = args.monitor_fmu or build.build_monitor(table_bytes(args.table or scen.table), args.fmi, tmp)
        train_fmu = args.train_fmu or build.build_train(tmp)
        result = loop.run_scenario(scen, monitor_fmu, train_fmu, args.step, args.demand_delay)
    csv_path = loop.write_csv(result, out / f"cosim-{scen.name}.csv")
    plot_path = None if args.no_plot else loop.plot(result, out / f"cosim-{scen.name}.png",
                                                    f"railguard co-simulation: {scen.name}")
    if args.json:
        print(json.dumps(_summary(scen, result, args, csv_path, plot_path)))
        return 0
    margin = "" if result.margin_m is None else f", margin {result.margin_m:.1f} m"
    brake = "never braked" if result.first_brake_s is None else f"first brake demand at {result.first_brake_s:.1f} s"
    print(f"{scen.name}: {result.outcome}{margin}; {brake}; {result.steps} steps of {args.step * 1000:g} ms "
          f"({result.monitor_cycles} monitor cycles) in {result.wall_s:.2f} s = {result.realtime_factor:,.0f}x real time")
    print(risk_line(loop.risk_summary(result)))
    output.wrote([csv_path, plot_path])
    return 0


def register(sub) -> None:
    c = sub.add_parser(
        "cosim",
        help="co-simulate the train-dynamics FMU and the monitor FMU in FMPy",
        description="Build both FMUs (unless given), close the loop in FMPy with a master over FMPy's slave "
                    "classes (train every --step, monitor every 100 ms), write a CSV of all signals and a plot, "
                    "and print the outcome and the speed as a real-time factor. FMU log lines go to stderr. "
                    "With --bus ls-bus the monitor and the train are network FMUs exchanging the DBC frames of "
                    "vcan0 through FMI-LS-BUS CAN terminals and our bus simulation FMU (arbitration by ID, bit "
                    "timing at 500 kbit/s, transmit queues, error frames, a babbling node), packed by "
                    "fmu-manipulation-toolbox's fmucontainer and run by FMPy; the summary gives the queue delay "
                    "per ID and the bus load, and an SSP of the same system is written (docs/fmu.md).",
        epilog=lambda: shipped_help("cosim"),
    )
    from fmu.scenario import DEFAULT

    c.add_argument("scenario", nargs="?", default=DEFAULT, metavar="SCENARIO",
                   help="a shipped scenario (listed below) or a .toml file (default: %(default)s)")
    options.add_table(c, None, "default: the scenario's table, else m2")
    c.add_argument("--fmi", type=int, choices=[2, 3], default=2, help="FMI version of the monitor FMU (default: %(default)s)")
    c.add_argument("--step", type=options.positive_float, default=0.01, metavar="S",
                   help="communication step of the train FMU in seconds; this master steps the monitor FMU "
                        "every 100 ms, so the step must divide 0.1 s (the FMUs themselves take any step: "
                        "docs/fmu.md) (default: %(default)s)")
    c.add_argument("--monitor-fmu", metavar="FILE", help="use this monitor FMU instead of building one (default: build it)")
    c.add_argument("--train-fmu", metavar="FILE", help="use this train FMU instead of building one (default: build it)")
    c.add_argument("--braking", metavar="FILE.toml", help=options.BRAKING_HELP + "; replaces the scenario's [braking]")
    c.add_argument("--demand-delay", type=int, metavar="CYCLES",
                   help="monitor cycles before the train acts on a demand (default: the scenario's, else 1: as on CAN)")
    c.add_argument("--bus", choices=["signals", "ls-bus"], default="signals",
                   help="signals: the FMUs' signals in a master loop; ls-bus: CAN frames over the simulated bus "
                        "(FMI-LS-BUS) (default: %(default)s)")
    g = c.add_argument_group("--bus ls-bus")
    g.add_argument("--flood-id", type=lambda x: int(x, 0), metavar="ID",
                   help="a babbling node sends this ID back to back (0x000 outranks every frame: BrakeDemand "
                        "starves) (default: none)")
    g.add_argument("--flood-start", type=float, metavar="S", help="when the babbling node starts (default: 0)")
    g.add_argument("--flood-stop", type=float, metavar="S", help="when it stops (default: never)")
    g.add_argument("--error-id", type=lambda x: int(x, 0), metavar="ID",
                   help="the next transmissions of this ID end in an error frame and are sent again (default: none)")
    g.add_argument("--error-count", type=options.positive_int, metavar="N",
                   help="how many of them (default: 1 with --error-id)")
    options.add_security(g)
    options.add_out(c, what="folder for the CSV and the plot")
    c.add_argument("--no-plot", action="store_true", help="do not draw the plot")
    options.add_json(c, "print the outcome as one JSON object")
    c.set_defaults(func=cosim, signal_defaults={"fmi": 2, "step": 0.01})
