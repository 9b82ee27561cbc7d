"""`railguard build-fmu`: the monitor (or the train-dynamics) FMU, or both and the SSP of
the closed loop."""
from __future__ import annotations

import argparse
from pathlib import Path

from monitor.tables import DEFAULT

from .. import options
from ..setup import braking_config, table_bytes


def build_fmu(args: argparse.Namespace) -> int:
    from fmu import build

    cfg = braking_config(args)
    out = Path(args.out)
    if args.ssp is not None:
        from fmu import scenario, ssp

        scen = scenario.load(args.ssp or None)
        monitor_fmu = build.build_monitor(table_bytes(args.table or scen.table), 2, out, config=cfg)
        train_fmu = build.build_train(out)
        path = ssp.write(out / f"railguard-{scen.name}.ssp", train_fmu, monitor_fmu, scen.train, scen.monitor,
                         scen.duration_s, name=f"railguard-{scen.name}")
        files = [monitor_fmu, train_fmu, path]
    elif args.train:
        files = [build.build_train(out)]
    else:
        files = [build.build_monitor(table_bytes(args.table or DEFAULT), args.fmi, out, config=cfg)]
    for f in files:
        print(f)
    return 0


def register(sub) -> None:
    from fmu.scenario import DEFAULT as COSIM_DEFAULT

    b = sub.add_parser(
        "build-fmu",
        help="build the monitor (or the train-dynamics) FMU and print the path of every file written",
        description="Generate the C core with the policy table compiled in, wrap it as an FMI 2.0 or 3.0 "
                    "Co-Simulation FMU with its sources and the linux64 binary (gcc -std=c99 -Wall -Wextra "
                    "-Werror -pedantic), and print the path of every file written, one per line.",
    )
    b.add_argument("--table", "--model", dest="table", metavar="m1|m2|FILE",
                   help=f"{options.TABLE_HELP} (default: {DEFAULT}; with --ssp, the scenario's)")
    b.add_argument("--fmi", type=int, choices=[2, 3], default=2, help="FMI version (default: %(default)s)")
    b.add_argument("--train", action="store_true", help="build the train-dynamics FMU (FMI 2.0) instead")
    b.add_argument("--braking", metavar="FILE.toml",
                   help=options.BRAKING_HELP + "; it becomes the monitor FMU's parameter start values")
    b.add_argument("--ssp", nargs="?", const="", metavar="SCENARIO",
                   help="build both FMUs and the SSP of the closed loop for a cosim scenario (default scenario: "
                        f"{COSIM_DEFAULT}); runs with fmpy.ssp.simulate_ssp at a 0.1 s step")
    options.add_out(b)
    b.set_defaults(func=build_fmu)
