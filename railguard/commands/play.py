"""`railguard play`: the scenario player alone on a real bus (the monitor runs elsewhere)."""
from __future__ import annotations

import argparse

from .. import options, output
from ..errors import UserError
from ..setup import bus_keys, bus_kwargs
from .scenarios import shipped_help


def play(args: argparse.Namespace) -> int:
    import signal
    import threading

    from can_bus import scenario as scenarios
    from can_bus.clock import WallClock
    from can_bus.player import Player
    from can_bus.security import describe
    from can_bus.session import open_bus, play_loop

    scen = scenarios.load(args.scenario)
    bus_cfg = bus_kwargs(args)
    if bus_cfg is None:
        raise UserError("play needs a real bus: give --interface and --channel (e.g. --interface socketcan "
                        "--channel vcan0); on the in-process bus use `railguard run`, which plays with the monitor")
    keys = bus_keys(args, real_bus=True)
    security = None
    if keys is not None:
        from can_bus.keys import SENDERS
        from can_bus.security import for_node

        security = for_node(keys, "player", SENDERS)   # sensors' and train's keys; the monitor's for the brake side
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    opened = [open_bus(bus_cfg)]
    try:
        player = Player(opened[0], scen, args.period, wait_for_monitor=not args.no_wait)
        player.secure(security)
        if player.wants_hostile:                 # the hostile faults: a second node, its own connection
            opened.append(open_bus(bus_cfg))
            player.join_hostile(opened[-1])
        play_loop(player, WallClock(), stop, None if args.no_wait else round(args.wait_limit * 1000))
    finally:
        for bus in opened:
            bus.shutdown()
        if security is not None:
            security.save()
    summary = dict(player.outcome(), scenario=scen.name, bus_security=describe(security), frames_sent=player.frames_sent, late_periods=player.late_periods,
                   faults_injected=sorted(f"{k}@ch{c}" for k, c in player.faults_injected))
    output.summary(summary, args.json)
    return 0


def register(sub) -> None:
    pl = sub.add_parser(
        "play",
        help="run the scenario player alone on a real bus (the monitor runs elsewhere)",
        description="Simulate the train and the six sensor channels of a scenario on a real bus, in real time. "
                    "The train waits at the entry until the monitor reports NORMAL with no demand (at most "
                    "--wait-limit seconds, then exit 2). A player that wakes up late (a busy host) moves the "
                    "train through the missed periods without sending them in a burst; their number is "
                    "`late_periods` in the outcome. A bus is "
                    "required (--interface and --channel, or python-can's configuration): the in-process bus "
                    "is private to one process. Writes no files.",
        epilog=lambda: shipped_help("run"),
    )
    pl.add_argument("scenario", metavar="SCENARIO", help="a shipped scenario name or a .toml file")
    options.add_bus(pl, real_only=True)
    options.add_security(pl, simulated=False)
    pl.add_argument("--period", type=options.positive_int, default=100, metavar="MS",
                    help="send period in ms (default: %(default)s)")
    pl.add_argument("--no-wait", action="store_true", help="start at once, do not wait for the monitor")
    pl.add_argument("--wait-limit", type=options.positive_float, default=60.0, metavar="S",
                    help="give up (exit 2) if the monitor has not reported NORMAL with no demand after S seconds "
                         "(default: %(default)g)")
    options.add_json(pl, "print the outcome as one JSON object")
    pl.set_defaults(func=play)
