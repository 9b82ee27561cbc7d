"""Options and argument types that several subcommands share, each written once, every
default shown in `--help`."""
from __future__ import annotations

import argparse

from monitor.tables import DEFAULT as DEFAULT_TABLE
from monitor.tables import SHIPPED

OUT = "railguard-out"
BRAKING_HELP = ("the train's braking declaration (TOML, SI units: guaranteed decelerations, build-up "
                "times, speed error, adhesion factors, gradient, standstill margin; docs/supervision.md) "
                "(default: the papers' train, monitor/trains/papers-train.toml)")
TABLE_HELP = f"policy table: a shipped one ({', '.join(SHIPPED)}) or a .table.rgt file"


def _positive(convert, kind: str):
    """An argparse type: `convert(text)`, finite and > 0, or a one-line usage error."""
    def parse(text: str):
        try:
            value = convert(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {kind}") from None
        if not 0 < value < float("inf"):
            raise argparse.ArgumentTypeError(f"{text!r} must be a finite number > 0")
        return value

    parse.__name__ = convert.__name__
    return parse


positive_int = _positive(int, "a whole number")
positive_float = _positive(float, "a number")


def workers(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if not 1 <= n <= 1024:
        raise argparse.ArgumentTypeError(f"{text!r} must be 1..1024")
    return n


def add_table(p: argparse.ArgumentParser, default: str | None = DEFAULT_TABLE, extra: str = "") -> None:
    shown = f"default: {default}" if default else extra
    p.add_argument("--table", default=default, metavar="m1|m2|FILE", help=f"{TABLE_HELP} ({shown})")


def add_monitor(p: argparse.ArgumentParser) -> None:
    """The monitor as it runs online: its table, the train's declaration, its configuration."""
    add_table(p)
    p.add_argument("--braking", metavar="FILE.toml", help=BRAKING_HELP)
    p.add_argument("--monitor-config", metavar="FILE.toml",
                   help="monitor configuration ([monitor] table: timeout_cycles, persistence_cycles, "
                        "emergency_release, ... see docs/core.md) (default: the built-in configuration)")


def add_bus(p: argparse.ArgumentParser, real_only: bool = False) -> None:
    fallback = "none: a real bus is required" if real_only else "the in-process virtual bus"
    p.add_argument("--interface", help="python-can interface (socketcan, virtual, pcan, ...) (default: python-can's "
                                       f"environment/config file, else {fallback})")
    p.add_argument("--channel", help="python-can channel, e.g. vcan0 (default: vcan0 for socketcan)")


def add_security(p: argparse.ArgumentParser, simulated: bool = True) -> None:
    """--keys / --unsecured: whether the bus is secured (issue 39), and with which key set."""
    g = p.add_mutually_exclusive_group()
    default = ("on the in-process bus a test key set in OUT/test-keys, made on first use; on a real bus one of "
               "the two options is required" if simulated else "one of the two options is required")
    g.add_argument("--keys", metavar="DIR", help="key set of a secured bus (railguard keys new DIR): every frame is a "
                                                 "CAN FD frame with a CMAC-AES-128 authenticator and a freshness "
                                                 f"value (docs/can.md) (default: {default})")
    g.add_argument("--unsecured", action="store_true",
                   help="an unsecured bus: classical frames with E2E only (old logs, legacy sensors); any node can "
                        "forge or replay frames, and the summary, MonitorRisk and the plot say so")


def add_out(p: argparse.ArgumentParser, default: str = OUT, what: str = "output folder") -> None:
    p.add_argument("--out", default=default, metavar="DIR", help=f"{what} (default: %(default)s)")


def add_json(p: argparse.ArgumentParser, what: str = "print one JSON object instead of text") -> None:
    p.add_argument("--json", action="store_true", help=what)


def add_cluster(p: argparse.ArgumentParser, default: str = "one per core", what: str = "") -> None:
    p.add_argument("--workers", type=workers, metavar="N",
                   help=f"{what}worker processes of a local dask cluster (default: {default}; 1 runs in this process)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on an existing dask.distributed cluster, e.g. tcp://10.0.0.5:8786 (its workers need "
                        "railguard installed; results are identical to a local run) (default: a local cluster)")


def add_world_train(p: argparse.ArgumentParser, default: str) -> None:
    p.add_argument("--world-train", metavar="FILE.toml",
                   help="the simulated world's train, independent of the monitor's declaration (a [world_train] "
                        "table: emergency_decel, service_decel, brake_delay, brake_buildup, gradient, traction_cutoff, "
                        "max_traction, speed_error, davis_a/b/c, mass, sensor_latency_s, output_latency_s; "
                        f"verification/world_train.py) (default: {default})")


def add_unsafe_margin(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument("--unsafe-margin", type=float, default=0.0, metavar="M", help=f"{what} (default: %(default)s)")
