"""`railguard run`: the cyclic monitor on CAN, with the scenario player on the in-process
bus by default, or on a real bus (SocketCAN vcan0, a HIL rig) in real time."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .. import options, output
from ..errors import UserError
from ..setup import bus_keys, bus_kwargs, monitor_setup
from .scenarios import shipped_help


def run(args: argparse.Namespace) -> int:
    from can_bus import scenario as scenarios
    from can_bus import session

    setup = monitor_setup(args)
    scen = None if args.no_player else scenarios.load(args.scenario)
    bus = bus_kwargs(args)
    out = Path(args.out)
    show = output.status_printer(args.json or args.quiet)
    if bus is None and scen is None:
        raise UserError("--no-player needs a real bus (--interface/--channel): on the in-process bus nothing would send")
    keys = bus_keys(args, bus is not None, out)
    if bus is None:
        result = session.run_virtual(setup, scen, out, show=show, plot=not args.no_plot, duration_s=args.duration,
                                     keys=keys)
    else:
        result = session.run_on_bus(setup, bus, out, scenario=scen, duration_s=args.duration, show=show,
                                    plot=not args.no_plot, name=scen.name if scen else str(bus.get("channel")),
                                    keys=keys)
    summary = result.summary
    output.summary(summary, args.json, show is not None and sys.stderr.isatty())
    if not args.json:
        output.wrote([summary.get("log"), summary.get("plot")])
    return 0


def register(sub) -> None:
    r = sub.add_parser(
        "run",
        help="run the cyclic monitor on CAN (default: with the scenario player on the in-process bus)",
        description="Run the monitor: every period drain the bus, latch the newest valid report per channel, "
                    "step the core, send BrakeDemand, MonitorStatus and MonitorTrack. With no bus options the monitor and the "
                    "built-in scenario player share python-can's in-process virtual bus on a simulated clock "
                    "(deterministic, as fast as the CPU allows). Writes a candump .log of the bus and a plot, "
                    "prints a summary. SIGINT/SIGTERM: a last emergency demand, the summary, exit 0. A run that "
                    "ends before its scenario does (--duration, a signal) has outcome 'incomplete'.",
        epilog=lambda: shipped_help("run"),
    )
    options.add_monitor(r)
    options.add_bus(r)
    options.add_security(r)
    r.add_argument("--scenario", default="static-obstacle", metavar="NAME|FILE.toml",
                   help="scenario for the player: a shipped one (listed below) or a TOML file (default: %(default)s)")
    r.add_argument("--no-player", action="store_true", help="monitor only (a real bus where others send)")
    r.add_argument("--duration", type=options.positive_float, metavar="S",
                   help="stop after S seconds of monitor time (default: the scenario's duration; on a real bus "
                        "without the player, until SIGINT/SIGTERM)")
    options.add_out(r, what="folder for the .log and the plot")
    r.add_argument("--no-plot", action="store_true", help="do not draw the plot")
    r.add_argument("--quiet", action="store_true", help="no live status line")
    options.add_json(r, "print the summary as one JSON object")
    r.set_defaults(func=run)
