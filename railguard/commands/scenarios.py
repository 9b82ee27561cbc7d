"""`railguard scenarios`: the one catalogue of shipped scenarios, and the listing every
scenario-playing command shows under its `--help`."""
from __future__ import annotations

import argparse
import json


def catalogue() -> list[tuple[str, str, tuple[str, ...]]]:
    """(name, description, the commands that play it) for every shipped scenario."""
    from monitor import scenario

    return [(e.name, e.description, tuple(e.players)) for e in scenario.catalogue()]


def shipped_help(player: str) -> str:
    """The epilog of a command's --help: the shipped scenarios it plays."""
    try:
        rows = [(n, d) for n, d, players in catalogue() if player in players]
    except Exception as exc:  # noqa: BLE001 - --help must never fail on a broken catalogue
        return f"(the shipped scenarios cannot be listed: {exc})"
    width = max((len(n) for n, _ in rows), default=0)
    return "shipped scenarios (docs/scenarios.md):\n" + "\n".join(f"  {n:<{width}}  {d}" for n, d in rows)


def show(args: argparse.Namespace) -> int:
    rows = catalogue()
    if args.json:
        print(json.dumps([{"name": n, "description": d, "players": list(p)} for n, d, p in rows]))
        return 0
    width = max(len(n) for n, _, _ in rows)
    print(f"{'scenario':<{width}}  {'played by':<22}  description")
    for name, description, players in rows:
        print(f"{name:<{width}}  {'/'.join(players):<22}  {description}")
    return 0


def register(sub) -> None:
    s = sub.add_parser(
        "scenarios",
        help="list the shipped scenarios and which commands play them",
        description="The one catalogue of shipped scenarios (monitor/scenarios/*.toml, the language in "
                    "docs/scenarios.md): name, the commands that can play it (run, cosim, campaign), description. "
                    "Every command that takes a scenario also takes a TOML file of your own.",
    )
    s.add_argument("--json", action="store_true", help="print a JSON list of {name, description, players}")
    s.set_defaults(func=show)
