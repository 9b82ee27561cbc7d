"""`railguard`: the one command, with a subcommand per job.

Errors a user can cause (bad file, bad value, unknown name) print one line on stderr and
exit with code 2; nothing else is allowed to escape as a traceback.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Callable, Sequence

from . import __version__

EXIT_USAGE = 2


class UserError(Exception):
    """A problem with the user's input, shown as one line."""


def _user_errors() -> tuple[type[BaseException], ...]:
    from .core.table import TableError
    from .offline.params import ConfigError
    from .offline.pomdp import ModelError
    from .offline.pomdp_file import PomdpFormatError

    return (UserError, TableError, ConfigError, ModelError, PomdpFormatError, OSError)


def _progress_printer(stream) -> Callable:
    """Solver progress on one refreshed line for a terminal, one line per 25 iterations otherwise."""
    tty = stream.isatty()

    def show(p) -> None:
        text = (f"iter {p.iteration:4d}  lower {p.lower:12.4f}  upper {p.upper:12.4f}  gap {p.gap:10.4f}  "
                f"alphas {p.alphas:4d}  beliefs {p.beliefs:4d}  {p.elapsed:6.1f} s")
        if tty:
            stream.write("\r" + text)
            stream.flush()
        elif p.iteration % 25 == 0:
            stream.write(text + "\n")

    def finish() -> None:
        if tty:
            stream.write("\n")

    def line(text: str) -> None:
        stream.write(text + "\n")
        stream.flush()

    show.finish = finish  # type: ignore[attr-defined]
    show.line = line  # type: ignore[attr-defined]
    return show


def cmd_solve(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from .offline import models, pipeline, pomdp_file
    if args.pomdp:
        model = pomdp_file.read(args.pomdp)
        plan = models.plan_for_pomdp_file(args.config)
    else:
        model, plan = models.load(args.model, args.config)
    settings = plan.settings
    for flag, field in (("seed", "seed"), ("time_budget", "time_budget_s"), ("max_iterations", "max_iterations"),
                        ("max_beliefs", "max_beliefs"), ("target_gap", "target_gap")):
        value = getattr(args, flag)
        if value is not None:
            settings = replace(settings, **{field: value})
    plan = replace(plan, settings=settings, max_nodes=args.max_nodes or plan.max_nodes)
    show_progress = not args.json or sys.stderr.isatty()
    printer = _progress_printer(sys.stderr) if show_progress else None
    started = {"done": False}

    def compile_line(text: str) -> None:
        if printer is None:
            return
        if not started["done"]:
            printer.finish()
            started["done"] = True
        printer.line(text)

    result = pipeline.run(model, plan, printer, compile_line)
    paths = pipeline.write(result, args.out)
    if args.json:
        out = pipeline.figures(result)
        out.update(table=str(paths["table"]), pomdp=str(paths["pomdp"]), summary=str(paths["summary"]))
        print(json.dumps(out))
    else:
        sys.stdout.write(pipeline.summary_text(result))
        print(f"wrote            {paths['table']}\n                 {paths['pomdp']}\n                 {paths['summary']}")
    return 0


def cmd_table_show(args: argparse.Namespace) -> int:
    from .offline import table_view

    table = table_view.read(args.file)
    if args.json:
        print(json.dumps(table_view.as_json(table)))
    else:
        sys.stdout.write(table_view.render(table))
    return 0


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"{text!r} must be > 0")
    return value


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"{text!r} must be > 0")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="railguard",
        description="Railway anti-collision safety monitor: offline POMDP tables, online cyclic monitor.",
    )
    parser.add_argument("--version", action="version", version=f"railguard {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    p = sub.add_parser(
        "solve",
        help="solve a POMDP with point-based value iteration and compile the fixed policy table",
        description=(
            "Solve one of the papers' models (--model) or any Cassandra .pomdp file (--pomdp) with "
            "point-based value iteration, compile the alpha vectors into a finite-state controller, "
            "evaluate it exactly and write DIR/<name>.table.rgt, DIR/<name>.pomdp and DIR/<name>.summary.txt. "
            "Progress (iteration, bounds, gap, elapsed) goes to stderr."
        ),
        epilog="A TOML file given with --config sets model parameters at top level and solver settings "
               "in a [solver] table (seed, max_iterations, max_beliefs, expand_every, target_gap, "
               "time_budget_s, max_nodes). See docs/models.md for every parameter.",
    )
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--model", choices=["m1", "m2"], help="m1: seed 000, 4 states; m2: seed 001, 144 states")
    src.add_argument("--pomdp", metavar="FILE", help="a Cassandra .pomdp file")
    p.add_argument("--config", metavar="FILE.toml", help="parameter and solver overrides")
    p.add_argument("--out", metavar="DIR", default="railguard-out", help="output folder (default: %(default)s)")
    p.add_argument("--seed", type=int, help="seed of the belief-set expansion (default 0)")
    p.add_argument("--time-budget", type=_positive_float, metavar="S", help="stop solving after S seconds")
    p.add_argument("--max-iterations", type=_positive_int, metavar="N", help="stop after N backups")
    p.add_argument("--max-beliefs", type=_positive_int, metavar="N", help="cap on the belief set")
    p.add_argument("--target-gap", type=_positive_float, metavar="X", help="stop when gap <= X * max(1, |upper|)")
    p.add_argument("--max-nodes", type=_positive_int, metavar="N", help="node budget of the compiled controller")
    p.add_argument("--json", action="store_true", help="print one JSON object with the figures and paths")
    p.set_defaults(func=cmd_solve)

    t = sub.add_parser("table", help="inspect compiled policy tables", description="Inspect compiled policy tables.")
    tsub = t.add_subparsers(dest="table_command", metavar="ACTION")
    tsub.required = True
    show = tsub.add_parser(
        "show",
        help="print a table's header and its controller node by node",
        description="Check a table file (magic, version, SHA-256, dimensions) and print its header and, "
                    "for every node, the action and where each observation leads.",
    )
    show.add_argument("file", metavar="FILE", help="a .table.rgt file")
    show.add_argument("--json", action="store_true", help="print the header and the controller as JSON")
    show.set_defaults(func=cmd_table_show)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except _user_errors() as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        if isinstance(exc, OSError) and getattr(exc, "filename", None):
            msg = f"{exc.filename}: {exc.strerror}"
        print(f"railguard: error: {msg}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("railguard: interrupted", file=sys.stderr)
        return 130


def entry() -> None:
    sys.exit(main())


if __name__ == "__main__":
    entry()
