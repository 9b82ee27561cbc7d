"""The monitor a command runs: its table, the train's braking declaration and its
configuration, read from the user's files with errors that name them."""
from __future__ import annotations

from pathlib import Path

import argparse

from .errors import UserError


def table_bytes(spec: str) -> bytes:
    from monitor.tables import TableNotFound, read

    try:
        return read(spec)
    except TableNotFound as exc:
        raise UserError(str(exc)) from None


def with_braking(cfg, args: argparse.Namespace):
    """`cfg` with the train's braking declaration from --braking (None: the shipped train's)."""
    from monitor.declaration import config_with

    return config_with(cfg, getattr(args, "braking", None))


def braking_config(args: argparse.Namespace):
    """The monitor configuration with --braking, or None when it was not given."""
    from monitor.core.config import Config

    return with_braking(Config(), args) if getattr(args, "braking", None) else None


def monitor_setup(args: argparse.Namespace):
    """The core's setup from --table, --braking and --monitor-config."""
    from monitor.core import config as core_config
    from monitor.core import cycle
    from monitor.core.config import ConfigurationError
    from monitor.offline.params import read_toml

    values = {}
    where = "monitor configuration"
    if args.monitor_config:
        where = args.monitor_config
        data = read_toml(args.monitor_config)
        values = data.get("monitor", data)
        if not isinstance(values, dict):
            raise UserError(f"{args.monitor_config}: [monitor] must be a table")
    try:
        cfg = core_config.from_mapping(values)
    except (TypeError, ConfigurationError) as exc:
        raise UserError(f"{where}: {exc}") from None
    return cycle.create(with_braking(cfg, args), table_bytes(args.table))


def bus_kwargs(args: argparse.Namespace) -> dict | None:
    """python-can's usual configuration: --interface/--channel, else its environment
    variables and config files; None if nothing names a bus (then: in-process virtual)."""
    import can

    given = {k: v for k, v in (("interface", args.interface), ("channel", args.channel)) if v}
    try:
        cfg = can.util.load_config(config=given)
    except can.CanInterfaceNotImplementedError as exc:
        if given:
            raise UserError(str(exc)) from None
        return None
    if not cfg.get("interface"):
        return None
    cfg.setdefault("channel", "vcan0" if cfg["interface"] == "socketcan" else "railguard")
    if cfg["interface"] == "virtual":
        cfg.setdefault("receive_own_messages", False)
    return cfg


def bus_keys(args: argparse.Namespace, real_bus: bool, out: Path | None = None) -> Path | None:
    """The key set a command's bus is secured with, None if --unsecured. Without either option:
    on the in-process bus a test set in OUT/test-keys (made on first use); on a real bus test
    keys are never a default, so the user must choose."""
    from can_bus import keys
    from can_bus.security import made_test_keys

    if args.unsecured:
        return None
    if args.keys is not None:
        keys.load(args.keys)                   # every key checked now: one error line, not a failure mid-run
        return Path(args.keys)
    if real_bus or out is None:
        raise UserError("a real bus needs --keys DIR (a key set: railguard keys new DIR) or --unsecured "
                        "(E2E only: any node can forge or replay frames)")
    return made_test_keys(out / "test-keys")


def cluster(args: argparse.Namespace, default_workers: int = 0):
    """The dask cluster of --workers/--scheduler, checked before any work starts."""
    from verification.scale import Cluster, check

    c = Cluster(args.workers or default_workers, args.scheduler)
    check(c)
    return c
